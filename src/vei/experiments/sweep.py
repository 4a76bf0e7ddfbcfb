"""Sweeps: many variants of one or many scenarios through the batched engine, crash-safe.

Output folder layout (``out_dir``)::

    sweep.json            what this sweep is: spec (and its digest), scenarios, status
    parts/part-000000.parquet ...   one file per finished chunk, each written atomically
    results.parquet       all rows, assembled atomically when every variant is done
    critical.csv / .json  the most critical variants (see :func:`most_critical`)
    configs/<variant_id>.yaml   each critical variant as a run configuration (vei run --config)
    riskmap.png           mean safety index over the first two range parameters + boundary
    reconstruction_samples.json, reconstruction_share.png   with ``reconstruction: {samples:
                          N}``: how many design points depend on the rider's sample, and
                          the share of samples without collision per design point

Resume design: a chunk's rows reach the disk only as a whole part file (temporary file +
rename), so a part file that exists is complete. On (re)start the variant ids in the
existing parts are the ids done; only the others are run, in new parts numbered after the
last one. A sweep killed at any instant (SIGKILL included) therefore loses at most the
chunks in flight and never duplicates a row; ``results.parquet`` is rebuilt from the parts
at the end (and de-duplicated by variant id as a last guard). A resume with a different
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
import os
import re
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import Any, Protocol

import numpy as np
import pandas as pd

from vei.calibrate.population import RIDER_COLUMN, RIDER_PARAM_COLUMNS
from vei.errors import ConfigError, InputError
from vei.experiments.sweep_spec import SAMPLE_COLUMN, SweepSpec, variants_table
from vei.io.atomic import write_json, write_parquet

SWEEP_FORMAT = "vei.sweep/1"
PART_RE = re.compile(r"^part-(\d{6,})\.parquet$")


class Evaluator(Protocol):
    """Turns a scenario and a chunk of variants into one metrics row per variant.

    ``prepare(scenario_dir)`` runs once per scenario and worker and returns a picklable
    object (the scenario read and compiled); ``evaluate(prepared, variants)`` takes a
    variants-table slice [B rows] and returns a DataFrame of B rows in the same order with
    a ``variant_id`` column and one column per metric (it must not depend on which other
    variants share the chunk).
    """

    def prepare(self, scenario_dir: Path) -> Any: ...

    def scenario_id(self, prepared: Any) -> str: ...

    def evaluate(self, prepared: Any, variants: pd.DataFrame) -> pd.DataFrame: ...

    def auto_shift_s(self, prepared: Any) -> float | None: ...


@dataclass(frozen=True)
class SweepResult:
    """What :func:`run_sweep` did.

    Attributes:
        out_dir: the output folder; results: path of results.parquet.
        n_variants: variants in the sweep (all scenarios); n_run: run by this call;
        n_skipped: already done by an earlier (interrupted) call; seconds: wall time.
    """

    out_dir: Path
    results: Path
    n_variants: int
    n_run: int
    n_skipped: int
    seconds: float


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


def _existing_parts(parts_dir: Path) -> list[Path]:
    if not parts_dir.is_dir():
        return []
    return sorted(p for p in parts_dir.iterdir() if PART_RE.match(p.name))


def _clean_temporaries(parts_dir: Path) -> int:
    """Remove temporary files a killed writer left behind (.part-*.tmp); returns how many."""
    n = 0
    if parts_dir.is_dir():
        for p in parts_dir.iterdir():
            if p.name.startswith(".") and p.name.endswith(".tmp"):
                with contextlib.suppress(FileNotFoundError):
                    p.unlink()
                    n += 1
    return n


def done_ids(out_dir: str | Path) -> set[str]:
    """Variant ids already written in ``out_dir/parts`` (every part file is complete).

    Raises:
        InputError: a part file cannot be read (names it).
    """
    import pyarrow.parquet as pq

    ids: set[str] = set()
    for p in _existing_parts(Path(out_dir) / "parts"):
        try:
            col = pq.read_table(p, columns=["variant_id"]).column("variant_id").to_pylist()
        except Exception as exc:  # pyarrow raises several types for a damaged file
            raise InputError(
                f"cannot read sweep part ({exc}); delete it to re-run its chunk", path=p
            ) from exc
        ids.update(col)
    return ids


def _chunks(frame: pd.DataFrame, size: int) -> Iterator[pd.DataFrame]:
    for start in range(0, len(frame), size):
        yield frame.iloc[start : start + size]


@contextlib.contextmanager
def _progress(total: int, done: int, enabled: bool) -> Iterator[Callable[[int], None]]:
    if not enabled:
        yield lambda n: None
        return
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    with Progress(
        TextColumn("sweep"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("variants"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        transient=False,
    ) as prog:
        task = prog.add_task("sweep", total=total, completed=done)
        yield lambda n: prog.advance(task, n)


def run_sweep(
    scenarios: str | Path | Sequence[str | Path],
    spec: SweepSpec,
    out_dir: str | Path,
    *,
    engine: str = "local",
    workers: int = 1,
    chunk_size: int = 2048,
    evaluator: Evaluator | None = None,
    progress: bool | None = None,
    max_chunks: int | None = None,
    k_critical: int = 20,
) -> SweepResult:
    """Run (or resume) a sweep: every variant of ``spec`` on every scenario.

    Args:
        scenarios: a scenario folder, a folder of scenario folders, or a list of folders.
        spec: the sweep spec (design and parameters).
        out_dir: output folder (layout and resume design in the module docstring).
        engine: 'local' (this process; ``workers`` > 1 = that many worker processes) or
            'ray' (``ray.init(num_cpus=workers)`` unless Ray is already initialised).
        workers: parallel workers (>= 1).
        chunk_size: variants per engine batch (bounds memory: one chunk's traces at a time
            per worker), >= 1.
        evaluator: how a chunk is evaluated; default :class:`EngineEvaluator`.
        progress: show a rich progress bar; default: when stderr is a terminal.
        max_chunks: stop after this many chunks (for tests and partial runs); the sweep
            stays resumable and results.parquet is only assembled once every variant is done.
        k_critical: how many most-critical variants go to critical.csv/json and configs/.

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
    if isinstance(chunk_size, bool) or not isinstance(chunk_size, int) or chunk_size < 1:
        raise ConfigError(f"chunk_size must be an integer >= 1, got {chunk_size!r}")
    if evaluator is None:
        evaluator = EngineEvaluator(
            time_shift_reference=spec.time_shift_reference,
            base=spec.base,
            reconstruction_samples=spec.reconstruction_samples,
            sample_seed=spec.seed,
        )
    if progress is None:
        progress = sys.stderr.isatty()
    dirs = (
        find_scenarios(scenarios)
        if isinstance(scenarios, str | Path)
        else [d for s in scenarios for d in find_scenarios(s)]
    )
    out = Path(out_dir)
    parts_dir = out / "parts"
    parts_dir.mkdir(parents=True, exist_ok=True)
    _clean_temporaries(parts_dir)

    with _runner(engine, workers, evaluator) as runner:
        n_skipped, n_run, table, scen_meta, prepared = _run_jobs(
            runner, dirs, spec, out, evaluator, chunk_size, max_chunks, bool(progress)
        )
    manifest_path = out / "sweep.json"
    manifest = json.loads(manifest_path.read_text(encoding="utf-8"))

    results_path = out / "results.parquet"
    if n_skipped + n_run >= len(table):
        results = assemble_results(out, table.drop(columns="_dir"))
        write_parquet(results_path, results)
        crit = most_critical(results, k_critical)
        from vei.io.atomic import write_text

        write_text(out / "critical.csv", crit.to_csv(index=False))
        write_json(out / "critical.json", json_records(crit))
        for sid, rows in crit.groupby("scenario_id", sort=False):
            d = next(m["path"] for m in scen_meta if m["id"] == sid)
            write_variant_configs(
                out / "configs", rows, spec, evaluator.auto_shift_s(prepared[_key_of(d, prepared)])
            )
        risk = sweep_risk_map(results, spec, out / "riskmap.png")
        if spec.reconstruction_samples and SAMPLE_COLUMN in results.columns:
            from vei.report.uncertainty import sample_dependence, write_sample_share_map

            design = ["scenario_id", *spec.names]
            summary, per_point = sample_dependence(results, design, SAMPLE_COLUMN)
            write_json(out / "reconstruction_samples.json", summary)
            if risk is not None:
                write_sample_share_map(
                    per_point, risk["x"], risk["y"], out / "reconstruction_share.png"
                )
        manifest["status"] = "complete"
        manifest["updated_utc"] = datetime.now(UTC).isoformat(timespec="seconds")
        write_json(manifest_path, manifest)
    return SweepResult(
        out_dir=out,
        results=results_path,
        n_variants=len(table),
        n_run=n_run,
        n_skipped=n_skipped,
        seconds=time.perf_counter() - t0,
    )


def _key_of(resolved: str, prepared: dict[str, Any]) -> str:
    """The key of ``prepared`` whose folder resolves to ``resolved``."""
    for k in prepared:
        if str(Path(k).resolve()) == resolved:
            return k
    raise KeyError(resolved)


def _evaluate_job(evaluator: Evaluator, prepared: Any, chunk: pd.DataFrame) -> pd.DataFrame:
    """Run one chunk and join its metrics to its variant rows (same order)."""
    metrics = evaluator.evaluate(prepared, chunk)
    if len(metrics) != len(chunk) or list(metrics["variant_id"]) != list(chunk["variant_id"]):
        raise RuntimeError("evaluator returned rows that do not match the chunk's variants")
    rows = chunk.reset_index(drop=True)
    extra = metrics.drop(columns=["variant_id"]).reset_index(drop=True)
    clash = set(extra.columns) & set(rows.columns)
    if clash:
        raise RuntimeError(f"metric columns clash with variant columns: {sorted(clash)}")
    return pd.concat([rows, extra], axis=1)


def _run_jobs(
    runner: Any,
    dirs: Sequence[Path],
    spec: SweepSpec,
    out: Path,
    evaluator: Evaluator,
    chunk_size: int,
    max_chunks: int | None,
    progress: bool,
) -> tuple[int, int, pd.DataFrame, list[dict[str, Any]], dict[str, Any]]:
    """Prepare the scenarios, check / write the manifest, run the chunks not yet done and
    write each as a part file. Returns (n_skipped, n_run, variants table, scenario
    metadata, prepared scenarios)."""
    parts_dir = out / "parts"
    prepared = runner.prepare_all(dirs)
    tables = []
    scen_meta = []
    for d in dirs:
        sid = evaluator.scenario_id(prepared[str(d)])
        t = variants_table(spec, sid)
        tables.append(t.assign(_dir=str(d)))
        scen_meta.append({"id": sid, "path": str(Path(d).resolve()), "n_variants": len(t)})
    ids_seen = [m["id"] for m in scen_meta]
    if len(set(ids_seen)) != len(ids_seen):
        raise InputError(f"two scenario folders share a scenario id: {ids_seen}", path=out)
    table = pd.concat(tables, ignore_index=True)

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
        "chunk_size": chunk_size,
        "status": "running",
        "updated_utc": datetime.now(UTC).isoformat(timespec="seconds"),
    }
    write_json(manifest_path, manifest)

    done = done_ids(out)
    todo = table[~table["variant_id"].isin(done)]
    n_skipped = len(table) - len(todo)
    existing = _existing_parts(parts_dir)
    next_seq = 1 + max((int(PART_RE.match(p.name).group(1)) for p in existing), default=-1)

    jobs = [
        (str(d), chunk)
        for d, grp in todo.groupby("_dir", sort=False)
        for chunk in _chunks(grp.drop(columns="_dir"), chunk_size)
    ]
    if max_chunks is not None:
        jobs = jobs[:max_chunks]

    n_run = 0

    def write_part(rows: pd.DataFrame) -> None:
        nonlocal next_seq, n_run
        write_parquet(parts_dir / f"part-{next_seq:06d}.parquet", rows)
        next_seq += 1
        n_run += len(rows)

    with _progress(len(table), n_skipped, progress) as advance:
        for rows in runner.run(jobs, prepared):
            write_part(rows)
            advance(len(rows))
    return n_skipped, n_run, table, scen_meta, prepared


def _prepare_job(evaluator: Evaluator, scenario_dir: str) -> Any:
    """Prepare one scenario (runs in a worker)."""
    return evaluator.prepare(Path(scenario_dir))


class _SerialRunner:
    """Everything in this process."""

    def __init__(self, evaluator: Evaluator) -> None:
        self.evaluator = evaluator

    def prepare_all(self, dirs: Sequence[Path]) -> dict[str, Any]:
        return {str(d): self.evaluator.prepare(Path(d)) for d in dirs}

    def run(
        self, jobs: list[tuple[str, pd.DataFrame]], prepared: dict[str, Any]
    ) -> Iterator[pd.DataFrame]:
        for d, chunk in jobs:
            yield _evaluate_job(self.evaluator, prepared[d], chunk)


class _PoolRunner:
    """A pool of ``workers`` spawned processes; at most 2 chunks per worker in flight."""

    def __init__(self, evaluator: Evaluator, pool: Any, workers: int) -> None:
        self.evaluator, self.pool, self.workers = evaluator, pool, workers

    def prepare_all(self, dirs: Sequence[Path]) -> dict[str, Any]:
        futures = {str(d): self.pool.submit(_prepare_job, self.evaluator, str(d)) for d in dirs}
        return {d: f.result() for d, f in futures.items()}

    def run(
        self, jobs: list[tuple[str, pd.DataFrame]], prepared: dict[str, Any]
    ) -> Iterator[pd.DataFrame]:
        from concurrent.futures import FIRST_COMPLETED, wait

        it = iter(jobs)
        pending: set = set()

        def fill() -> None:
            for d, chunk in it:
                pending.add(self.pool.submit(_evaluate_job, self.evaluator, prepared[d], chunk))
                if len(pending) >= 2 * self.workers:
                    break

        fill()
        while pending:
            finished, rest = wait(pending, return_when=FIRST_COMPLETED)
            pending.clear()
            pending.update(rest)
            for f in finished:
                yield f.result()
            fill()


class _RayRunner:
    """Ray tasks: scenarios prepared in parallel, each kept once in the object store."""

    def __init__(self, evaluator: Evaluator, ray: Any, workers: int) -> None:
        self.ray, self.workers = ray, workers
        self.ev_ref = ray.put(evaluator)
        self.refs: dict[str, Any] = {}

    def prepare_all(self, dirs: Sequence[Path]) -> dict[str, Any]:
        remote = self.ray.remote(num_cpus=1)(_prepare_job)
        self.refs = {str(d): remote.remote(self.ev_ref, str(d)) for d in dirs}
        return {d: self.ray.get(r) for d, r in self.refs.items()}

    def run(
        self, jobs: list[tuple[str, pd.DataFrame]], prepared: dict[str, Any]
    ) -> Iterator[pd.DataFrame]:
        remote = self.ray.remote(num_cpus=1)(_evaluate_job)
        it = iter(jobs)
        pending: list = []

        def fill() -> None:
            for d, chunk in it:
                pending.append(remote.remote(self.ev_ref, self.refs[d], chunk))
                if len(pending) >= 2 * self.workers:
                    break

        fill()
        while pending:
            ready, rest = self.ray.wait(pending, num_returns=1)
            pending[:] = rest
            for r in ready:
                yield self.ray.get(r)
            fill()


@contextlib.contextmanager
def _runner(engine: str, workers: int, evaluator: Evaluator) -> Iterator[Any]:
    """The executor of a sweep: serial, a process pool, or a Ray session (started and shut
    down here unless Ray is already initialised)."""
    if engine == "ray":
        try:
            import ray
        except ImportError as exc:  # pragma: no cover - ray is in the 'distributed' extra
            from vei.errors import DependencyError

            raise DependencyError("engine 'ray' needs Ray: pip install 'vei[distributed]'") from exc
        started = False
        if not ray.is_initialized():
            os.environ.setdefault("RAY_DISABLE_IMPORT_WARNING", "1")
            ray.init(
                num_cpus=workers,
                include_dashboard=False,
                log_to_driver=False,
                configure_logging=False,
            )
            started = True
        try:
            yield _RayRunner(evaluator, ray, workers)
        finally:
            if started:
                ray.shutdown()
        return
    if workers == 1:
        yield _SerialRunner(evaluator)
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor

    with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn")) as pool:
        yield _PoolRunner(evaluator, pool, workers)


def assemble_results(out_dir: str | Path, table: pd.DataFrame | None = None) -> pd.DataFrame:
    """All rows of ``out_dir/parts``, de-duplicated by variant_id, sorted by
    (scenario_id, variant_index); restricted to ``table``'s variant ids when given."""
    parts = _existing_parts(Path(out_dir) / "parts")
    if not parts:
        return pd.DataFrame()
    frame = pd.concat([pd.read_parquet(p) for p in parts], ignore_index=True)
    frame = frame.drop_duplicates("variant_id", keep="first")
    if table is not None:
        frame = frame[frame["variant_id"].isin(set(table["variant_id"]))]
    return frame.sort_values(["scenario_id", "variant_index"], kind="stable").reset_index(drop=True)


def most_critical(results: pd.DataFrame, k: int = 20) -> pd.DataFrame:
    """The ``k`` most critical variants: collisions first, then the lowest safety index,
    then the smallest minimum gap (columns that exist are used; ties keep table order)."""
    if results.empty:
        return results
    keys, asc = [], []
    if "collision" in results:
        keys.append("collision")
        asc.append(False)
    for col in ("safety_index", "min_gap_m"):
        if col in results:
            keys.append(col)
            asc.append(True)
    ranked = results.sort_values(keys, ascending=asc, kind="stable") if keys else results
    return ranked.head(k).reset_index(drop=True)


def read_results(out_dir: str | Path) -> pd.DataFrame:
    """results.parquet of a finished sweep.

    Raises:
        InputError: the sweep has not finished (no results.parquet).
    """
    path = Path(out_dir) / "results.parquet"
    if not path.is_file():
        raise InputError(
            "no results.parquet: the sweep has not finished (run it again to resume)", path=path
        )
    return pd.read_parquet(path)


def numeric_metric_columns(results: pd.DataFrame, spec_names: Sequence[str]) -> list[str]:
    """Metric columns of a results table (those that are not variant columns)."""
    fixed = {
        "variant_id",
        "scenario_id",
        "variant_index",
        "seed",
        SAMPLE_COLUMN,
        RIDER_COLUMN,
        *RIDER_PARAM_COLUMNS,
        *spec_names,
    }
    return [
        c for c in results.columns if c not in fixed and np.issubdtype(results[c].dtype, np.number)
    ]


def json_records(frame: pd.DataFrame) -> list[dict[str, Any]]:
    """Rows of a table as JSON-safe dicts (NaN / inf -> None, numpy scalars -> Python)."""
    recs = []
    for row in frame.to_dict("records"):
        clean = {}
        for k, v in row.items():
            if isinstance(v, np.generic):
                v = v.item()
            if isinstance(v, float) and not np.isfinite(v):
                v = None
            clean[k] = v
        recs.append(clean)
    return recs


def write_variant_configs(
    folder: str | Path,
    variants: pd.DataFrame,
    spec: SweepSpec,
    auto_shift_s: float | None,
) -> list[Path]:
    """One run-configuration YAML per variant row: ``folder/<variant_id>.yaml``.

    Each file is a :class:`vei.config.RunConfig` (``vei.config.load_config(path,
    RunConfig)`` reads it back; ``vei run SCENARIO --config FILE`` runs it) with the
    variant's absolute time shift. Returns the paths written.
    """
    import yaml

    from vei.config import config_to_dict
    from vei.experiments.sweep_spec import variant_config
    from vei.io.atomic import write_text

    folder = Path(folder)
    paths = []
    for row in variants.to_dict("records"):
        params = {n: row[n] for n in (*spec.names, *RIDER_PARAM_COLUMNS) if n in row}
        cfg = variant_config(
            params, spec, auto_shift_s=auto_shift_s, name=f"variant-{row['variant_id']}"
        )
        doc = config_to_dict(cfg)
        header = (
            f"# vei run configuration of sweep variant {row['variant_id']} "
            f"(scenario {row.get('scenario_id', '?')})\n"
        )
        paths.append(
            write_text(
                folder / f"{row['variant_id']}.yaml", header + yaml.safe_dump(doc, sort_keys=False)
            )
        )
    return paths


def sweep_risk_map(
    results: pd.DataFrame,
    spec: SweepSpec,
    path: str | Path,
    *,
    x: str | None = None,
    y: str | None = None,
    bins: int | None = None,
) -> dict[str, Any] | None:
    """Risk map of a finished sweep over two range parameters (default: time shift x ego
    cruise speed when both are ranges, else the first two ranges in PARAMETERS order).

    Variants are binned in the (x, y) plane: a grid design's own values are the bins (one
    variant per bin per other setting), other designs use ``bins`` equal bins per axis
    (default: about 10 variants per bin, 4 to 25 bins per axis). The
    heatmap is the mean safety index per bin, the boundary the 0.5 level of the collision
    share (marching squares, linear interpolation; :func:`vei.experiments.boundary.share_boundary`).

    Returns:
        None when the spec has fewer than two range parameters or results lack
        safety_index / collision; else {'x', 'y', 'binned', 'segments', 'crossings'} (what
        was drawn) after writing the PNG at ``path``.
    """
    from vei.experiments.boundary import binned_risk, share_boundary
    from vei.report.riskmap import write_risk_map

    ranges = [p.name for p in spec.parameters if p.is_range and p.min != p.max]
    if x is None or y is None:
        if len(ranges) < 2:
            return None
        x, y = (
            ("time_shift_s", "ego.cruise_speed_mps")
            if {"time_shift_s", "ego.cruise_speed_mps"} <= set(ranges)
            else (ranges[0], ranges[1])
        )
    if bins is None:
        bins = int(np.clip(np.sqrt(len(results) / 10.0), 4, 25))
    if not {"safety_index", "collision", x, y} <= set(results.columns):
        return None

    def edges(name: str) -> np.ndarray:
        p = spec.param(name)
        if p.num is not None and p.num >= 2:
            c = np.linspace(p.min, p.max, p.num)
            return _centre_edges(c)
        return np.linspace(p.min, p.max, bins + 1)

    binned = binned_risk(
        results[x].to_numpy(float),
        results[y].to_numpy(float),
        results["collision"].to_numpy(bool),
        results["safety_index"].to_numpy(float),
        edges(x),
        edges(y),
    )
    segments, crossings = share_boundary(binned)
    n_sc = results["scenario_id"].nunique() if "scenario_id" in results else 1
    write_risk_map(
        path,
        x_centres=binned["x_centres"],
        y_centres=binned["y_centres"],
        value=binned["value"],
        segments=segments,
        x_label=x,
        y_label=y,
        title=f"mean safety index of {len(results)} variants ({n_sc} scenario(s)); "
        "boundary: collision share 0.5",
    )
    return {"x": x, "y": y, "binned": binned, "segments": segments, "crossings": crossings}


def _centre_edges(c: np.ndarray) -> np.ndarray:
    mid = 0.5 * (c[:-1] + c[1:])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


# --------------------------------------------------------------------------------------
# The built-in engine as the evaluator
# --------------------------------------------------------------------------------------
#: Metrics a sweep records by default (scalar metrics of vei.metrics, one column each).
DEFAULT_METRICS: tuple[str, ...] = (
    "collision",
    "collision_time_s",
    "safety_index",
    "t_safe_s",
    "t_attention_s",
    "t_alert_s",
    "t_interaction_s",
    "min_gap_m",
    "min_ttc_s",
    "max_drac_mps2",
    "peak_decel_mps2",
    "ego_speed_std_mps",
    "ego_speed_min_mps",
)

#: Categorical sweep parameters: variants sharing them share one base configuration.
_CATEGORICAL = ("rider_model", "cap.enabled", "sfm.vehicle_force")
#: Float sweep parameter -> VariantParams field (sfm.k_des is scaled by k_des_factor).
_PARAM_FIELDS: dict[str, str] = {
    "sfm.k_des": "k_des_nspm",
    "sfm.A": "a_veh_n",
    "sfm.b": "b_veh_per_m",
    "sfm.v0": "v0_mps",
    "sfm.mass": "mass_kg",
    "ego.cruise_speed_mps": "cruise_speed_mps",
    "cap.T_safe_s": "t_safe_s",
    "cap.d_buf_m": "d_buf_m",
    "cap.a_min_mps2": "a_min_mps2",
    "perception_delay_s": "perception_delay_s",
    # A population rider's parameters (vei.calibrate.population.RIDER_PARAM_COLUMNS).
    **RIDER_PARAM_COLUMNS,
}
#: Columns of a destination gain (scaled by the configuration's k_des_factor).
_K_DES_COLUMNS = ("sfm.k_des", "rider.k_des_nspm")


@dataclass(frozen=True)
class PreparedScenario:
    """A scenario compiled for the engine (picklable; shared by every chunk).

    Attributes:
        scenario_id: its id. path: its folder. arrays: vei.sim.state.ScenarioArrays.
        auto_shift_s: the automatic time shift [s] (None unless the reference is 'auto').
        sample_arrays: one ScenarioArrays per posterior sample of the primary rider's
            trajectory (``reconstruction: {samples: N}``; empty otherwise).
    """

    scenario_id: str
    path: str
    arrays: Any
    auto_shift_s: float | None
    sample_arrays: tuple = ()


def variant_params(
    variants: pd.DataFrame,
    arrays: Any,
    *,
    base: str = "normal-cap",
    time_shift_reference: str = "auto",
    auto_shift_s: float | None = None,
) -> Any:
    """The engine's per-variant parameters ([B] arrays) of a variants table, vectorised.

    Rows are grouped by their categorical parameters (rider model, CAP on/off, vehicle
    force: at most 12 groups); each group starts from the run configuration that
    :func:`vei.experiments.sweep_spec.variant_config` gives it and takes the float
    parameters as [B_g] overrides. The result equals, row by row, the parameters of the
    row's own run configuration (what ``vei run --config`` runs; a test checks this).

    Args:
        variants: [B] rows of a variants table (parameter columns by dotted name).
        arrays: the scenario's ``vei.sim.state.ScenarioArrays``.
        base, time_shift_reference: of the sweep spec.
        auto_shift_s: the scenario's automatic shift [s] (reference 'auto').

    Returns:
        ``vei.sim.state.VariantParams`` with B variants in row order (labels = variant ids).

    Raises:
        ConfigError: a variant's configuration is invalid (e.g. a_min beyond the brake).
    """
    from vei.experiments.sweep_spec import SweepSpec, variant_config
    from vei.sim.state import VariantParams

    probe = SweepSpec(
        design="grid", parameters=(), time_shift_reference=time_shift_reference, base=base
    )
    b = len(variants)
    cats = [c for c in _CATEGORICAL if c in variants.columns]
    keys = (
        variants[cats].astype(str).agg("|".join, axis=1).to_numpy()
        if cats
        else np.zeros(b, dtype=object)
    )
    pieces, order = [], []
    for key in dict.fromkeys(keys):
        idx = np.flatnonzero(keys == key)
        first = variants.iloc[idx[0]]
        cat_params = {c: first[c] for c in cats}
        case = variant_config(cat_params, probe, auto_shift_s=auto_shift_s or 0.0).case
        grp = variants.iloc[idx]
        overrides: dict[str, np.ndarray] = {}
        for col, fname in _PARAM_FIELDS.items():
            if col in grp.columns:
                v = grp[col].to_numpy(np.float64)
                if col in _K_DES_COLUMNS:
                    v = v * case.sfm.k_des_factor
                overrides[fname] = v
        if "v0_mps" in overrides and case.sfm.speed_from_recording:
            # A swept or sampled v0 is the rider's own (as in variant_config).
            case = replace(case, sfm=replace(case.sfm, speed_from_recording=False))
        if case.ego_mode == "cap":
            a_min = overrides.get("a_min_mps2", np.array([case.cap.a_min_mps2]))
            if np.any(-a_min > case.ego.max_decel_mps2):
                raise ConfigError(
                    f"cap.a_min_mps2 below -ego.max_decel_mps2 ({-case.ego.max_decel_mps2}): "
                    "the CAP would demand more than the car's full brake"
                )
        offset = (
            grp["time_shift_s"].to_numpy(np.float64)
            if "time_shift_s" in grp
            else np.zeros(len(idx))
        )
        shift = offset + (float(auto_shift_s or 0.0) if time_shift_reference == "auto" else 0.0)
        if time_shift_reference == "auto" and auto_shift_s is None:
            raise ConfigError("time_shift_reference 'auto' needs the scenario's automatic shift")
        p = VariantParams.from_case(case, arrays, len(idx), time_shift_s=shift, **overrides)
        pieces.append(p.with_values(labels=grp["variant_id"].to_numpy(object)))
        order.append(idx)
    params = VariantParams.concat(pieces)
    perm = np.concatenate(order)
    inverse = np.empty(b, dtype=np.intp)
    inverse[perm] = np.arange(b)
    return params if np.array_equal(perm, np.arange(b)) else params.take(inverse)


class EngineEvaluator:
    """Evaluates sweep chunks with the built-in batched engine and the metrics registry.

    Args:
        time_shift_reference: 'auto' or 'zero' (of the sweep spec).
        base: the spec's base configuration name.
        sim: engine settings (default: SimConfig(), 20 Hz over the scenario's span).
        metrics: scalar metric names (vei.metrics) to record per variant.
        reconstruction_samples: N posterior samples of the primary rider's trajectory
            (:func:`vei.recon.samples.sample_rider`, drawn with ``sample_seed``); variants
            carry the sample they run on in column SAMPLE_COLUMN. None: mean trajectory.
    """

    def __init__(
        self,
        time_shift_reference: str = "auto",
        base: str = "normal-cap",
        sim: Any = None,
        metrics: Sequence[str] = DEFAULT_METRICS,
        reconstruction_samples: int | None = None,
        sample_seed: int = 0,
    ) -> None:
        from vei.config import SimConfig

        self.reconstruction_samples = reconstruction_samples
        self.sample_seed = sample_seed
        self.time_shift_reference = time_shift_reference
        self.base = base
        self.sim = sim if sim is not None else SimConfig()
        self.metrics = tuple(metrics)

    def prepare(self, scenario_dir: Path) -> PreparedScenario:
        """Read the scenario, compile its arrays, and find its automatic time shift."""
        from vei.io.scenario import read_scenario
        from vei.sim.state import prepare_scenario

        scenario = read_scenario(scenario_dir)
        arrays = prepare_scenario(scenario, self.sim)
        auto = None
        if self.time_shift_reference == "auto":
            from vei.experiments.timeshift import find_time_shift

            auto = float(find_time_shift(scenario, sim=self.sim).time_shift_s)
        sample_arrays: tuple = ()
        if self.reconstruction_samples:
            from vei.recon.samples import sample_rider, scenario_with_sample

            draws = sample_rider(scenario, self.reconstruction_samples, self.sample_seed)
            sample_arrays = tuple(
                prepare_scenario(scenario_with_sample(scenario, draws, k), self.sim)
                for k in range(draws.n_samples)
            )
        return PreparedScenario(scenario.id, str(scenario_dir), arrays, auto, sample_arrays)

    def scenario_id(self, prepared: PreparedScenario) -> str:
        """The scenario's id."""
        return prepared.scenario_id

    def auto_shift_s(self, prepared: PreparedScenario) -> float | None:
        """The scenario's automatic time shift [s] (None for reference 'zero')."""
        return prepared.auto_shift_s

    def evaluate(self, prepared: PreparedScenario, variants: pd.DataFrame) -> pd.DataFrame:
        """Simulate ``variants`` [B rows] as one batch; one metrics row per variant.

        Returns a DataFrame: variant_id, time_shift_applied_s (the absolute shift [s]),
        then ``self.metrics`` columns (collision bool, the others float). Variants with a
        SAMPLE_COLUMN run on that sample's arrays (one batch per sample).
        """
        from vei.metrics import summarize
        from vei.sim.engine import simulate

        if SAMPLE_COLUMN in variants.columns and prepared.sample_arrays:
            parts = []
            for k, grp in variants.groupby(SAMPLE_COLUMN, sort=False):
                one = PreparedScenario(
                    prepared.scenario_id,
                    prepared.path,
                    prepared.sample_arrays[int(k)],
                    prepared.auto_shift_s,
                )
                parts.append(self.evaluate(one, grp.drop(columns=SAMPLE_COLUMN)))
            out = pd.concat(parts, ignore_index=True).set_index("variant_id")
            return out.loc[variants["variant_id"].to_numpy()].reset_index()

        params = variant_params(
            variants,
            prepared.arrays,
            base=self.base,
            time_shift_reference=self.time_shift_reference,
            auto_shift_s=prepared.auto_shift_s,
        )
        result = simulate(prepared.arrays, params, record="full", kernel=self.sim.kernel)
        summary = summarize(result.to_trace(), names=self.metrics)
        summary.insert(0, "time_shift_applied_s", params.time_shift_s)
        summary.insert(0, "variant_id", variants["variant_id"].to_numpy())
        return summary.reset_index(drop=True)
