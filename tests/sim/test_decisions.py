"""The rider's yield / go decision in the engine (vei.sim.decisions, both kernels): hand-built
crossings, a gap above / below the critical gap, the stop short of the conflict zone and
the start once the car has passed; decisions off change nothing."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vei.config import DecisionConfig, SimConfig, case_preset
from vei.models import decision_core as core
from vei.sim.engine import simulate
from vei.sim.state import VariantParams, prepare_scenario
from vei.sim.testing import crossing_scenario

KERNELS = ["numpy", "numba"]
# the crossing scene at 4 m/s: the e-scooter (1.2 x 0.6 m) crosses the ego's lane at
# x = 60 m, its centre there 13.41 s into the run; the sedan (4.7 x 1.85 m) at 4 m/s. Its
# recording starts 30 m before the lane (not 15 m): a social-force rider takes over at its
# first recorded sample (vei.sim.riders.sfm_entry_s), and it must do so before the
# decision horizon (4 s, 17.6 m at 4.4 m/s) so that the decision falls at the horizon.
# the zone along the rider's path (perpendicular crossing): half the car's width, half the
# rider's length, and the corridor's margin (vei.sim.decisions.CORRIDOR_MARGIN_M)
HZ_R = 0.925 + 0.6 + 0.3
HZ_E = 0.3 + 2.35  # along the ego's
SHIFT_S = 8.0 - 15.0 / 4.4  # as a 15 m recording's 8 s shift


@pytest.fixture(scope="module")
def arrays():
    scene = crossing_scenario(ego_speed_mps=4.0, rider_y0_m=-30.0, rider_y1_m=15.0)
    return prepare_scenario(scene, SimConfig())


def _params(arrays, t_c: float | None, **decision) -> VariantParams:
    case = case_preset("paper-normal")
    if t_c is not None:
        case = dataclasses.replace(
            case, decision=DecisionConfig(enabled=True, critical_gap_s=t_c, **decision)
        )
    return VariantParams.from_case(case, arrays, 1, time_shift_s=SHIFT_S, cruise_speed_mps=4.0)


def test_the_crossing_is_one_conflict(arrays) -> None:
    c = arrays.conflicts
    assert c.n == 1
    assert c.s_ego_m[0] == pytest.approx(60.0, abs=0.05)  # the ego path starts at x = 0
    assert c.hz_rider_m[0] == pytest.approx(HZ_R) and c.hz_ego_m[0] == pytest.approx(HZ_E)
    assert c.exit_m[0] == pytest.approx(c.s_rider_m[0] + HZ_R)


def _run(arrays, kernel: str, *tcs: float | None):
    return simulate(arrays, VariantParams.concat([_params(arrays, t) for t in tcs]), kernel=kernel)


@pytest.mark.parametrize("kernel", KERNELS)
def test_gap_above_the_critical_gap_goes_below_yields(arrays, kernel) -> None:
    r = _run(arrays, kernel, -1.0, 3.0)
    dec = r.rider_decision
    first = [int(np.flatnonzero(dec[b] != core.FREE)[0]) for b in range(2)]
    assert first[0] == first[1]  # the same state until the decision
    k = first[0] - 1  # the decision is taken on the state of step k
    # the offered gap, by hand from the recorded states (both paths straight)
    v_ref = core.reference_speed_core(5.0, 5.0, 1.0)  # the paper's rider: v0 5, L 5, sigma 1
    tta_r = (-r.rider_y_m[0, k] - HZ_R) / max(r.rider_speed_mps[0, k], v_ref)
    tta_e = (60.0 - HZ_E - r.ego_x_m[0, k]) / r.ego_speed_mps[0, k]
    dta = tta_e - tta_r
    assert tta_r <= 4.0 < tta_r + 0.05 * r.rider_speed_mps[0, k]  # just inside the horizon
    assert -1.0 < dta < 3.0
    assert dec[0, k + 1] == core.GO and dec[1, k + 1] == core.YIELD
    # the rider that goes crosses in front of the car: it leaves the zone (y > HZ_R)
    # before the car's front reaches it (x < 60 - HZ_E)
    out = int(np.flatnonzero(r.rider_y_m[0] > HZ_R)[0])
    assert r.ego_x_m[0, out] < 60.0 - HZ_E
    assert not r.collision.any()


@pytest.mark.parametrize("kernel", KERNELS)
def test_a_yielding_rider_stops_short_of_the_zone_and_goes_after_the_car(arrays, kernel) -> None:
    r = _run(arrays, kernel, 3.0)
    y, sp, ex = r.rider_y_m[0], r.rider_speed_mps[0], r.ego_x_m[0]
    act = r.rider_active[0]
    stop = np.flatnonzero(act & (sp < 0.15))
    assert stop.size  # it stops ...
    assert (y[stop] < -HZ_R).all()  # ... short of the zone
    assert y[stop].max() > -HZ_R - 0.5 - 0.5  # within half a metre of its stop point
    # where the car cannot reach it: its box (across the car's path: half its length,
    # 0.6 m) is outside the strip the car sweeps (half its width, 0.925 m) by the margin
    assert (np.abs(y[stop]) - 0.6 - 0.925 >= 0.3 - 1e-9).all()
    enter = int(np.flatnonzero(y > -HZ_R)[0])
    assert ex[enter] > 60.0 + HZ_E  # it enters the zone once the car has left it
    assert stop[0] < enter and r.rider_decision[0, enter] == core.FREE
    assert not r.collision.any()
    # braking no harder than the yield deceleration (and the rider's own limits)
    dv = np.diff(sp[act]) / r.t_s[1]
    assert dv.min() > -2.0 * 1.6


def test_both_kernels_agree_with_decisions(arrays) -> None:
    pytest.importorskip("numba")
    a = _run(arrays, "numpy", -1.0, 0.5, 3.0)
    b = _run(arrays, "numba", -1.0, 0.5, 3.0)
    assert np.array_equal(a.rider_decision, b.rider_decision)
    for name in ("rider_x_m", "rider_y_m", "rider_speed_mps", "ego_x_m"):
        np.testing.assert_allclose(getattr(a, name), getattr(b, name), atol=1e-7, err_msg=name)


def test_decisions_off_change_nothing(arrays) -> None:
    base = VariantParams.from_case(case_preset("paper-normal"), arrays, 1, time_shift_s=SHIFT_S)
    off = base.with_values(critical_gap_s=5.0, decision_horizon_s=9.0, yield_decel_mps2=3.0)
    a = simulate(arrays, VariantParams.concat([base, off]), kernel="numpy")
    for name in ("rider_x_m", "rider_y_m", "rider_speed_mps", "ego_speed_mps"):
        v = getattr(a, name)
        assert v[0].tobytes() == v[1].tobytes(), name
    assert not a.rider_decision.any()


def test_on_the_demo_a_cautious_rider_collides_no_more_often_and_no_harder():
    """Issue 32's grid: 41 time shifts of the demo (the rider rides ahead of the car in its
    lane, then crosses), decisions on, critical gap -3 s (always goes) or +3 s (always
    yields). The rider shares the car's lane before it crosses, so the conflict zone starts
    where the rider already is: it does not brake to a stop in the lane; the cautious
    riders collide no more often, and no harder, than the bold ones (before: 41 of 41 at
    3.5 m/s against 35 of 41 at 1.8 m/s)."""
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.engine import simulate_metrics
    from vei.sim.timeshift import find_time_shift

    scen = reconstruct(demo_interaction())
    arrays = prepare_scenario(scen, SimConfig())
    assert arrays.conflicts.n == 1
    # the zone begins before the rider's recorded path does (arc 0, where a social-force
    # rider takes over): it rides in the car's lane from its first recorded sample
    assert arrays.conflicts.s_rider_m[0] - arrays.conflicts.hz_rider_m[0] <= 0.0
    auto = find_time_shift(scen).time_shift_s
    shifts = auto + np.linspace(-2.0, 2.0, 41)
    rows = {}
    for t_c in (-3.0, 3.0):
        case = dataclasses.replace(
            case_preset("normal"), decision=DecisionConfig(enabled=True, critical_gap_s=t_c)
        )
        p = VariantParams.from_case(case, arrays, shifts.size, time_shift_s=shifts)
        rows[t_c] = simulate_metrics(
            arrays, p, names=("collision", "impact_speed_mps"), kernel="numpy"
        )
    bold, cautious = rows[-3.0], rows[3.0]
    assert cautious["collision"].sum() <= bold["collision"].sum()
    hit_c, hit_b = cautious["collision"].to_numpy(), bold["collision"].to_numpy()
    if hit_c.any():
        assert cautious["impact_speed_mps"][hit_c].mean() <= bold["impact_speed_mps"][hit_b].mean()


@pytest.mark.parametrize("kernel", KERNELS)
def test_the_extra_social_force_riders_decide_too(kernel) -> None:
    """Issue 32: with ``--sfm-riders`` every social-force rider decides at its own
    conflicts with the car. In the four-rider scene (e2 and e3 cross the car's lane at
    x = 45 m and 75 m) a cautious population (t_c = 6 s) changes the extra riders' tracks
    against decisions off, at least one of them yields, and both kernels agree."""
    from vei.sim.testing import four_rider_scenario

    arrays = prepare_scenario(four_rider_scenario(), SimConfig(sfm_riders="all"))
    assert arrays.riders.n == 3
    assert [c.n for c in arrays.riders.conflicts][:2] == [1, 1]  # e2, e3 cross the lane
    case = case_preset("paper-normal")
    on = dataclasses.replace(case, decision=DecisionConfig(enabled=True, critical_gap_s=6.0))
    shifts = np.array([0.0, 1.0, 2.0])
    p = VariantParams.concat(
        [VariantParams.from_case(c, arrays, 3, time_shift_s=shifts) for c in (case, on)]
    )
    r = simulate(arrays, p, kernel=kernel)
    moved = np.abs(r.extra_y_m[3:] - r.extra_y_m[:3])  # decisions on against off
    assert moved[:, :, :2].max() > 0.5
    # a yielding extra rider waits short of the car's corridor while the car passes
    waits = (r.extra_speed_mps[3:, :, :2] < 0.1) & r.extra_active[3:, :, :2]
    assert waits.any()
    assert (np.abs(r.extra_y_m[3:, :, :2][waits]) > 0.925 + 0.6).all()
    if kernel == "numba":
        ref = simulate(arrays, p, kernel="numpy")
        np.testing.assert_allclose(r.extra_y_m, ref.extra_y_m, atol=1e-7)
        assert np.array_equal(r.final_state.extra_decision, ref.final_state.extra_decision)
