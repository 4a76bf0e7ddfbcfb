"""The compiled kernel (numba) against the NumPy reference engine."""

from __future__ import annotations

import numpy as np
import pytest

from vei.sim.engine import _RECORDED, simulate
from vei.sim.state import prepare_scenario
from vei.sim.testing import TrackSpec, crossing_scenario

from .test_engine import _mixed_params

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
