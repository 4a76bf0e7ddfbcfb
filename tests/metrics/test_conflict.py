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


def _approach(brake_from_gap_m: float | None, decel_mps2: float = 0.0):
    """Ego (4 m) at 10 m/s along +x toward a standing rider (1 m), gap 10 m at t = 0, steps
    of 0.125 s (exact in binary); braking at ``decel_mps2`` once the gap is
    ``brake_from_gap_m``, else at constant speed until contact (gap 0 at t = 1 s)."""
    dt = 0.125
    t = np.arange(13) * dt
    if brake_from_gap_m is None:
        x, v = 10.0 * t, np.full_like(t, 10.0)
    else:
        t0 = (10.0 - brake_from_gap_m) / 10.0
        tb = np.clip(t - t0, 0.0, None)
        v = np.where(t < t0, 10.0, 10.0 - decel_mps2 * tb)
        x = np.where(t < t0, 10.0 * t, 10.0 * t0 + 10.0 * tb - 0.5 * decel_mps2 * tb**2)
    collided = x >= 10.0
    v = np.where(collided, 0.0, v)
    return make_trace(
        ego_xy=np.stack([x, 0 * x], 1), other_xy=(12.5, 0.0), ego_speed=v, dt=dt, collided=collided
    )


def test_drac_unavoidable_only_beyond_the_reaction_time():
    from vei.metrics.conflict import drac_unavoidable

    # Constant 10 m/s into a standing rider: the last step with time to contact >= 0.5 s
    # has gap 5 m (TTC 0.5 s): DRAC = 100 / 10 = 10 m/s^2 > the car's 8 -> unavoidable,
    # max capped at 8. The steps closer (gap 3.75, 2.5, 1.25 m: DRAC 13.3, 20, 40) do not
    # count.
    tr = _approach(None)
    assert drac_series(tr, MetricsConfig(drac_ceiling_mps2=1e3))[0, 4:8] == pytest.approx(
        [10.0, 100 / 7.5, 20.0, 40.0]
    )
    assert max_drac(tr)[0] == 8.0 and bool(drac_unavoidable(tr)[0])
    assert max_drac(tr, MetricsConfig(drac_ceiling_mps2=1e3))[0] == pytest.approx(10.0)
    # Reaction time 0: every step counts, the gap-1.25 m step gives 40 m/s^2.
    zero = MetricsConfig(drac_ceiling_mps2=1e3, reaction_time_s=0.0)
    assert max_drac(tr, zero)[0] == pytest.approx(40.0)
    # Braking at 6.25 m/s^2 from gap 8 m (TTC 0.8 s): DRAC = 100 / 16 = 6.25 at every step
    # from then on (constant deceleration = the DRAC): below 8 -> not unavoidable.
    tr = _approach(8.0, 6.25)
    assert max_drac(tr)[0] == pytest.approx(6.25) and not drac_unavoidable(tr)[0]
    # The ceiling is the run's full brake: 6 m/s^2 makes the same run unavoidable.
    assert bool(drac_unavoidable(_approach(8.0, 6.25), MetricsConfig(drac_ceiling_mps2=6.0))[0])


def test_max_drac_from_the_memoised_series_equals_the_fresh_search():
    from vei.metrics._trace import arrays
    from vei.metrics.conflict import drac_unavoidable

    for tr in (_approach(None), _approach(8.0, 6.25)):  # collision (NaN steps) and not
        for cfg in (MetricsConfig(), MetricsConfig(reaction_time_s=0.0, drac_ceiling_mps2=1e3)):
            fresh = max_drac(tr, cfg), drac_unavoidable(tr, cfg)
            a = arrays(tr)
            drac_series(a)  # the full series in the memo: max_drac takes it from there
            assert np.isnan(drac_series(a)[0]).any() == bool(a.collided.any())
            np.testing.assert_array_equal(max_drac(a, cfg), fresh[0])
            np.testing.assert_array_equal(drac_unavoidable(a, cfg), fresh[1])


def test_drac_ceiling_from_the_run_params():
    from vei.metrics._trace import arrays
    from vei.metrics.conflict import drac_ceiling, drac_unavoidable

    a = arrays(_approach(None), {"ego_max_decel_mps2": 10.5})
    assert drac_ceiling(a)[0] == 10.5
    # DRAC 10 at TTC 0.5 s is reachable with a 10.5 m/s^2 brake
    assert max_drac(a)[0] == pytest.approx(10.0) and not drac_unavoidable(a)[0]
    assert drac_ceiling(_approach(None))[0] == 8.0  # EgoConfig.max_decel_mps2


def test_drac_nan_from_contact_on():
    # From the contact step on: NaN (no deceleration avoids a crash that happened).
    tr = make_trace(
        ego_xy=[(0, 0), (0.4, 0), (0.4, 0)],
        other_xy=(3.0, 0.0),
        ego_speed=[10.0, 0.0, 0.0],
        collided=[False, True, True],
    )
    d = drac_series(tr)[0]
    assert d[0] == 8.0 and np.isnan(d[1:]).all()


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
    a = arrays(tr)
    series = drac_series(a)  # every step's course test
    # the maximum is over the steps with time to contact gap / v_close >= 0.5 s
    from vei.metrics.conflict import _drac_candidates

    ttc = _drac_candidates(a)[3]
    assert np.isfinite(ttc).any()
    eligible = np.where(ttc >= MetricsConfig().reaction_time_s, series, 0.0)
    has = np.isfinite(series).any(axis=1)
    full = np.where(has, np.max(np.nan_to_num(eligible, nan=0.0), axis=1), np.nan)
    np.testing.assert_array_equal(fast, full)
    # reaction time 0: the maximum of the whole series (computed fresh, no shared memo)
    zero = MetricsConfig(reaction_time_s=0.0)
    full0 = np.full(series.shape[0], np.nan)
    full0[has] = np.nanmax(series[has], axis=1)
    np.testing.assert_array_equal(max_drac(tr, zero), full0)
    raw_flag = (np.nan_to_num(series, nan=0.0) >= 8.0).any(axis=1)
    assert (drac_unavoidable(tr) <= raw_flag).all()  # flagged runs reach the ceiling
    assert drac_unavoidable(tr, zero).sum() > drac_unavoidable(tr).sum()
    assert 0 < raw_flag.sum() < raw_flag.size  # both kinds in the batch
