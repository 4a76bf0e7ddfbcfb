"""Collision severity: impact speed, delta-v, side, who hit whom, injury risk, verdict.

Hand-computed cases (masses 1,500 kg car, 95 kg rider):
- head-on: car 10 m/s east, rider 5 m/s west -> |v_rel| = 15 m/s,
  dv_rider = 1500 / 1595 * 15 = 14.107 m/s, dv_car = 95 / 1595 * 15 = 0.893 m/s,
  front, car-hits-rider.
- side: car 2 m/s east, rider 4 m/s south into the car's left side -> |v_rel| =
  hypot(2, 4) = 4.472 m/s, left, rider-hits-car (the car's motion has no component
  along the left face's normal).
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.metrics.helpers import make_trace
from vei.config import case_preset
from vei.errors import ConfigError
from vei.metrics import MetricsConfig, summarize
from vei.metrics.severity import (
    delta_v,
    impact_side,
    impact_speed,
    injury_risk,
    injury_risk_of_speed,
    striking,
    verdict,
)
from vei.sim.engine import run_cases
from vei.sim.testing import TrackSpec, ego_straight, make_scenario
from vei.types import EGO_ID

M_C, M_R = 1500.0, 95.0


def _two_step(ego_xy, ego_v, other_xy, other_v, ego_yaw=0.0):
    """Step 0 just before contact (velocities), step 1 in contact (speeds zeroed)."""
    ego_xy = np.asarray(ego_xy, float)
    other_xy = np.asarray(other_xy, float)
    return make_trace(
        ego_xy=[ego_xy, ego_xy],
        other_xy=[other_xy, other_xy],
        ego_speed=[ego_v, 0.0],
        ego_yaw=ego_yaw,
        other_vel=[other_v, (0.0, 0.0)],
        collided=[False, True],
        ego_dims=(4.7, 1.85),
        other_dims=(1.2, 0.6),
        dt=0.05,
    )


def test_head_on_by_hand():
    tr = _two_step((0, 0), 10.0, (2.9, 0.0), (-5.0, 0.0))
    assert impact_speed(tr)[0] == pytest.approx(15.0)
    dv_r, dv_c = delta_v(tr)
    assert dv_r[0] == pytest.approx(M_C / (M_C + M_R) * 15.0)
    assert dv_r[0] == pytest.approx(14.1066, abs=1e-4)
    assert dv_c[0] == pytest.approx(0.8934, abs=1e-4)
    assert dv_r[0] + dv_c[0] == pytest.approx(15.0)
    assert impact_side(tr)[0] == "front"
    assert striking(tr)[0] == "car-hits-rider"


def test_delta_v_uses_the_runs_rider_mass():
    from vei.metrics import run_params
    from vei.metrics._trace import arrays

    tr = _two_step((0, 0), 10.0, (2.9, 0.0), (-5.0, 0.0))
    from dataclasses import replace

    base = case_preset("normal")
    heavy = replace(base, sfm=replace(base.sfm, mass_kg=150.0))
    params = run_params([heavy])
    assert params["rider_mass_kg"][0] == 150.0 and params["ego_max_decel_mps2"][0] == 8.0
    dv_r, dv_c = delta_v(arrays(tr, params))
    assert dv_c[0] == pytest.approx(150.0 / 1650.0 * 15.0)  # m_r / (m_c + m_r) |v_rel|
    assert dv_r[0] == pytest.approx(1500.0 / 1650.0 * 15.0)
    # a number in the config overrides the run's mass; summarize takes the params too
    assert delta_v(arrays(tr), MetricsConfig(rider_mass_kg=500.0))[1][0] == pytest.approx(
        500.0 / 2000.0 * 15.0
    )
    row = summarize(tr, params=params).iloc[0]
    assert row["delta_v_car_mps"] == pytest.approx(150.0 / 1650.0 * 15.0)
    assert delta_v(tr)[1][0] == pytest.approx(M_R / (M_C + M_R) * 15.0)  # default 95 kg


def test_side_impact_by_hand():
    tr = _two_step((0, 0), 2.0, (0.3, 1.5), (0.0, -4.0))
    assert impact_speed(tr)[0] == pytest.approx(math.hypot(2.0, 4.0))
    dv_r, dv_c = delta_v(tr)
    assert dv_r[0] == pytest.approx(M_C / (M_C + M_R) * math.hypot(2, 4))
    assert impact_side(tr)[0] == "left"
    assert striking(tr)[0] == "rider-hits-car"


def test_rotated_frame_rear_and_right():
    # Ego heading north; a rider from behind (south) faster than the car: rear, rider hits.
    tr = _two_step((0, 0), 2.0, (0.0, -2.9), (0.0, 6.0), ego_yaw=np.pi / 2)
    assert impact_side(tr)[0] == "rear"
    assert striking(tr)[0] == "rider-hits-car"
    assert impact_speed(tr)[0] == pytest.approx(4.0)
    # Heading north, rider to the east = the car's right.
    tr = _two_step((0, 0), 3.0, (1.4, 0.2), (-1.0, 0.0), ego_yaw=np.pi / 2)
    assert impact_side(tr)[0] == "right"
    assert striking(tr)[0] == "rider-hits-car"


def test_no_collision_is_empty():
    tr = make_trace(ego_xy=(0, 0), other_xy=(30, 0), ego_speed=5.0, collided=False)
    assert np.isnan(impact_speed(tr)[0])
    assert np.isnan(delta_v(tr)[0][0])
    assert impact_side(tr)[0] == "" and striking(tr)[0] == ""
    assert injury_risk(tr)[0] == 0.0


def test_injury_risk_curve():
    # Rosen & Sander (2009): 1 / (1 + exp(6.9 - 0.090 v_kmh)); their abstract: risk at
    # 50 km/h > 2x that at 40 km/h and > 5x that at 30 km/h.
    r30, r40, r50 = injury_risk_of_speed(np.array([30.0, 40.0, 50.0]) / 3.6)
    assert r50 == pytest.approx(1.0 / (1.0 + math.exp(6.9 - 4.5)))
    assert r50 / r40 > 2.0 and r50 / r30 > 5.0
    assert np.isnan(injury_risk_of_speed(np.nan))
    cfg = MetricsConfig(injury_intercept=0.0, injury_slope_per_kmh=1.0)
    assert injury_risk_of_speed(0.0, cfg) == pytest.approx(0.5)


def test_config_validation():
    with pytest.raises(ConfigError):
        MetricsConfig(car_mass_kg=0.0)
    with pytest.raises(ConfigError):
        MetricsConfig(mitigation_share=1.5)
    with pytest.raises(ConfigError):
        MetricsConfig(drac_ceiling_mps2=-1.0)
    with pytest.raises(ConfigError):
        MetricsConfig(rider_mass_kg=float("nan"))
    with pytest.raises(ConfigError):
        MetricsConfig(reaction_time_s=-0.1)
    assert MetricsConfig().rider_mass_kg is None and MetricsConfig().drac_ceiling_mps2 is None
    with pytest.raises(ConfigError, match="reaction_tme_s"):
        MetricsConfig.from_dict({"reaction_tme_s": 1.0})


def test_verdict():
    out = verdict(
        collision=[False, True, True, True, True],
        impact_speed_mps=[np.nan, 4.0, 4.5, 3.0, 2.0],
        none_collision=[True, True, True, False, True],
        none_impact_speed_mps=[5.0, 5.0, 5.0, np.nan, 2.0],
        mitigation_share=0.2,
    )
    assert list(out) == ["avoided", "mitigated", "not-mitigated", "not-mitigated", "not-mitigated"]
    with pytest.raises(ValueError):
        verdict([True], [1.0], [True, False], [1.0, 1.0])


# ------------------------------------------------------------------- through the engine
def _replay_speed_run(ego_speed, rider_t, rider_x, rider_y, rider_yaw):
    ego = ego_straight(ego_speed, duration_s=10.0)
    rider = TrackSpec("escooter", rider_t, rider_x, rider_y, np.full_like(rider_t, rider_yaw))
    sc = make_scenario({EGO_ID: ego, "rider1": rider}, primary_threat="rider1")
    case = case_preset("replay-speed")
    return run_cases(sc, [case]).to_trace()


def test_head_on_through_engine():
    t = np.arange(0, 201) / 20.0
    tr = _replay_speed_run(10.0, t, 60.0 - 5.0 * t, np.zeros_like(t), np.pi)
    s = summarize(tr)
    assert bool(s["collision"][0])
    assert s["impact_speed_mps"][0] == pytest.approx(15.0, abs=1e-6)
    assert s["delta_v_rider_mps"][0] == pytest.approx(M_C / (M_C + M_R) * 15.0, abs=1e-6)
    assert s["delta_v_car_mps"][0] == pytest.approx(M_R / (M_C + M_R) * 15.0, abs=1e-6)
    assert s["impact_side"][0] == "front"
    assert s["striking"][0] == "car-hits-rider"
    assert 0.0 < s["injury_risk"][0] < 1.0


def test_side_impact_through_engine():
    # Rider rides south at 4 m/s at x = 4.24 m: it meets the car's left side mid-length
    # (car centre x = 2 t; contact at y = 0.925 + 0.6 when t = (10 - 1.525) / 4 = 2.12 s).
    t = np.arange(0, 101) / 20.0
    tr = _replay_speed_run(2.0, t, np.full_like(t, 4.24), 10.0 - 4.0 * t, -np.pi / 2)
    s = summarize(tr)
    assert bool(s["collision"][0])
    assert s["impact_speed_mps"][0] == pytest.approx(math.hypot(2.0, 4.0), abs=1e-6)
    assert s["impact_side"][0] == "left"
    assert s["striking"][0] == "rider-hits-car"


def test_contact_on_the_riders_first_active_step_has_no_impact_speed():
    # The rider appears overlapping the car (a time shift can do this): no approach.
    tr = make_trace(
        ego_xy=[(0, 0), (0.5, 0)],
        other_xy=[(2.0, 0.0), (2.0, 0.0)],
        ego_speed=[10.0, 0.0],
        other_vel=(0.0, 0.0),
        active=[False, True],
        collided=[False, True],
        ego_dims=(4.7, 1.85),
        other_dims=(1.2, 0.6),
        dt=0.05,
    )
    s = summarize(tr)
    assert bool(s["collision"][0])
    assert np.isnan(s["impact_speed_mps"][0]) and np.isnan(s["injury_risk"][0])
    assert np.isnan(s["delta_v_rider_mps"][0])
    assert s["impact_side"][0] == "front" and s["striking"][0] == ""


def test_front_corner_caught_while_crossing_is_a_front_impact():
    # Car 3 m/s east; the rider's centre is beyond both the front (x > 2.35) and the left
    # (y > 0.925) face, moving left (north) at 4 m/s, away from the left face: the car's
    # front caught it. Approach speeds: front 3 - 0 = 3 m/s, left 0 - 4 = -4 m/s.
    tr = _two_step((0, 0), 3.0, (2.6, 1.1), (0.0, 4.0))
    assert impact_side(tr)[0] == "front"
    assert striking(tr)[0] == "car-hits-rider"
    assert impact_speed(tr)[0] == pytest.approx(5.0)  # hypot(3, 4)
    # The same place with the rider riding south into the car: through the left face.
    tr = _two_step((0, 0), 3.0, (2.6, 1.1), (0.0, -4.0))
    assert impact_side(tr)[0] == "left"
    assert striking(tr)[0] == "rider-hits-car"
