"""Sweeps: many variants of one or many scenarios through the batched engine, crash-safe.

Output folder layout (``out_dir``)::

    sweep.json            what this sweep is: spec (and its digest), scenarios, status
    parts/part-000000.parquet ...   one file per finished chunk, each written atomically
    results.parquet       all rows, assembled atomically when every variant is done
    critical.csv / .json  the most critical variants (see :func:`most_critical`)
    configs/<variant_id>.yaml   each critical variant as a run configuration (vei run --config)
    riskmap.png           mean safety index over the first two range parameters + boundary
    severity_map.png      mean injury risk of the rider over the same plane + boundary
    probability_map.png   P(collision | cell) where its 95 % CI is within +-0.1, the rest
                          hatched as not known (vei.sweep.riskmap.sweep_probability_map)
                          (severity_map_<policy>.png, one per policy, when it is swept)
    policy_comparison.csv when the policy is swept with 'none': per policy, collisions,
                          impact speeds, injury risk and the verdicts against 'none' at the
                          same design point (vei.sweep.compare)
    reconstruction_samples.json, reconstruction_share.png   with ``reconstruction: {samples:
                          N}``: how many design points depend on the rider's sample, and
                          the share of samples without collision per design point

Resume design: a chunk's rows reach the disk only as a whole part file (temporary file +
rename), so a part file that exists is complete. On (re)start the variant ids in the
existing parts are the ids done; only the others are run, in new parts numbered after the
last one. A sweep killed at any instant (SIGKILL included) therefore loses at most the
chunks in flight and never duplicates a row; ``results.parquet`` is rebuilt from the parts
at the end (and de-duplicated by variant id as a last guard), streamed part by part when
the parts are in order (the usual case), so memory holds one part and not the whole
result. A resume with a different
spec is refused (the spec digest is in ``sweep.json``).

The evaluation of a chunk goes through an :class:`Evaluator` (default: the built-in
engine + the metrics registry); ``engine='ray'`` runs chunks as Ray tasks, each scenario
prepared once and shared through the object store. Results do not depend on the engine,
the chunk size or the number of workers: the engine is deterministic and a variant's
outcome does not depend on the other variants of its batch.
"""

from __future__ import annotations

import contextlib
import json
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd

from vei.errors import ConfigError, InputError
from vei.io.atomic import write_json

# The evaluator (engine parameters of a variants table; _PARAM_FIELDS maps sweep columns
# to engine parameters), the storage and the executors live in their own modules; their
# public names stay importable from here.
from vei.sweep.evaluator import (  # noqa: F401 - _PARAM_FIELDS re-exported
    _PARAM_FIELDS,
    DEFAULT_METRICS,
    EngineEvaluator,
    Evaluator,
    PreparedScenario,
    variant_params,
)
from vei.sweep.io import (
    PART_RE,
    SWEEP_FORMAT,
    _clean_temporaries,
    _existing_parts,
    assemble_results,
    done_ids,
    json_records,
    most_critical,
    numeric_metric_columns,
    read_results,
    write_results,
    write_variant_configs,
)
from vei.sweep.runners import _key_of, _runner
from vei.sweep.spec import SAMPLE_COLUMN, SweepSpec, name_variants, variants_table

__all__ = [
    "DEFAULT_METRICS",
    "PART_RE",
    "SWEEP_FORMAT",
    "EngineEvaluator",
    "Evaluator",
    "PreparedScenario",
    "SweepResult",
    "assemble_results",
    "done_ids",
    "find_scenarios",
    "json_records",
    "most_critical",
    "numeric_metric_columns",
    "read_results",
    "run_sweep",
    "variant_params",
    "write_results",
    "write_variant_configs",
]


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` did.

    Attributes:
        out_dir: the output folder; results: path of results.parquet.
        n_variants: variants in the sweep (all scenarios); n_run: run by this call;
        n_skipped: already done by an earlier (interrupted) call; seconds: wall time.
        timings: wall time of each phase [s]: ``prepare`` (scenarios read and compiled,
            automatic time shifts, variants tables, manifest), ``evaluate`` (every chunk
            simulated, scored and written as a part file), ``results`` (results.parquet
            assembled, critical variants ranked and written with their configurations),
            ``post`` (the critical variants' recording and figures, risk / severity maps,
            comparisons). Phases not reached are absent.
    """

    out_dir: Path
    results: Path
    n_variants: int
    n_run: int
    n_skipped: int
    seconds: float
    timings: dict[str, float] = field(default_factory=dict)

    @property
    def variants_per_s(self) -> float:
        """Throughput of this call [variants/s]: variants run / (prepare + evaluate +
        results); the post phase is a fixed cost per sweep (figures of the k critical
        variants, two maps), not per variant. NaN when nothing ran."""
        busy = sum(self.timings.get(k, 0.0) for k in ("prepare", "evaluate", "results"))
        return self.n_run / busy if self.n_run and busy > 0 else float("nan")


def find_scenarios(path: str | Path) -> list[Path]:
    """Scenario folders under ``path``: the folder itself if it holds scenario.json, else
    its sub-folders that do (sorted by name).

    Raises:
        InputError: the path does not exist or holds no scenario.
    """
    path = Path(path)
    if not path.exists():
        raise InputError("no such scenario folder", path=path)
    if (path / "scenario.json").is_file():
        return [path]
    found = sorted(p for p in path.iterdir() if p.is_dir() and (p / "scenario.json").is_file())
    if not found:
        raise InputError(
            "neither a scenario folder (scenario.json) nor a folder of scenario folders", path=path
        )
    return found


#: Largest automatic chunk [variants]. The default metrics are scored in the compiled
#: kernel's pass (no [B, T] series: a chunk of 4096 adds no measurable memory to a worker);
#: the per-chunk costs (parameters, rows, part file) are ~2 % of a chunk's time at 4096.
MAX_AUTO_CHUNK = 4096

#: Chunks per worker the automatic size aims at. The last 2 x workers chunks are split in
#: quarters (:func:`_chunks`), so the workers finish within ~1/32 of a share of each other;
#: more, smaller chunks would only add their fixed cost (~8 ms each: parameters, naming,
#: rows, part file; measured on the demo).
_CHUNKS_PER_WORKER = 8


def auto_chunk_size(n_variants: int, workers: int) -> int:
    """The default chunk size [variants] of a sweep of ``n_variants`` over ``workers``:
    at least :data:`_CHUNKS_PER_WORKER` chunks per worker (both workers stay busy to the
    end), at most :data:`MAX_AUTO_CHUNK` (bounds memory), at least 1."""
    per = -(-int(n_variants) // (_CHUNKS_PER_WORKER * max(1, int(workers))))
    return max(1, min(MAX_AUTO_CHUNK, per))


def _chunks(frame: pd.DataFrame, size: int, tail: int = 0) -> Iterator[pd.DataFrame]:
    """``frame`` in chunks of ``size`` rows; the last ``tail`` chunks' rows in chunks of a
    quarter of that (the workers then finish within a quarter chunk of each other)."""
    fine = max(1, size // 4)
    split = max(0, len(frame) - tail * size) if tail > 0 and fine < size else len(frame)
    for start in range(0, split, size):
        yield frame.iloc[start : min(start + size, split)]
    for start in range(split, len(frame), fine):
        yield frame.iloc[start : start + fine]


@contextlib.contextmanager
def _progress(total: int, done: int, enabled: bool | None) -> Iterator[Callable[[int], None]]:
    """advance(n): a bar on a terminal, a line at least every 10 s otherwise (None), or
    nothing (False)."""
    from vei.io.progress import progress

    with progress("sweep", total, unit="variants", done=done, enabled=enabled) as rep:
        yield rep.advance


def run_sweep(
    scenarios: str | Path | Sequence[str | Path],
    spec: SweepSpec,
    out_dir: str | Path,
    *,
    engine: str = "local",
    workers: int = 1,
    chunk_size: int | None = None,
    evaluator: Evaluator | None = None,
    progress: bool | None = None,
    max_chunks: int | None = None,
    k_critical: int = 20,
    record_critical: bool = True,  # [H5]
) -> SweepResult:
    """Run (or resume) a sweep: every variant of ``spec`` on every scenario.

    Args:
        scenarios: a scenario folder, a folder of scenario folders, or a list of folders.
        spec: the sweep spec (design and parameters).
        out_dir: output folder (layout and resume design in the module docstring).
        engine: 'local' (this process; ``workers`` > 1 = that many worker processes) or
            'ray' (``ray.init(num_cpus=workers)`` unless Ray is already initialised).
        workers: parallel workers (>= 1). With more than one, each is a process that
            gets the evaluator and each prepared scenario once and runs the compiled
            kernel on its share of the cores (:mod:`vei.sweep.runners`).
        chunk_size: variants per engine batch (bounds memory: one chunk's traces at a time
            per worker), >= 1; None: :func:`auto_chunk_size` of the variants to run.
        evaluator: how a chunk is evaluated; default :class:`EngineEvaluator`.
        progress: None (default): a progress bar when stderr is a terminal, else a line
            at least every 10 s (vei.io.progress); True: the same; False: silent.
        max_chunks: stop after this many chunks (for tests and partial runs); the sweep
            stays resumable and results.parquet is only assembled once every variant is done.
        k_critical: how many most-critical variants go to critical.csv/json and configs/.
        record_critical: re-run the critical variants with the full recording
            (critical/timeseries.parquet, figures; :mod:`vei.sweep.critical`).

    Returns:
        a :class:`SweepResult`. results.parquet: one row per variant, the variants-table
        columns (variant_id, scenario_id, variant_index, seed, parameters) then the metrics,
        sorted by (scenario_id, variant_index).

    Raises:
        ConfigError: bad engine/workers/chunk_size, or ``out_dir`` holds another sweep.
        InputError: a scenario folder is missing or unreadable.
    """
    t0 = time.perf_counter()
    if engine not in ("local", "ray"):
        raise ConfigError(f"engine must be 'local' or 'ray', got {engine!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers must be an integer >= 1, got {workers!r}")
    if chunk_size is not None and (
        isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1
    ):
        raise ConfigError(f"chunk_size must be an integer >= 1, got {chunk_size!r}")
    if evaluator is None:
        from vei.sweep.params import reach_sim, reach_speed_of

        evaluator = EngineEvaluator(
            time_shift_reference=spec.time_shift_reference,
            base=spec.base,
            reconstruction_samples=spec.reconstruction_samples,
            sample_seed=spec.seed,
            perception=spec.perception,
            v2x=spec.v2x,
            # continuations reach beyond the car at the sweep's largest cruise speed
            sim=reach_sim(reach_speed_of(spec)),
        )
    dirs = (
        find_scenarios(scenarios)
        if isinstance(scenarios, str | Path)
        else [d for s in scenarios for d in find_scenarios(s)]
    )
    out = Path(out_dir)
    parts_dir = out / "parts"
    parts_dir.mkdir(parents=True, exist_ok=True)
    _clean_temporaries(parts_dir)

    timings: dict[str, float] = {}
    t_start = time.perf_counter()
    with _runner(engine, workers, evaluator) as runner:
        n_skipped, n_run, table, scen_meta, prepared = _run_jobs(
            runner, dirs, spec, out, evaluator, chunk_size, workers, max_chunks,
            None if progress is None else bool(progress), timings,
        )  # fmt: skip
    # evaluate: from the end of prepare to the last worker gone
    timings["evaluate"] = time.perf_counter() - t_start - timings["prepare"]
    manifest_path = out / "sweep.json"
    manifest = json.loads(manifest_path.read_text(encoding="utf-8"))

    results_path = out / "results.parquet"
    n_variants = len(table)
    if n_skipped + n_run >= n_variants:
        t_results = time.perf_counter()
        # streamed part by part into results.parquet, then read back (only the columns
        # the critical ranking and the maps need, unless policies or samples are compared)
        # restricted to the table's ids where it has them (the rows of a fresh sweep's
        # parts are this call's: the count is checked)
        named = "variant_id" in table
        n_rows = write_results(out, results_path, table if named else None)
        if n_rows != n_variants:
            raise RuntimeError(f"results.parquet has {n_rows} rows, the sweep {n_variants}")
        del table
        whole = "ego.policy" in spec.names or bool(spec.reconstruction_samples)
        results = read_results(out, columns=None if whole else _post_columns(results_path, spec))
        crit = _critical_rows(results_path, most_critical(results, k_critical), whole, results)
        from vei.io.atomic import write_text

        write_text(out / "critical.csv", crit.to_csv(index=False))
        write_json(out / "critical.json", json_records(crit))
        for sid, rows in crit.groupby("scenario_id", sort=False):
            d = next(m["path"] for m in scen_meta if m["id"] == sid)
            write_variant_configs(
                out / "configs", rows, spec, evaluator.auto_shift_s(prepared[_key_of(d, prepared)])
            )
        t_post = time.perf_counter()
        timings["results"] = t_post - t_results
        if record_critical:  # [H5] the full recording of the critical variants only
            from vei.sweep.critical import record_critical as _record_critical

            _record_critical(out, crit, evaluator, prepared)
        from vei.sweep.riskmap import sweep_risk_map, sweep_severity_maps

        risk = sweep_risk_map(results, spec, out / "riskmap.png")
        from vei.sweep.riskmap import sweep_probability_map

        sweep_probability_map(results, spec, out / "probability_map.png")  # issue 23
        sweep_severity_maps(results, spec, out)
        if "ego.policy" in spec.names and (results["ego.policy"].astype(str) == "none").any():
            from vei.calibrate.population import RIDER_COLUMN
            from vei.io.atomic import write_text
            from vei.sweep.compare import policy_summary, policy_verdicts

            extra = [c for c in ("scenario_id", SAMPLE_COLUMN, RIDER_COLUMN) if c in results]
            design = [*extra, *(n for n in spec.names if n != "ego.policy")]
            comparison = policy_summary(policy_verdicts(results, design))
            write_text(out / "policy_comparison.csv", comparison.to_csv(index=False))
        if spec.reconstruction_samples and SAMPLE_COLUMN in results.columns:
            from vei.report.uncertainty import sample_dependence, write_sample_share_map

            design = ["scenario_id", *spec.names]
            summary, per_point = sample_dependence(results, design, SAMPLE_COLUMN)
            write_json(out / "reconstruction_samples.json", summary)
            if risk is not None:
                write_sample_share_map(
                    per_point, risk["x"], risk["y"], out / "reconstruction_share.png"
                )
        timings["post"] = time.perf_counter() - t_post
        from vei.metrics.seen import flag_counts

        # runs no planner could have reacted to (vei.metrics.seen), counted apart
        manifest["seen_too_late"] = flag_counts(results)
        manifest["status"] = "complete"
        manifest["updated_utc"] = datetime.now(UTC).isoformat(timespec="seconds")
        manifest["timings_s"] = {k: round(v, 3) for k, v in timings.items()}
        write_json(manifest_path, manifest)
    return SweepResult(
        out_dir=out,
        results=results_path,
        n_variants=n_variants,
        n_run=n_run,
        n_skipped=n_skipped,
        seconds=time.perf_counter() - t0,
        timings=timings,
    )


#: Columns the ranking of critical variants and the risk / severity maps read.
_POST_COLUMNS = (
    "variant_id",
    "scenario_id",
    "variant_index",
    "collision",
    "safety_index",
    "min_gap_m",
    "injury_risk",
    "impact_speed_mps",
    "seen_too_late",
)


def _post_columns(results_path: Path, spec: SweepSpec) -> list[str]:
    """The columns of results.parquet that the critical ranking and the maps need."""
    import pyarrow.parquet as pq

    have = pq.read_schema(results_path).names
    want = {*_POST_COLUMNS, *spec.names}
    return [c for c in have if c in want]


def _critical_rows(
    results_path: Path, crit: pd.DataFrame, whole: bool, results: pd.DataFrame
) -> pd.DataFrame:
    """The full rows (every column) of the critical variants ``crit`` (in its order) when
    ``crit`` holds only some columns: read from results.parquet by their row numbers in
    ``results`` (the same file read with fewer columns), one row group at a time."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.parquet as pq

    if whole or crit.empty:
        return crit
    pos = pd.Index(results["variant_id"]).get_indexer(crit["variant_id"])
    if np.any(pos < 0):
        raise RuntimeError("critical variants missing from results.parquet")
    pf = pq.ParquetFile(results_path)
    sizes = [pf.metadata.row_group(i).num_rows for i in range(pf.metadata.num_row_groups)]
    starts = np.concatenate([[0], np.cumsum(sizes)])
    groups = np.searchsorted(starts, pos, side="right") - 1
    read = {int(g): pf.read_row_group(int(g)) for g in np.unique(groups)}
    rows = pa.concat_tables(
        [read[int(g)].slice(int(p - starts[g]), 1) for p, g in zip(pos, groups, strict=True)]
    )
    return rows.to_pandas()


def _run_jobs(
    runner: Any,
    dirs: Sequence[Path],
    spec: SweepSpec,
    out: Path,
    evaluator: Evaluator,
    chunk_size: int | None,
    workers: int,
    max_chunks: int | None,
    progress: bool | None,
    timings: dict[str, float],
) -> tuple[int, int, pd.DataFrame, list[dict[str, Any]], dict[str, Any]]:
    """Prepare the scenarios, check / write the manifest, run the chunks not yet done and
    write each as a part file (the runner writes them; part numbers are handed out here, in
    job order). Returns (n_skipped, n_run, variants table, scenario
    metadata, prepared scenarios); sets ``timings['prepare']`` [s] (the caller's clock
    starts before the runner is opened)."""
    t0 = time.perf_counter()
    parts_dir = out / "parts"
    existing = _existing_parts(parts_dir)
    prepared = runner.prepare_all(dirs)
    tables = []
    scen_meta = []
    for d in dirs:
        sid = evaluator.scenario_id(prepared[str(d)])
        # a fresh sweep leaves the naming of its variants to the workers (no ids up front)
        tables.append(variants_table(spec, sid, named=bool(existing)))
        scen_meta.append({"id": sid, "path": str(Path(d).resolve()), "n_variants": len(tables[-1])})
    ids_seen = [m["id"] for m in scen_meta]
    if len(set(ids_seen)) != len(ids_seen):
        raise InputError(f"two scenario folders share a scenario id: {ids_seen}", path=out)
    if any("variant_id" in t for t in tables):  # all named or none
        tables = [t if "variant_id" in t else name_variants(t, spec.seed) for t in tables]
    table = pd.concat([t.assign(_dir=str(d)) for t, d in zip(tables, dirs, strict=True)])
    table = table.reset_index(drop=True)
    id_seed = None if "variant_id" in table else spec.seed

    manifest_path = out / "sweep.json"
    digest = spec.digest()
    if manifest_path.exists():
        try:
            old = json.loads(manifest_path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputError(f"cannot read the sweep manifest: {exc}", path=manifest_path) from exc
        if old.get("spec_digest") != digest:
            raise ConfigError(
                f"{out} holds a sweep with a different spec (digest {old.get('spec_digest')} != "
                f"{digest}); choose another --out folder"
            )
    manifest = {
        "format": SWEEP_FORMAT,
        "spec_digest": digest,
        "spec": spec.to_dict(),
        "scenarios": scen_meta,
        "n_variants": len(table),
        "chunk_size": chunk_size,  # None: automatic (auto_chunk_size)
        "status": "running",
        "updated_utc": datetime.now(UTC).isoformat(timespec="seconds"),
    }
    write_json(manifest_path, manifest)

    todo = table[~table["variant_id"].isin(done_ids(out))] if existing else table
    n_skipped = len(table) - len(todo)
    next_seq = 1 + max((int(PART_RE.match(p.name).group(1)) for p in existing), default=-1)

    size = chunk_size or auto_chunk_size(len(todo), workers)

    def jobs() -> Iterator[tuple[str, pd.DataFrame, Path, int | None]]:
        # Made as the runner asks for them (a few chunks ahead), not all at once.
        nonlocal next_seq
        n = 0
        for d, grp in todo.groupby("_dir", sort=False):
            for chunk in _chunks(grp.drop(columns="_dir"), size, 2 * workers if workers > 1 else 0):
                if max_chunks is not None and n >= max_chunks:
                    return
                yield str(d), chunk, parts_dir / f"part-{next_seq:06d}.parquet", id_seed
                next_seq += 1
                n += 1

    n_run = 0
    timings["prepare"] = time.perf_counter() - t0
    with _progress(len(table), n_skipped, progress) as advance:
        for n_rows in runner.run(jobs(), prepared):
            n_run += n_rows
            advance(n_rows)
    return n_skipped, n_run, table, scen_meta, prepared
