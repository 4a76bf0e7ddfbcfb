"""Sweep mechanics at scale: the scenario reaches each worker once, workers run one numba
thread each, whole-design variant ids equal the one-at-a-time ones, results.parquet is
streamed (and de-duplicated when parts overlap), resumed sweeps equal uninterrupted ones.

Most tests use tests.sweep.sweep_fakes.FakeEvaluator (formulas, no engine), so they
take seconds; the engine's own sweeps are tested in test_sweep.py / test_workers.py.
"""

from __future__ import annotations

import os
import shutil

import numpy as np
import pandas as pd
import pytest

from tests.sweep.sweep_fakes import FakeEvaluator, fake_scenarios
from vei.calibrate.columns import RIDER_COLUMN, RIDER_PARAM_COLUMNS
from vei.sweep.ids import (
    name_variants,
    variant_id,
    variant_ids,
    variant_seed,
    variant_seeds,
)
from vei.sweep.io import _existing_parts, _in_order
from vei.sweep.run import (
    MAX_AUTO_CHUNK,
    assemble_results,
    auto_chunk_size,
    most_critical,
    read_results,
    run_sweep,
    write_results,
)
from vei.sweep.runners import threads_per_worker
from vei.sweep.spec import SAMPLE_COLUMN, row_params, spec_from_dict, variants_table

N = 60  # variants of the fake sweeps: time_shift_s in [-3, 3] (61 points minus one)


def _spec(num: int = N):
    return spec_from_dict(
        {"design": "grid", "parameters": {"time_shift_s": {"min": -3.0, "max": 3.0, "num": num}}}
    )


def test_whole_design_ids_and_seeds_equal_one_at_a_time():
    pts = pd.DataFrame(
        {
            "time_shift_s": [0.0, -0.0, np.nan, 1e-300, 3.0, 0.1 + 0.2, 3.0],
            "ego.policy": ["none", 'a"é\\', "none", True, 1, 1.0, "none"],
            "sample": np.array([0, 1, 2, 3, 4, 5, 0], dtype=np.int64),
            "sfm.use_vehicle_force": [True, False, True, True, False, False, True],
        }
    )
    for sid in ("demo", 'odd "ü" id'):
        one = [variant_id(sid, r) for r in pts.to_dict("records")]
        assert variant_ids(sid, pts) == one
        assert list(variant_seeds(one, 7)) == [variant_seed(v, 7) for v in one]
    ids = variant_ids("demo", pts)
    assert ids[0] != ids[1]  # -0.0 and 0.0 print differently, so they are two variants
    assert ids[4] != ids[6] and len(set(ids)) == len(ids)
    # hand-checked payload of the canonical form: repr of the float, sorted keys, no spaces
    import hashlib

    text = '{"params":{"time_shift_s":"0.5"},"scenario":"s"}'
    want = hashlib.sha256(text.encode()).hexdigest()[:16]
    assert variant_ids("s", pd.DataFrame({"time_shift_s": [0.5]})) == [want]
    assert variant_ids("s", pd.DataFrame(index=range(2))) == [variant_id("s", {})] * 2


@pytest.mark.parametrize(
    "raw",
    [
        {"design": "grid", "parameters": {"time_shift_s": {"min": -3, "max": 3, "num": 7},
                                          "rider_model": {"choices": ["normal", "aggressive"]}}},
        {"design": "random", "n_samples": 40, "seed": 3,
         "parameters": {"ego.cruise_speed_mps": {"min": 3, "max": 9},
                        "sfm.use_vehicle_force": {"choices": [True, False]},
                        "ego.policy": {"choices": ["none", "paper-cap"]}}},
        {"design": "grid", "seed": 4, "parameters": {"time_shift_s": {"choices": [-1.0, 1.0]}},
         "rider": {"profile": "calibrated", "sample": 3}},
        {"design": "grid", "parameters": {"time_shift_s": {"choices": [0.5]}},
         "reconstruction": {"samples": 3}},
    ],
)  # fmt: skip
def test_unnamed_variants_named_later_equal_the_named_table(raw):
    """A fresh sweep's table leaves the ids to the workers: naming any slice of it later
    gives the named table's rows (ids, seeds, columns, dtypes)."""
    spec = spec_from_dict(raw)
    named = variants_table(spec, "scen")
    bare = variants_table(spec, "scen", named=False)
    assert "variant_id" not in bare and "seed" not in bare
    pd.testing.assert_frame_equal(name_variants(bare, spec.seed), named)
    lo, hi = 1, len(named) - 1
    part = name_variants(bare.iloc[lo:hi], spec.seed)  # a chunk, named by its worker
    pd.testing.assert_frame_equal(part, named.iloc[lo:hi])
    for i in (0, len(named) - 1):  # = the id of the row's own parameters
        row = named.iloc[i]
        assert row["variant_id"] == variant_id("scen", row_params(row, spec) | extra(row))


def extra(row):
    """The columns beside the spec's parameters that enter a variant's id."""
    return {
        c: row[c] for c in row.index if c in (SAMPLE_COLUMN, RIDER_COLUMN, *RIDER_PARAM_COLUMNS)
    }


def test_repeated_design_points_are_named_and_kept_once():
    """Equal points (random draws of sets repeat) are named and de-duplicated up front;
    rows of several scenarios are each named with their own scenario id."""
    spec = spec_from_dict(
        {"design": "random", "n_samples": 30, "seed": 1,
         "parameters": {"time_shift_s": {"choices": [-1.0, 0.0, 1.0]},
                        "rider_model": {"choices": ["normal", "aggressive"]}}}
    )  # fmt: skip
    table = variants_table(spec, "scen", named=False)
    assert "variant_id" in table and len(table) == 6  # 30 draws of 3 x 2 points
    assert table.equals(variants_table(spec, "scen"))
    two = pd.concat([variants_table(spec, s) for s in ("a", "b")], ignore_index=True)
    named = name_variants(two.drop(columns=["variant_id", "seed"]), spec.seed)
    pd.testing.assert_frame_equal(named, two)
    assert not set(two["variant_id"][:6]) & set(two["variant_id"][6:])


def test_auto_chunk_size_and_threads_per_worker():
    assert auto_chunk_size(100_000, 2) == MAX_AUTO_CHUNK == 4096  # 10^5 / 16 > the cap
    assert auto_chunk_size(50_000, 2) == 3125  # 8 chunks per worker
    assert auto_chunk_size(10_016, 2) == 626 and auto_chunk_size(10_017, 2) == 627
    assert auto_chunk_size(3, 4) == 1 and auto_chunk_size(0, 1) == 1
    assert threads_per_worker(2, cpus=2) == 1
    assert threads_per_worker(2, cpus=16) == 8
    assert threads_per_worker(3, cpus=2) == 1
    assert threads_per_worker(1, cpus=4) == 4


def test_the_scenario_reaches_each_worker_once(tmp_path):
    """12 chunks over 2 workers: each worker unpickles the prepared scenario once (from the
    file), not with every chunk; the parent prepares it once."""
    (scen,) = fake_scenarios(tmp_path, ["one"])
    ev = FakeEvaluator()
    res = run_sweep(scen, _spec(), tmp_path / "out", workers=2, chunk_size=5, evaluator=ev)
    assert res.n_run == N and ev.prepares == 1
    rows = read_results(tmp_path / "out")
    assert rows["pid"].nunique() <= 2
    assert rows.groupby("pid")["unpickled"].max().max() == 1
    assert (rows["payload_sum"] == float(np.arange(100_000).sum())).all()
    # each worker runs the compiled kernel on its share of the cores
    assert set(rows["threads"]) == {threads_per_worker(2)}
    # two scenarios: prepared in the pool (in parallel); each worker loads each at most once
    scens = fake_scenarios(tmp_path / "many", ["a", "b"])
    res = run_sweep(scens, _spec(), tmp_path / "two", workers=2, chunk_size=5, evaluator=ev)
    rows = read_results(tmp_path / "two")
    assert res.n_run == 2 * N and ev.prepares == 1  # the parent prepared none of them
    assert rows.groupby("pid")["unpickled"].max().max() <= 2


def test_rows_equal_the_formulas_and_keep_their_dtypes(tmp_path):
    (scen,) = fake_scenarios(tmp_path, ["one"])
    run_sweep(scen, _spec(), tmp_path / "out", chunk_size=7, evaluator=FakeEvaluator())
    rows = read_results(tmp_path / "out")
    x = np.linspace(-3.0, 3.0, N)
    assert list(rows["variant_index"]) == list(range(N))
    np.testing.assert_array_equal(rows["time_shift_s"].to_numpy(), x)
    np.testing.assert_array_equal(rows["collision"].to_numpy(), x > 0)
    np.testing.assert_array_equal(rows["min_gap_m"].to_numpy(), x + 3.0)
    assert list(rows["side"]) == ["front" if v > 0 else "" for v in x]
    assert rows["collision"].dtype == bool and rows["variant_index"].dtype == np.int64
    assert rows["safety_index"].dtype == np.float64 and rows["seed"].dtype == np.int64
    assert pd.api.types.is_string_dtype(rows["variant_id"]) and rows["variant_id"].is_unique


def test_resumed_pool_sweep_equals_an_uninterrupted_one(tmp_path):
    (scen,) = fake_scenarios(tmp_path, ["one"])
    spec = _spec()
    out = tmp_path / "resumed"
    first = run_sweep(scen, spec, out, chunk_size=4, max_chunks=5, evaluator=FakeEvaluator())
    assert first.n_run == 20 and not (out / "results.parquet").exists()
    # a second partial run: its parts fill gaps after the first run's, numbered after them
    again = run_sweep(scen, spec, out, chunk_size=7, max_chunks=2, evaluator=FakeEvaluator())
    assert again.n_skipped == 20 and again.n_run == 14
    done = run_sweep(scen, spec, out, workers=2, chunk_size=3, evaluator=FakeEvaluator())
    assert done.n_skipped == 34 and done.n_run == N - 34
    # the resumed parts fill gaps without overlap: results.parquet was streamed
    assert _in_order(_existing_parts(out / "parts")) is not None
    run_sweep(scen, spec, tmp_path / "whole", evaluator=FakeEvaluator())
    drop = ["pid", "unpickled", "threads"]
    a, b = read_results(out).drop(columns=drop), read_results(tmp_path / "whole").drop(columns=drop)
    pd.testing.assert_frame_equal(a, b)


def test_overlapping_parts_are_deduplicated_and_sorted(tmp_path):
    """results.parquet from parts in order is streamed; from parts with a duplicate chunk
    and out of order it is rebuilt; both give the same table as assemble_results."""
    (scen,) = fake_scenarios(tmp_path, ["one"])
    out = tmp_path / "out"
    run_sweep(scen, _spec(), out, chunk_size=8, evaluator=FakeEvaluator())
    ref = read_results(out)
    parts = sorted((out / "parts").glob("part-*.parquet"))
    shutil.copy(parts[0], out / "parts" / "part-000100.parquet")  # a duplicate chunk
    parts[3].rename(out / "parts" / "part-000050.parquet")  # out of order
    assert _in_order(_existing_parts(out / "parts")) is None  # overlap: loaded and sorted
    write_results(out, tmp_path / "again.parquet")
    again = pd.read_parquet(tmp_path / "again.parquet")
    pd.testing.assert_frame_equal(again, ref)
    pd.testing.assert_frame_equal(assemble_results(out), ref)
    # restricted to a table's ids
    table = ref.iloc[::2]
    write_results(out, tmp_path / "half.parquet", table)
    half = pd.read_parquet(tmp_path / "half.parquet")
    pd.testing.assert_frame_equal(half, ref.iloc[::2].reset_index(drop=True))


def test_most_critical_equals_a_full_sort_with_nan_and_ties():
    rng = np.random.default_rng(3)
    n = 500
    df = pd.DataFrame(
        {
            "variant_id": [f"v{i}" for i in range(n)],
            "collision": rng.random(n) < 0.3,
            "safety_index": np.where(rng.random(n) < 0.1, np.nan, rng.integers(0, 5, n) / 4),
            "min_gap_m": np.where(rng.random(n) < 0.1, np.nan, rng.integers(0, 3, n) * 1.0),
        }
    )
    ref = df.sort_values(
        ["collision", "safety_index", "min_gap_m"], ascending=[False, True, True], kind="stable"
    )
    pd.testing.assert_frame_equal(most_critical(df, 40), ref.head(40).reset_index(drop=True))


def test_chunks_cover_the_table_in_order_with_a_finer_tail():
    from vei.sweep.run import _chunks

    frame = pd.DataFrame({"i": np.arange(103)})
    sizes = [len(c) for c in _chunks(frame, 10, tail=4)]
    # 63 rows in chunks of 10 (the last one cut where the tail starts), then 40 in 2-row chunks
    assert sizes == [10] * 6 + [3] + [2] * 20
    got = pd.concat(list(_chunks(frame, 10, tail=4)))["i"].to_numpy()
    np.testing.assert_array_equal(got, np.arange(103))
    assert [len(c) for c in _chunks(frame, 50)] == [50, 50, 3]  # no tail: plain chunks
    assert [len(c) for c in _chunks(frame, 3, tail=100)] == [1] * 103  # all tail, >= 1 row


def test_phase_timings_and_throughput(tmp_path):
    import json
    import math

    import pytest

    (scen,) = fake_scenarios(tmp_path, ["one"])
    out = tmp_path / "out"
    res = run_sweep(scen, _spec(), out, workers=2, chunk_size=7, evaluator=FakeEvaluator())
    assert list(res.timings) == ["prepare", "evaluate", "results", "post"]
    assert all(v >= 0.0 for v in res.timings.values())
    assert sum(res.timings.values()) <= res.seconds
    busy = res.timings["prepare"] + res.timings["evaluate"] + res.timings["results"]
    assert res.variants_per_s == pytest.approx(N / busy)
    manifest = json.loads((out / "sweep.json").read_text())
    assert manifest["timings_s"] == {k: round(v, 3) for k, v in res.timings.items()}
    # 2 workers: this process computes chunks too (it takes the third while the child
    # starts), and one child does the rest
    pids = set(read_results(out)["pid"])
    assert os.getpid() in pids and len(pids) <= 2
    again = run_sweep(scen, _spec(), out, workers=2, chunk_size=7, evaluator=FakeEvaluator())
    assert again.n_run == 0 and math.isnan(again.variants_per_s)  # nothing ran this time


class _FailingWarmUp(FakeEvaluator):
    """A fake whose workers fail while starting (their warm-up raises)."""

    def warm_up(self, load_kernel: bool = False) -> None:
        raise RuntimeError("warm-up failed on purpose")


def test_a_worker_that_fails_to_start_stops_the_sweep_and_loses_nothing(tmp_path):
    """The sweep's process computes chunks itself, but a child that dies while starting
    is an error (not chunks silently left undone); a rerun completes the sweep."""
    from concurrent.futures.process import BrokenProcessPool

    import pytest

    (scen,) = fake_scenarios(tmp_path, ["one"])
    out = tmp_path / "out"
    with pytest.raises(BrokenProcessPool):
        run_sweep(scen, _spec(), out, workers=2, chunk_size=5, evaluator=_FailingWarmUp())
    assert not (out / "results.parquet").exists()
    res = run_sweep(scen, _spec(), out, workers=2, chunk_size=5, evaluator=FakeEvaluator())
    assert res.n_run + res.n_skipped == N
    assert len(read_results(out)) == N
