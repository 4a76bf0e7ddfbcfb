"""The compiled kernel (numba) against the NumPy reference engine."""

from __future__ import annotations

import numpy as np
import pytest

from tests.sim.test_engine import _mixed_params
from vei.sim.engine import _RECORDED, simulate
from vei.sim.state import prepare_scenario
from vei.sim.testing import TrackSpec, crossing_scenario

pytest.importorskip("numba")


@pytest.fixture(scope="module")
def arrays_with_other():
    t = np.arange(0, 501) / 20.0
    other = TrackSpec(
        "cyclist",
        t,
        np.full_like(t, 20.0),
        np.zeros_like(t),
        np.full_like(t, np.pi / 2),
        np.zeros_like(t),
    )
    return prepare_scenario(crossing_scenario(others=[("c2", other)]))


def test_numba_kernel_matches_numpy_reference(arrays_with_other) -> None:
    p = _mixed_params(arrays_with_other)
    ref = simulate(arrays_with_other, p, kernel="numpy")
    fast = simulate(arrays_with_other, p, kernel="numba")
    for name, _, _ in _RECORDED:
        a, b = np.asarray(getattr(ref, name)), np.asarray(getattr(fast, name))
        if a.dtype.kind == "f":
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-9, err_msg=name)
        else:
            assert np.array_equal(a, b), name
    assert np.array_equal(ref.hit_other, fast.hit_other)
    assert ref.hit_other.any()
    np.testing.assert_allclose(fast.collision_time_s, ref.collision_time_s, atol=1e-12)
    np.testing.assert_allclose(fast.min_center_distance_m, ref.min_center_distance_m, atol=1e-9)
    for name in ("ego_s_m", "pid_integral_m", "rider_prog_m", "hist"):
        np.testing.assert_allclose(
            getattr(fast.final_state, name), getattr(ref.final_state, name), atol=1e-9
        )
    assert np.array_equal(fast.final_state.rider_done, ref.final_state.rider_done)


def test_numba_kernel_deterministic_and_batch_invariant(arrays_with_other) -> None:
    p = _mixed_params(arrays_with_other)
    a = simulate(arrays_with_other, p, kernel="numba")
    b = simulate(arrays_with_other, p, kernel="numba", record="none")
    assert np.array_equal(a.collision_time_s, b.collision_time_s, equal_nan=True)
    assert np.array_equal(a.min_center_distance_m, b.min_center_distance_m)
    for i in (0, 4, 9, 13):
        single = simulate(arrays_with_other, p.take([i]), kernel="numba")
        for name, _, _ in _RECORDED:
            assert np.array_equal(
                np.asarray(getattr(single, name))[0], np.asarray(getattr(a, name))[i]
            ), (i, name)


def _numpy_transcendentals_are_libm() -> bool:
    """True when NumPy's vectorised exp / expm1 / sin / cos round like the C library here
    (no SIMD variant with other last bits on this CPU), so both engines can agree exactly."""
    import math

    x = np.random.default_rng(3).uniform(-12.0, 12.0, 4096)
    pairs = ((np.exp, math.exp), (np.expm1, math.expm1), (np.sin, math.sin), (np.cos, math.cos))
    return all(np.array_equal(f(x), np.array([g(v) for v in x])) for f, g in pairs)


def test_both_engines_run_one_implementation_of_the_ego(arrays_with_other) -> None:
    # Rider replayed (no social force): what differs between the engines is only the ego,
    # whose PID, actuator, CAP laws and states are vei.models.ego_core in both. Where NumPy's
    # exp / sin / cos are the C library's, the two engines agree bit for bit; elsewhere to
    # the last bits of those functions.
    p = _mixed_params(arrays_with_other)
    p = p.with_values(rider_sfm=np.zeros(p.batch_size, dtype=bool))
    ref = simulate(arrays_with_other, p, kernel="numpy")
    fast = simulate(arrays_with_other, p, kernel="numba")
    assert ref.collision.any() and (fast.collision == ref.collision).all()
    exact = _numpy_transcendentals_are_libm()
    for name in ("ego_s_m", "ego_speed_mps", "ego_accel_mps2", "ego_command", "cap_state"):
        a, b = np.asarray(getattr(ref, name)), np.asarray(getattr(fast, name))
        if exact or a.dtype.kind != "f":
            assert np.array_equal(a, b), name
        else:
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-12, err_msg=name)
    assert set(np.unique(ref.cap_state)) == {0, 1, 2}  # every CAP state is exercised
