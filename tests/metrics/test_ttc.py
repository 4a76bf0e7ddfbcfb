import math

import numpy as np
import pytest

from vei.errors import ConfigError
from vei.metrics import MetricsConfig, paper_ttc, relative_ttc, safety_index, ttc_zones
from vei.metrics.ttc import (
    ZONE_ALERT,
    ZONE_ATTENTION,
    ZONE_COLLISION,
    ZONE_INACTIVE,
    ZONE_SAFE,
    zone_durations,
)

from .helpers import make_trace

# Ego 4 x 2 m at the origin heading +x at 5 m/s; the other (1 x 1 m) straight ahead with
# box gaps chosen so that the paper's TTC = gap / 5 is, step by step (dt = 0.1 s):
GAPS = [15.0, 12.0, 10.0, 8.0, 7.0, 5.0, 4.0, 2.0, 0.5, 30.0]
TTC = [3.0, 2.4, 2.0, 1.6, 1.4, 1.0, 0.8, 0.4, 0.1]  # last step: other inactive
ZONES = [
    ZONE_SAFE,
    ZONE_SAFE,
    ZONE_ATTENTION,
    ZONE_ATTENTION,
    ZONE_ATTENTION,
    ZONE_ALERT,
    ZONE_ALERT,
    ZONE_ALERT,
    ZONE_ALERT,
    ZONE_INACTIVE,
]


def _ahead_trace(collided=False, ego_speed=5.0, sign=1.0):
    other = [[sign * (2.0 + 0.5 + g), 0.0] for g in GAPS]
    active = [True] * 9 + [False]
    return make_trace(
        ego_xy=[0.0, 0.0], other_xy=other, ego_speed=ego_speed, active=active, collided=collided
    )


def test_paper_ttc_is_box_gap_over_ego_speed():
    ttc = paper_ttc(_ahead_trace())
    assert ttc.shape == (1, 10)
    assert ttc[0, :9] == pytest.approx(TTC)
    assert math.isnan(ttc[0, 9])


def test_zones_follow_the_two_second_rule_with_closed_upper_bounds():
    assert ttc_zones(_ahead_trace())[0].tolist() == ZONES


def test_safety_index_hand_value_and_durations():
    tr = _ahead_trace()
    # 2 safe + 3 attention steps out of 9 active ones
    assert safety_index(tr)[0] == pytest.approx(5 / 9)
    d = zone_durations(tr)
    assert d["safe"][0] == pytest.approx(0.2)
    assert d["attention"][0] == pytest.approx(0.3)
    assert d["alert"][0] == pytest.approx(0.4)
    assert d["collision"][0] == 0.0
    assert d["all"][0] == pytest.approx(0.9)


def test_collision_forces_index_to_zero_and_latches_zone():
    collided = [False] * 7 + [True] * 3
    tr = _ahead_trace(collided=collided)
    assert safety_index(tr)[0] == 0.0
    z = ttc_zones(tr)[0].tolist()
    assert z[:7] == ZONES[:7]
    assert z[7:9] == [ZONE_COLLISION, ZONE_COLLISION]
    assert z[9] == ZONE_INACTIVE
    assert paper_ttc(tr)[0, 7] == 0.0


def test_all_safe_gives_index_one():
    tr = make_trace(ego_xy=[0.0, 0.0], other_xy=[50.0, 0.0], ego_speed=[5.0] * 20)
    assert safety_index(tr)[0] == 1.0


def test_standing_ego_is_safe_and_never_active_is_nan():
    tr = make_trace(ego_xy=[0.0, 0.0], other_xy=[3.0, 0.0], ego_speed=[0.0] * 5)
    assert np.isinf(paper_ttc(tr)).all()
    assert safety_index(tr)[0] == 1.0
    never = make_trace(ego_xy=[0.0, 0.0], other_xy=[3.0, 0.0], ego_speed=[5.0] * 5, active=False)
    assert math.isnan(safety_index(never)[0])


def test_scope_ahead_versus_literal_formula_for_a_road_user_behind():
    behind = _ahead_trace(sign=-1.0)
    assert np.isinf(paper_ttc(behind)[0, :9]).all()
    assert safety_index(behind)[0] == 1.0
    literal = MetricsConfig(ttc_scope="all")
    assert paper_ttc(behind, literal)[0, :9] == pytest.approx(TTC)
    assert safety_index(behind, literal)[0] == pytest.approx(5 / 9)


def test_custom_thresholds():
    cfg = MetricsConfig(safe_ttc_s=3.0, alert_ttc_s=1.5)
    # TTC 3.0 -> attention (closed upper bound); 2.4, 2.0, 1.6 attention; 1.4 ... alert
    z = ttc_zones(_ahead_trace(), cfg)[0].tolist()
    assert z[:9] == [ZONE_ATTENTION] * 4 + [ZONE_ALERT] * 5


def test_relative_ttc_closing_on_a_slower_rider():
    # gap 12 m, ego 5 m/s, rider ahead at 2 m/s same direction: closing 3 m/s -> 4 s
    tr = make_trace(ego_xy=[0.0, 0.0], other_xy=[14.5, 0.0], ego_speed=5.0, other_vel=(2.0, 0.0))
    assert relative_ttc(tr)[0] == pytest.approx([4.0] * 1)
    # rider faster than the ego: never
    fast = make_trace(ego_xy=[0.0, 0.0], other_xy=[14.5, 0.0], ego_speed=5.0, other_vel=(6.0, 0.0))
    assert np.isinf(relative_ttc(fast)).all()


def test_metrics_config_validation():
    with pytest.raises(ConfigError):
        MetricsConfig(safe_ttc_s=1.0, alert_ttc_s=1.0)
    with pytest.raises(ConfigError):
        MetricsConfig(alert_ttc_s=0.0)
    with pytest.raises(ConfigError):
        MetricsConfig(ttc_scope="sideways")
    with pytest.raises(ConfigError, match="unknown metrics key"):
        MetricsConfig.from_dict({"safe_ttc_sec": 2.0})
    assert MetricsConfig.from_dict({"safe_ttc_s": 3.0}).safe_ttc_s == 3.0
