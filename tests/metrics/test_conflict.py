import math

import numpy as np
import pytest

from vei.metrics import MetricsConfig
from vei.metrics.conflict import drac_series, gap_series, max_drac, min_gap, pet

from .helpers import make_trace


def test_min_gap_over_active_steps_only():
    other = [[12.5, 0.0], [8.5, 0.0], [5.0, 3.0], [4.5, 0.0]]
    tr = make_trace(
        ego_xy=[0.0, 0.0], other_xy=other, ego_speed=5.0, active=[True, True, True, False]
    )
    g = gap_series(tr)[0]
    assert g[:3] == pytest.approx([10.0, 6.0, math.hypot(2.5, 1.5)])
    assert math.isnan(g[3])
    assert min_gap(tr)[0] == pytest.approx(math.hypot(2.5, 1.5))


def test_drac_hand_values():
    # gap 20 m, ego 10 m/s: standing rider -> 100 / 40; rider at 4 m/s ahead -> 36 / 40
    standing = make_trace(ego_xy=[0.0, 0.0], other_xy=[22.5, 0.0], ego_speed=10.0)
    assert drac_series(standing)[0, 0] == pytest.approx(2.5)
    moving = make_trace(
        ego_xy=[0.0, 0.0], other_xy=[22.5, 0.0], ego_speed=10.0, other_vel=(4.0, 0.0)
    )
    assert max_drac(moving)[0] == pytest.approx(0.9)
    behind = make_trace(ego_xy=[0.0, 0.0], other_xy=[-22.5, 0.0], ego_speed=10.0)
    assert max_drac(behind)[0] == 0.0


def _crossing(other_start_y: float, collided=False):
    # Ego (4 m long) from x = -50 at 10 m/s along +x; other (1 m) along +y at 2 m/s from
    # (0, other_start_y); 101 steps of 0.1 s.
    t = np.arange(101) * 0.1
    ego = np.stack([-50.0 + 10.0 * t, 0.0 * t], axis=1)
    oth = np.stack([0.0 * t, other_start_y + 2.0 * t], axis=1)
    return make_trace(
        ego_xy=ego,
        other_xy=oth,
        ego_speed=10.0,
        other_yaw=math.pi / 2,
        other_vel=(0.0, 2.0),
        collided=collided,
    )


def test_pet_ego_first_then_rider():
    # ego occupies (0, 0) while its centre is within 2 m: t in [4.8, 5.2] s; the rider
    # (half length 0.5 m) from y = -16: t in [7.75, 8.25] s -> PET = 7.75 - 5.2
    assert pet(_crossing(-16.0))[0] == pytest.approx(2.55)


def test_pet_rider_first_then_ego():
    # rider from y = -6: occupies the point for t in [2.75, 3.25]; ego arrives at 4.8
    assert pet(_crossing(-6.0))[0] == pytest.approx(1.55)


def test_pet_zero_when_occupancies_overlap_or_collision_and_nan_without_crossing():
    assert pet(_crossing(-10.0))[0] == 0.0  # rider occupies [4.75, 5.25]
    assert pet(_crossing(-16.0, collided=True))[0] == 0.0
    parallel = make_trace(
        ego_xy=np.stack([np.arange(20.0), np.zeros(20)], 1),
        other_xy=np.stack([np.arange(20.0), np.full(20, 5.0)], 1),
        ego_speed=10.0,
    )
    assert math.isnan(pet(parallel)[0])


def test_drac_is_zero_for_a_rider_passing_beside():
    # Rider 1.5 m left of the car's path, 10 m ahead, standing: the car closes along its
    # heading (v_close = 8 m/s, gap ~9 m) but would pass it: no braking needed.
    tr = make_trace(ego_xy=(0, 0), other_xy=(12.0, 2.5), ego_speed=8.0, other_yaw=0.0)
    assert max_drac(tr)[0] == 0.0
    # On the path: v^2 / (2 gap) = 64 / (2 x 9.5) with ego 4 m and rider 1 m long.
    tr = make_trace(ego_xy=(0, 0), other_xy=(12.0, 0.0), ego_speed=8.0)
    assert max_drac(tr)[0] == pytest.approx(64.0 / 19.0)


def test_drac_capped_at_one_g_and_flagged():
    from vei.metrics.conflict import drac_unavoidable

    # 10 m/s towards a standing rider 0.5 m ahead: 100 / 1 = 100 m/s^2 -> 9.81, flagged.
    tr = make_trace(ego_xy=(0, 0), other_xy=(3.0, 0.0), ego_speed=10.0)
    assert max_drac(tr)[0] == 9.81 and bool(drac_unavoidable(tr)[0])
    cfg = MetricsConfig(drac_ceiling_mps2=200.0)
    assert max_drac(tr, cfg)[0] == pytest.approx(100.0) and not drac_unavoidable(tr, cfg)[0]
    # From the contact step on: NaN (no deceleration avoids a crash that happened).
    tr = make_trace(
        ego_xy=[(0, 0), (0.4, 0), (0.4, 0)],
        other_xy=(3.0, 0.0),
        ego_speed=[10.0, 0.0, 0.0],
        collided=[False, True, True],
    )
    d = drac_series(tr)[0]
    assert d[0] == 9.81 and np.isnan(d[1:]).all()


def test_max_drac_equals_the_series_maximum_on_engine_runs():
    from vei.config import case_preset
    from vei.metrics._trace import arrays
    from vei.metrics.conflict import drac_unavoidable
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario
    from vei.sim.testing import crossing_scenario

    arr = prepare_scenario(crossing_scenario())
    shifts = 4.886 + np.linspace(-3.0, 3.0, 61)
    p = VariantParams.from_case(case_preset("normal"), arr, shifts.size, time_shift_s=shifts)
    tr = simulate(arr, p).to_trace()
    fast = max_drac(tr)  # the course test on the largest candidates only
    series = drac_series(arrays(tr))  # every step's course test
    full = np.full(series.shape[0], np.nan)
    has = np.isfinite(series).any(axis=1)
    full[has] = np.nanmax(series[has], axis=1)
    np.testing.assert_array_equal(fast, full)
    raw_flag = (np.nan_to_num(series, nan=0.0) >= 9.81).any(axis=1)
    assert (drac_unavoidable(tr) <= raw_flag).all()  # flagged runs reach the ceiling
    assert 0 < raw_flag.sum() < raw_flag.size  # both kinds in the batch
