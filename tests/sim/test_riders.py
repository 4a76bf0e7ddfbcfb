"""Several social-force riders: rider-rider / rider-pedestrian repulsion, both kernels."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from vei.config import CALIBRATED_SFM, PAPER_SFM, SimConfig, case_preset
from vei.errors import ConfigError, InputError
from vei.models.sfm import rider_force
from vei.sim.engine import _RECORDED, simulate, step
from vei.sim.result import _RECORDED_EXTRA
from vei.sim.state import VariantParams, prepare_scenario
from vei.sim.step import initial_state
from vei.sim.testing import TrackSpec, crossing_scenario, ego_straight, make_scenario
from vei.types import EGO_ID

ALL = SimConfig(sfm_riders="all")
#: The paper's Normal rider (k_des 100 N s/m, v0 5 m/s, no limits) with a PID ego, whatever
#: the 'normal' preset's rider is.
PAPER_NORMAL = dataclasses.replace(case_preset("normal"), sfm=PAPER_SFM)


def _line(category: str, t0: float, t1: float, x0: float, x1: float, y: float) -> TrackSpec:
    """A rider recorded at constant speed from (x0, y) to (x1, y) over [t0, t1]."""
    t = np.arange(round(t0 * 20), round(t1 * 20) + 1) / 20.0
    x = x0 + (x1 - x0) * (t - t0) / (t1 - t0)
    sp = abs(x1 - x0) / (t1 - t0)
    yaw = 0.0 if x1 >= x0 else math.pi
    return TrackSpec(category, t, x, np.full_like(t, y), np.full_like(t, yaw), np.full_like(t, sp))


def _standing(category: str, x: float, y: float, t1: float = 20.0) -> TrackSpec:
    t = np.arange(round(t1 * 20) + 1) / 20.0
    return TrackSpec(category, t, np.full_like(t, x), np.full_like(t, y), np.zeros_like(t),
                     np.zeros_like(t))  # fmt: skip


def _head_on(speed_mps: float = 4.0):
    """Two e-scooters on y = 50 riding at each other at ``speed_mps`` (recorded: they pass
    through each other half-way, at x = 20); the ego drives along y = 0, far away."""
    t1 = 40.0 / speed_mps
    tracks = {
        EGO_ID: ego_straight(5.6, t1 + 2.0),
        "r1": _line("escooter", 0.0, t1, 0.0, 40.0, 50.0),
        "r2": _line("escooter", 0.0, t1, 40.0, 0.0, 50.0),
    }
    return make_scenario(tracks, primary_threat="r1", scenario_id="head-on")


def test_rider_force_by_hand() -> None:
    # Two e-scooters (radius 0.6 m each) 2 m apart: gap 0.8 m, 1000 exp(-1.6) N.
    fx, fy = rider_force(2.0, 0.0, 0.0, 0.0, 1.2, 1000.0, 2.0)
    assert fx == pytest.approx(201.8965179946554, rel=1e-12)
    assert fy == 0.0
    # Direction from the other agent to this one; overlap (negative gap) is not clipped.
    fx, fy = rider_force(0.0, -0.6, 0.0, 0.0, 1.2, 1000.0, 2.0)
    assert fx == 0.0
    assert fy == pytest.approx(-1000.0 * math.exp(1.2), rel=1e-12)
    # Coincident centres and gaps beyond the 10 m cut-off: no force.
    assert rider_force(1.0, 1.0, 1.0, 1.0, 1.2, 1000.0, 2.0) == (0.0, 0.0)
    assert rider_force(11.3, 0.0, 0.0, 0.0, 1.2, 1000.0, 2.0) == (0.0, 0.0)


def test_one_step_acceleration_equals_hand_force() -> None:
    """Two riders standing 2 m apart with v0 = 0: after one step each has v = F dt / m."""
    sc = make_scenario(
        {
            EGO_ID: ego_straight(5.6, 20.0),
            "r1": _standing("escooter", 30.0, 60.0),
            "r2": _standing("escooter", 32.0, 60.0),
        },
        primary_threat="r1",
    )
    arrays = prepare_scenario(sc, ALL)
    assert arrays.riders.ids == ("r2",)
    p = VariantParams.from_case(PAPER_NORMAL, arrays, 1, v0_mps=0.0)
    st1 = step(initial_state(arrays, p), p, arrays)
    dv = 1000.0 * math.exp(-2.0 * 0.8) / 95.0 * 0.05  # 0.10626 m/s
    assert st1.rider_vx_mps[0] == pytest.approx(-dv, rel=1e-9)
    assert st1.extra_vx_mps[0, 0] == pytest.approx(dv, rel=1e-9)
    assert st1.rider_vy_mps[0] == pytest.approx(0.0, abs=1e-12)
    # 'primary' (the default): no repulsion, the riders stay at rest (up to the rounding of
    # the recorded table's finite-difference velocity on the standing run-in's time grid,
    # ~1e-13 m/s; a repulsion would give 0.1 m/s)
    arrays1 = prepare_scenario(sc)
    p1 = VariantParams.from_case(PAPER_NORMAL, arrays1, 1, v0_mps=0.0)
    assert abs(step(initial_state(arrays1, p1), p1, arrays1).rider_vx_mps[0]) < 1e-12


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_head_on_riders_repel_and_pass_through_without_force(kernel: str) -> None:
    if kernel == "numba":
        pytest.importorskip("numba")
    arrays = prepare_scenario(_head_on(), ALL)
    on = VariantParams.from_case(PAPER_NORMAL, arrays, 1)
    off = on.with_values(use_rider_force=False)
    r = simulate(arrays, VariantParams.concat([on, off]), kernel=kernel)
    gap = r.extra_x_m[:, :, 0] - r.rider_x_m  # r2 - r1 along the line
    both = r.extra_active[:, :, 0] & r.rider_active
    assert both[0].sum() > 150
    # With the repulsion they never pass each other (r2 stays ahead of r1). At the paper
    # rider's ~4.9 m/s the short-range force does not stop them before their footprints
    # touch (the closest centre distance, 0.43 m, is below the 1.2 m body length).
    assert gap[0][both[0]].min() == pytest.approx(0.431, abs=0.01)
    # Then each is held by the other where 1000 exp(-2 (d - 1.2)) = f_des = k_des v_des,
    # v_des = v0 g / sqrt(g^2 + sigma^2), g the distance to its goal (5 m ahead of its
    # progress, which never goes back: a little more than 5 m after the bounce).
    x0 = arrays.rider_track.data[0, 0]  # progress 0: the start of its run-in (issue 22)
    g = r.final_state.rider_prog_m[0] + 5.0 - (r.rider_x_m[0, -1] - x0)
    d_eq = 1.2 + math.log(1000.0 / (100.0 * 5.0 * g / math.hypot(g, 1.0))) / 2.0
    # (a damped oscillation after the impact: the mean over the last 2 s)
    assert gap[0, int(10.0 / 0.05) :].mean() == pytest.approx(d_eq, abs=0.03)
    # Without it they ride through each other (the order flips).
    assert gap[1][both[1]].min() < -5.0
    # The time series carry the simulated poses (not the recording: r2 is recorded at x = 8).
    df = r.to_frame(variant_slice=[0])
    r2 = df[(df.agent_id == "r2") & np.isclose(df.t_s, 8.0)]
    assert len(r2) == 1 and float(r2.x_m.iloc[0]) > 15.0


def test_head_on_calibrated_riders_stop_clear() -> None:
    """At recorded speeds (1.5 m/s, calibrated rider) the riders stop before touching."""
    arrays = prepare_scenario(_head_on(1.5), ALL)
    p = VariantParams.from_case(
        dataclasses.replace(case_preset("normal"), sfm=CALIBRATED_SFM), arrays, 1
    )
    r = simulate(arrays, p)
    gap = (r.extra_x_m[:, :, 0] - r.rider_x_m)[0]
    both = (r.extra_active[:, :, 0] & r.rider_active)[0]
    assert gap[both].min() > 1.2
    # At rest where 1000 exp(-2 (d - 1.2)) = f_des = 180 N s/m x v0 g / sqrt(g^2 + 1),
    # v0 = 1.5 x hypot(1.31, 1) / 1.31 m/s (cruise 1.5 m/s at the look-ahead 1.31 m), g
    # the distance to its goal (1.31 m ahead of its progress, which never goes back).
    assert r.rider_speed_mps[0, -1] < 1e-3
    x0 = arrays.rider_track.data[0, 0]  # progress 0: the start of its run-in (issue 22)
    g = r.final_state.rider_prog_m[0] + 1.31 - (r.rider_x_m[0, -1] - x0)
    v0 = 1.5 * math.hypot(1.31, 1.0) / 1.31
    d_eq = 1.2 + math.log(1000.0 / (180.0 * v0 * g / math.hypot(g, 1.0))) / 2.0
    assert gap[-1] == pytest.approx(d_eq, abs=5e-3)


@pytest.mark.parametrize(("speed_mps", "calibrated"), [(1.5, True), (4.0, False)])
def test_pedestrian_repels_rider(speed_mps: float, calibrated: bool) -> None:
    """A pedestrian standing 0.3 m beside the rider's line: the rider swerves around it."""
    t1 = 40.0 / speed_mps
    sc = make_scenario(
        {
            EGO_ID: ego_straight(5.6, t1 + 2.0),
            "r1": _line("escooter", 0.0, t1, 0.0, 40.0, 50.0),
            "p1": _standing("pedestrian", 20.0, 50.3, t1 + 2.0),
        },
        primary_threat="r1",
    )
    arrays = prepare_scenario(sc, SimConfig(sfm_riders=["r1"]))
    assert arrays.riders.ids == () and arrays.riders.enabled
    assert list(arrays.riders.ped_idx) == [0] and arrays.other_ids == ("p1",)
    case = PAPER_NORMAL
    if calibrated:
        case = dataclasses.replace(case, sfm=CALIBRATED_SFM)
    on = VariantParams.from_case(case, arrays, 1)
    r = simulate(arrays, VariantParams.concat([on, on.with_values(use_rider_force=False)]))
    d = np.hypot(r.rider_x_m - arrays.other_x_m[:, 0], r.rider_y_m - arrays.other_y_m[:, 0])
    dmin = d.min(axis=1)
    # Without the force it rides straight past 0.3 m from the pedestrian's centre.
    assert dmin[1] == pytest.approx(0.3, abs=0.01)
    # With it, it swerves (away from the pedestrian: -y) and gets past.
    assert r.rider_y_m[0].min() < 49.0 and r.rider_x_m[0, -1] > 30.0
    if calibrated:  # at 1.5 m/s it keeps clear of the discs (radii 0.6 + 0.25 m)
        assert dmin[0] > 0.85
    else:  # at ~4.9 m/s the short-range force only halves the intrusion
        assert 0.5 < dmin[0] < 0.85


@pytest.fixture(scope="module")
def multi_arrays():
    """The crossing scenario with two more riders (one entering late, one leaving early),
    a pedestrian and a car; 'all' makes the two riders SFM-driven."""
    t = np.arange(0, 121) / 20.0
    e3 = TrackSpec("escooter", t, np.full_like(t, 62.0), -12.0 + 2.0 * t)
    others = [
        ("c2", _line("cyclist", 3.0, 9.0, 75.0, 45.0, 1.5)),
        ("e3", e3),
        ("p4", _standing("pedestrian", 61.0, 3.0, 25.0)),
        ("v5", _line("vehicle", 0.0, 25.0, 200.0, 100.0, 4.0)),
    ]
    return prepare_scenario(crossing_scenario(others=others), ALL)


def _multi_params(arrays) -> VariantParams:
    from .test_engine import _mixed_params

    p = _mixed_params(arrays)
    i = np.arange(p.batch_size)
    return p.with_values(
        speed_from_recording=i % 4 == 1, a_rider_n=np.where(i % 3 == 0, 1500.0, 1000.0)
    )


def test_multi_rider_selection(multi_arrays) -> None:
    assert multi_arrays.riders.ids == ("c2", "e3")
    assert multi_arrays.other_ids == ("p4", "v5")
    assert list(multi_arrays.riders.ped_idx) == [0]
    with pytest.raises(InputError, match="not a rider"):
        prepare_scenario(crossing_scenario(others=[("p4", _standing("pedestrian", 1, 1))]),
                         SimConfig(sfm_riders=["p4"]))  # fmt: skip
    with pytest.raises(InputError, match="no trajectory"):
        prepare_scenario(crossing_scenario(), SimConfig(sfm_riders=["nobody"]))
    with pytest.raises(ConfigError, match="sfm_riders"):
        SimConfig(sfm_riders="some")


def test_multi_rider_batch_equals_single_runs(multi_arrays) -> None:
    p = _multi_params(multi_arrays)
    batch = simulate(multi_arrays, p)
    again = simulate(multi_arrays, p)
    for name, _, _ in _RECORDED_EXTRA:
        assert np.array_equal(getattr(batch, name), getattr(again, name)), name
    for i in (0, 5, 9, 16):
        single = simulate(multi_arrays, p.take([i]))
        for name, _, _ in (*_RECORDED, *_RECORDED_EXTRA):
            assert np.array_equal(getattr(single, name)[0], getattr(batch, name)[i]), (i, name)
    # The extra riders are simulated in SFM variants and replayed in replay ones.
    sfm = p.rider_sfm
    assert batch.extra_active[:, :, 0].any(axis=1).all()
    rec_x = 75.0 - 5.0 * (multi_arrays.t_s - 3.0)  # c2's recording
    act = batch.extra_active[:, :, 0]
    dev = np.abs(batch.extra_x_m[:, :, 0] - rec_x[None])
    assert dev[~sfm][act[~sfm]].max() < 1e-9
    assert dev[sfm][act[sfm]].max() > 0.5


def test_multi_rider_numba_matches_numpy(multi_arrays) -> None:
    pytest.importorskip("numba")
    p = _multi_params(multi_arrays)
    ref = simulate(multi_arrays, p, kernel="numpy")
    fast = simulate(multi_arrays, p, kernel="numba")
    for name, _, _ in (*_RECORDED, *_RECORDED_EXTRA):
        a, b = np.asarray(getattr(ref, name)), np.asarray(getattr(fast, name))
        if a.dtype.kind == "f":
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-8, err_msg=name)
        else:
            assert np.array_equal(a, b), name
    for name in ("extra_prog_m", "extra_vx_mps", "extra_done", "extra_started"):
        np.testing.assert_allclose(
            getattr(fast.final_state, name), getattr(ref.final_state, name), atol=1e-8
        )
    # Something happens: the extra riders move, enter late / leave, and feel each other.
    assert ref.extra_active[:, 0, 0].sum() == 0 and ref.extra_active[:, :, 0].any()
    assert ref.final_state.extra_done[:, 1].any()
    again = simulate(multi_arrays, p, kernel="numba")
    assert np.array_equal(again.extra_x_m, fast.extra_x_m)
