"""simulate_metrics: a sweep's metrics scored inside the compiled kernel equal, row for
row and bit for bit, the full recording scored by summarize (what sweeps stored before);
policy variants and the NumPy kernel fall back to that recording in sub-batches; the
memory of a metrics-only run does not grow with B x T; a sweep chunk's rows are the same."""

from __future__ import annotations

import tracemalloc
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

pytest.importorskip("numba")

from vei.config import SimConfig, case_preset  # noqa: E402
from vei.metrics import MetricsConfig, as_timeseries_trace, summarize  # noqa: E402
from vei.metrics.fused_layout import FUSED_METRICS  # noqa: E402
from vei.sim.engine import simulate, simulate_metrics  # noqa: E402
from vei.sim.state import VariantParams, prepare_scenario  # noqa: E402
from vei.sweep.evaluator import DEFAULT_METRICS  # noqa: E402

OTHER_CFG = MetricsConfig(ttc_scope="all", drac_ceiling_mps2=2.0, rider_mass_kg=80.0)


def reference(arrays, params, cfg=None, names=FUSED_METRICS, kernel="numba") -> pd.DataFrame:
    """What a sweep chunk stored before: the full recording, scored by summarize."""
    result = simulate(arrays, params, record="full", kernel=kernel)
    run = {"rider_mass_kg": params.mass_kg, "ego_max_decel_mps2": params.max_decel_mps2_ego}
    return summarize(as_timeseries_trace(result.to_trace()), cfg, names=names, params=run)


def assert_rows_equal(got: pd.DataFrame, ref: pd.DataFrame) -> None:
    assert list(got.columns) == list(ref.columns)
    for name in ref.columns:
        assert got[name].dtype == ref[name].dtype, name
        np.testing.assert_array_equal(got[name].to_numpy(), ref[name].to_numpy(), err_msg=name)
        if ref[name].dtype == np.float64:  # bit for bit: also the sign of a zero
            np.testing.assert_array_equal(np.signbit(got[name]), np.signbit(ref[name]), name)


@pytest.fixture(scope="module")
def demo():
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.timeshift import find_time_shift

    scenario = reconstruct(demo_interaction())
    return prepare_scenario(scenario, SimConfig()), float(find_time_shift(scenario))


def _grid(arrays, base: float, cases=("normal-cap", "normal", "aggressive-cap", "replay")):
    shifts = base + np.linspace(-3.0, 3.0, 9)
    parts = []
    for case in cases:
        for cruise in (3.0, 5.6, 9.0):
            p = VariantParams.from_case(case_preset(case), arrays, shifts.size, time_shift_s=shifts)
            parts.append(p.with_values(cruise_speed_mps=np.full(shifts.size, cruise)))
    params = VariantParams.concat(parts)
    # shuffled: the kernel runs the variants in blocks, the rows come back in this order
    return params.take(np.random.default_rng(3).permutation(params.batch_size))


def test_compiled_metrics_equal_the_recorded_summary(demo) -> None:
    """The demo over time shifts x cruise speeds x 4 configurations, in shuffled order,
    with the paper's thresholds and with others."""
    arrays, base = demo
    params = _grid(arrays, base)
    got = simulate_metrics(arrays, params, names=FUSED_METRICS, kernel="numba")
    ref = reference(arrays, params)
    assert_rows_equal(got, ref)
    assert 10 < ref["collision"].sum() < len(ref) - 10
    assert set(ref["impact_side"]) > {"", "front"}
    got = simulate_metrics(arrays, params, OTHER_CFG, names=DEFAULT_METRICS, kernel="numba")
    ref = reference(arrays, params, OTHER_CFG, names=DEFAULT_METRICS)
    assert_rows_equal(got, ref)
    assert ref["drac_unavoidable"].any()


def _aeb(name: str):
    c = case_preset(name)
    return replace(c, name=f"{name}/aeb", ego=replace(c.ego, policy="aeb"))


def test_policy_variants_fall_back_in_sub_batches(demo) -> None:
    """A batch mixing paper-cap and AEB variants (AEB with ideal perception is scored in
    the kernel's pass too, issue 34; with kernel='numpy' recorded 4 at a time): the rows
    come back in the caller's order and equal the recorded reference."""
    arrays, base = demo
    shifts = base + np.linspace(-2.0, 2.0, 5)
    parts = []
    for case in ("normal-cap", _aeb("normal"), "normal", _aeb("aggressive")):
        c = case if not isinstance(case, str) else case_preset(case)
        p = VariantParams.from_case(c, arrays, shifts.size, time_shift_s=shifts)
        parts.append(p.with_values(labels=[f"{c.name}#{i}" for i in range(shifts.size)]))
    params = VariantParams.concat(parts).take(np.random.default_rng(5).permutation(20))
    got = simulate_metrics(arrays, params, names=DEFAULT_METRICS, kernel="numba", full_batch=4)
    assert_rows_equal(got, reference(arrays, params, names=DEFAULT_METRICS))


def test_numpy_kernel_and_other_metrics_fall_back(demo) -> None:
    """kernel='numpy' and a metric without a fused implementation (pet_s): the full
    recording in sub-batches, scored by summarize."""
    arrays, base = demo
    params = _grid(arrays, base, cases=("normal-cap", "normal")).take(np.arange(20))
    got = simulate_metrics(arrays, params, names=DEFAULT_METRICS, kernel="numpy", full_batch=7)
    assert_rows_equal(got, reference(arrays, params, names=DEFAULT_METRICS, kernel="numpy"))
    names = (*DEFAULT_METRICS, "pet_s", "min_ttc_rel_s")
    got = simulate_metrics(arrays, params, names=names, kernel="numba", full_batch=6)
    assert_rows_equal(got, reference(arrays, params, names=names))


def test_four_riders() -> None:
    """The crossing scene with three more social-force e-scooters (the kernel's extra
    riders); the primary rider is scored."""
    from vei.sim.testing import four_rider_scenario

    arrays = prepare_scenario(four_rider_scenario(), SimConfig(sfm_riders="all"))
    parts = [
        VariantParams.from_case(case_preset(c), arrays, 6, time_shift_s=np.linspace(3.5, 6.5, 6))
        for c in ("replay", "normal", "normal-cap", "aggressive-cap")
    ]
    params = VariantParams.concat(parts)
    got = simulate_metrics(arrays, params, names=FUSED_METRICS, kernel="numba")
    ref = reference(arrays, params)
    assert_rows_equal(got, ref)
    assert ref["collision"].any() and not ref["collision"].all()


def test_memory_does_not_grow_with_steps_times_variants(demo) -> None:
    """A metrics-only run of 2000 variants allocates (NumPy, traced) less than one float64
    [B, T] series; a full recording holds 16 of them (what it keeps per variant is its
    parameters, initial and final state: O(B), ~2 kB each, whatever T)."""
    arrays, base = demo
    params = VariantParams.from_case(
        case_preset("normal-cap"), arrays, 2000, time_shift_s=base + np.linspace(-3, 3, 2000)
    )
    simulate_metrics(arrays, params.take(np.arange(2)), names=DEFAULT_METRICS)  # compile
    one_series = 8 * params.batch_size * arrays.n_steps
    tracemalloc.start()
    try:
        frame = simulate_metrics(arrays, params, names=DEFAULT_METRICS, kernel="numba")
        _, peak = tracemalloc.get_traced_memory()
    finally:
        tracemalloc.stop()
    assert len(frame) == 2000
    assert peak < one_series, (peak, one_series)


def test_sweep_chunk_rows_unchanged(demo, tmp_path) -> None:
    """EngineEvaluator.evaluate (the fused path) gives the rows of the recorded path."""
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct
    from vei.sweep.evaluator import EngineEvaluator, variant_params
    from vei.sweep.spec import spec_from_dict, variants_table

    write_scenario(reconstruct(demo_interaction()), tmp_path / "scen")
    spec = spec_from_dict(
        {
            "design": "grid",
            "base": "normal-cap",
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0, "num": 6},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0, "num": 5},
                "sfm.mass_kg": {"choices": [70.0, 110.0]},
                # without avoidance too: the CAP alone avoids every collision now that the
                # rider arrives along its run-in (issue 22)
                "ego.policy": {"choices": ["none", "paper-cap"]},
            },
        }
    )
    ev = EngineEvaluator(time_shift_reference="auto", base=spec.base)
    prep = ev.prepare(tmp_path / "scen")
    chunk = variants_table(spec, prep.scenario_id)
    got = ev.evaluate(prep, chunk)
    params = variant_params(chunk, prep.arrays, base=spec.base, auto_shift_s=prep.auto_shift_s)
    ref = reference(prep.arrays, params, names=ev.metrics, kernel=ev.sim.kernel)
    assert_rows_equal(got.drop(columns=["variant_id", "time_shift_applied_s"]), ref)
    assert got["collision"].any() and not got["collision"].all()
