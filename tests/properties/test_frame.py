"""Property: rotating and translating the whole scene (every trajectory and keyframe)
leaves every metric unchanged: the engine, the auto time shift and the scores see only
relative geometry. Both kernels; the demo in the fast tier, shared recordings in the
slow one."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.properties.scenes import DEMO, RECORDINGS, moved, props, scene
from vei.config import DecisionConfig, SimConfig, case_preset
from vei.sim.engine import kernel_metrics, simulate_metrics
from vei.sim.state import VariantParams, prepare_scenario
from vei.sim.timeshift import find_time_shift

NAMES = kernel_metrics()  # every scalar metric the engine scores
SHIFTS_S = np.linspace(-2.0, 2.0, 5)  # about the auto shift [s]
# float tolerance: metrics are differences of coordinates of size |(dx, dy)| <= 5 km
# (ulp ~1e-12 m), carried through the closed loop (measured: <= 4e-12 on the demo)
RTOL, ATOL = 1e-9, 1e-9
angles = st.floats(-math.pi, math.pi, allow_nan=False)
offsets = st.floats(-5000.0, 5000.0, allow_nan=False)


def _cases():
    deciding = dataclasses.replace(
        case_preset("normal"), decision=DecisionConfig(enabled=True, critical_gap_s=1.0)
    )
    return [case_preset("replay"), case_preset("normal"), case_preset("normal-cap"), deciding]


def _metrics(s, kernel: str) -> tuple[float, pd.DataFrame]:
    arrays = prepare_scenario(s, SimConfig())
    base = float(find_time_shift(s))
    parts = [VariantParams.from_case(c, arrays, SHIFTS_S.size, time_shift_s=base + SHIFTS_S)
             for c in _cases()]  # fmt: skip
    frame = simulate_metrics(arrays, VariantParams.concat(parts), names=NAMES, kernel=kernel)
    return base, frame


def assert_same_metrics(got: pd.DataFrame, ref: pd.DataFrame, what: str) -> None:
    """Every column equal: flags and labels exactly, floats within RTOL / ATOL (NaN = NaN)."""
    assert list(got.columns) == list(ref.columns)
    for name in ref.columns:
        a, b = got[name].to_numpy(), ref[name].to_numpy()
        if ref[name].dtype.kind == "f":
            np.testing.assert_allclose(a, b, rtol=RTOL, atol=ATOL, err_msg=f"{what}: {name}")
        else:
            np.testing.assert_array_equal(a, b, err_msg=f"{what}: {name}")


_REF: dict[tuple[str, str], tuple[float, pd.DataFrame]] = {}


def _check(name: str, kernel: str, angle: float, dx: float, dy: float) -> None:
    key = (name, kernel)
    if key not in _REF:
        _REF[key] = _metrics(scene(name), kernel)
    base, ref = _REF[key]
    assert ref["collision"].any() and not ref["collision"].all()  # both outcomes are tested
    got_base, got = _metrics(moved(scene(name), angle, dx, dy), kernel)
    what = f"{name}, {kernel}, rotated {angle:.6g} rad, moved ({dx:.6g}, {dy:.6g}) m"
    assert got_base == pytest.approx(base, abs=1e-6), what
    assert_same_metrics(got, ref, what)


@props(max_examples=5)
@given(angle=angles, dx=offsets, dy=offsets)
def test_demo_metrics_do_not_depend_on_the_frame_compiled(angle, dx, dy) -> None:
    pytest.importorskip("numba")
    _check(DEMO, "numba", angle, dx, dy)


@props(max_examples=2)  # the NumPy kernel: ~0.8 s an example
@given(angle=angles, dx=offsets, dy=offsets)
def test_demo_metrics_do_not_depend_on_the_frame_numpy(angle, dx, dy) -> None:
    _check(DEMO, "numpy", angle, dx, dy)


@pytest.mark.slow
@props(max_examples=12)
@given(
    name=st.sampled_from(RECORDINGS),
    kernel=st.sampled_from(["numpy", "numba"]),
    angle=angles,
    dx=offsets,
    dy=offsets,
)
def test_recording_metrics_do_not_depend_on_the_frame(name, kernel, angle, dx, dy) -> None:
    if kernel == "numba":
        pytest.importorskip("numba")
    _check(name, kernel, angle, dx, dy)
