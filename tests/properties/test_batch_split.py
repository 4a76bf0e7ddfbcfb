"""Property: splitting a batch changes nothing. A batch of variants (replayed, social-force,
deciding, CAP cars; perceived and V2X-informed ones drawing random numbers; recorded cars
that react) run at once
and the same variants run in parts give the same rows, bit for bit, on each kernel.

Narrower than "any batch": each variant has its own label. Perception and V2X draw their
random numbers from the variant's label (vei.policy.perception_random.label_keys); equal
labels in one batch get distinct keys by their order of occurrence, so a split can move a
repeated label's draws to another variant (documented there; sweeps label by variant id).
The split also changes the compiled kernel's feature set (a part without deciding riders
runs the specialisation without decisions), which must not change a row either."""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tests.properties.scenes import ALL_ROAD_USERS, DEMO, RECORDINGS, prepared, props
from vei.config import DecisionConfig, PerceptionConfig, V2XConfig, case_preset
from vei.sim.engine import kernel_metrics, simulate_metrics
from vei.sim.state import VariantParams

NAMES = kernel_metrics()
SHIFTS_S = np.arange(-2.0, 2.01, 0.25)  # about the auto shift [s]
CRUISE_MPS = (4.0, 5.6, 8.0)


def _deciding(t_c: float):
    return dataclasses.replace(
        case_preset("normal"), decision=DecisionConfig(enabled=True, critical_gap_s=t_c)
    )


def _perceived():
    """A CAP car behind a noisy, missing sensor, with V2X from half the riders (the
    policy path: the NumPy step loop on either kernel)."""
    return dataclasses.replace(
        case_preset("normal-cap"),
        perception=PerceptionConfig(enabled=True, position_noise_std_m=0.5,
                                    detection_probability=0.7),
        v2x=V2XConfig(enabled=True, penetration_rate=0.5),
    )  # fmt: skip


COMPILED_POOL = {
    "replay": case_preset("replay"),
    "normal": case_preset("normal"),
    "aggressive-cap": case_preset("aggressive-cap"),
    "bold": _deciding(-3.0),
    "cautious": _deciding(3.0),
}
POLICY_POOL = {**COMPILED_POOL, "perceived": _perceived()}
#: On a recording with its vehicles: also the recorded cars reacting to the car (IDM): a
#: part without them runs the compiled specialisation without traffic.
TRAFFIC_POOL = {
    **COMPILED_POOL,
    "traffic": dataclasses.replace(
        case_preset("normal-cap"),
        traffic=dataclasses.replace(case_preset("normal-cap").traffic, cars_react=True),
    ),
}


def _batch(arrays, base: float, pool: dict, rows: list[tuple[str, int, int]], ids: list[int]):
    parts = []
    for kind, shift_i, cruise_i in rows:
        p = VariantParams.from_case(pool[kind], arrays, 1, time_shift_s=base + SHIFTS_S[shift_i])
        parts.append(p.with_values(cruise_speed_mps=np.array([CRUISE_MPS[cruise_i]])))
    params = VariantParams.concat(parts)
    labels = np.array([f"v{i}" for i in ids], dtype=object)  # one label a variant
    return params.with_values(labels=labels)


def _variants(pool: dict, max_size: int):
    row = st.tuples(
        st.sampled_from(sorted(pool)),
        st.integers(0, SHIFTS_S.size - 1),
        st.integers(0, len(CRUISE_MPS) - 1),
    )
    return st.lists(row, min_size=2, max_size=max_size)


def _check(name: str, pool: dict, kernel: str, rows, cuts) -> None:
    arrays, base = prepared(name)
    n = len(rows)
    ids = list(range(n))
    whole = simulate_metrics(arrays, _batch(arrays, base, pool, rows, ids), names=NAMES,
                             kernel=kernel)  # fmt: skip
    edges = [0, *sorted({c % n for c in cuts} - {0}), n]
    frames = []
    for a, b in zip(edges[:-1], edges[1:], strict=True):
        part = _batch(arrays, base, pool, rows[a:b], ids[a:b])
        frames.append(simulate_metrics(arrays, part, names=NAMES, kernel=kernel))
    split = pd.concat(frames, ignore_index=True)
    assert list(split.columns) == list(whole.columns)
    for col in whole.columns:
        a, b = split[col].to_numpy(), whole[col].to_numpy()
        np.testing.assert_array_equal(a, b, err_msg=f"{col}: parts {edges} of {rows}")
        if whole[col].dtype.kind == "f":  # bit for bit: also the sign of a zero
            np.testing.assert_array_equal(np.signbit(a), np.signbit(b), err_msg=col)


@props(max_examples=10)
@given(rows=_variants(COMPILED_POOL, 10), cuts=st.sets(st.integers(1, 9), max_size=3))
def test_splitting_a_compiled_batch_changes_nothing(rows, cuts) -> None:
    pytest.importorskip("numba")
    _check(DEMO, COMPILED_POOL, "numba", rows, cuts)


@props(max_examples=3)  # the NumPy kernel: ~0.4 s an example
@given(rows=_variants(COMPILED_POOL, 6), cuts=st.sets(st.integers(1, 5), min_size=1, max_size=2))
def test_splitting_a_numpy_batch_changes_nothing(rows, cuts) -> None:
    _check(DEMO, COMPILED_POOL, "numpy", rows, cuts)


@pytest.mark.slow
@props(max_examples=6)  # the policy step loop: ~1.7 s CPU an example
@given(
    first=st.tuples(st.just("perceived"), st.integers(0, SHIFTS_S.size - 1), st.just(1)),
    rows=_variants(POLICY_POOL, 5),
    cuts=st.sets(st.integers(1, 5), min_size=1, max_size=2),
)
def test_splitting_a_perceived_batch_changes_nothing(first, rows, cuts) -> None:
    _check(DEMO, POLICY_POOL, "numpy", [first, *rows], cuts)  # always a random-drawing one


@pytest.mark.slow
@props(max_examples=10)
@given(rows=_variants(TRAFFIC_POOL, 10), cuts=st.sets(st.integers(1, 9), max_size=3))
def test_splitting_a_recording_batch_changes_nothing(rows, cuts) -> None:
    pytest.importorskip("numba")
    # the left turn with every road user: 23 others, 14 of them cars that can react
    _check(RECORDINGS[1] + ALL_ROAD_USERS, TRAFFIC_POOL, "numba", rows, cuts)
