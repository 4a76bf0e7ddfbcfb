"""Run a whole catalogue: every recording, every encounter, in parallel, resumably.

Two phases, each a set of independent jobs: (1) one job per recording
(:func:`vei.catalogue.pipeline.process_recording`), (2) one job per encounter found
(:func:`vei.catalogue.pipeline.process_encounter`). The jobs run in this process
(``workers=1``), in a pool of spawned local processes, or as Ray tasks
(``engine='ray'``): the same functions with the same arguments, so results do not depend
on where they ran. Progress bars (rich) show both phases when stderr is a terminal.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import pandas as pd

from vei.catalogue.config import CatalogueConfig
from vei.catalogue.pipeline import list_recordings, process_encounter, process_recording
from vei.catalogue.store import (
    CATALOGUE_FORMAT,
    assemble,
    check_manifest,
    is_done,
    write_manifest,
)
from vei.errors import ConfigError, InputError

ENGINES: tuple[str, ...] = ("local", "ray")


@dataclass(frozen=True)
class CatalogueResult:
    """What :func:`run_catalogue` did.

    Attributes:
        out_dir: the catalogue folder. rows: catalogue table (one row per encounter x
        configuration, ranked). encounters: one row per encounter, ranked.
        recordings: per recording {'recording', 'status' ('ok', 'no-riders', 'failed'),
        'reason', 'encounters', ...}.
        failed_encounters: [{'encounter_id', 'reason'}]. failed_recordings: names of the
        recordings (of this folder, any run) that failed. n_done_before: encounters a
        previous (interrupted) run had finished. seconds: wall time of this call.
        complete: no recording and no encounter failed, and every encounter of every
        recording this folder holds (this run's and earlier runs') is done (none left
        undone by ``max_encounters``); otherwise the catalogue is partial.
        rows / encounters / the manifest cover every recording processed in this folder
        so far, not only this run's ``recordings``.
    """

    out_dir: Path
    rows: pd.DataFrame
    encounters: pd.DataFrame
    recordings: list[dict[str, Any]]
    failed_encounters: list[dict[str, Any]]
    failed_recordings: list[str]
    n_done_before: int
    seconds: float
    complete: bool


class _Serial:
    def map(self, fn: Callable, calls: Sequence[tuple]) -> Iterator[Any]:
        for args in calls:
            yield fn(*args)


class _Pool:
    def __init__(self, pool: Any) -> None:
        self.pool = pool

    def map(self, fn: Callable, calls: Sequence[tuple]) -> Iterator[Any]:
        from concurrent.futures import as_completed

        futures = [self.pool.submit(fn, *args) for args in calls]
        for f in as_completed(futures):
            yield f.result()


class _Ray:
    def __init__(self, ray: Any) -> None:
        self.ray = ray

    def map(self, fn: Callable, calls: Sequence[tuple]) -> Iterator[Any]:
        remote = self.ray.remote(num_cpus=1, max_retries=0)(fn)
        pending = [remote.remote(*args) for args in calls]
        while pending:
            ready, pending = self.ray.wait(pending, num_returns=1)
            for r in ready:
                yield self.ray.get(r)


def check_executor(engine: str, workers: int) -> None:
    """Raise ConfigError unless ``engine`` is known and ``workers`` an integer >= 1."""
    if engine not in ENGINES:
        raise ConfigError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise ConfigError(f"workers must be an integer >= 1, got {workers!r}")


@contextlib.contextmanager
def executor(engine: str, workers: int) -> Iterator[Any]:
    """A job executor with ``map(fn, calls)`` yielding results as jobs finish.

    'local': this process (workers == 1) or a pool of ``workers`` spawned processes
    (:class:`vei.sweep.workers.WorkerPool`: they die with this process, ignore
    SIGINT, and are killed at once when the block ends with an exception);
    'ray': Ray tasks (``ray.init(num_cpus=workers)`` unless Ray is initialised already,
    e.g. ``ray.init(address='auto')`` on a cluster: then the cluster's CPUs are used).
    """
    check_executor(engine, workers)
    if engine == "ray":
        from vei.sweep.workers import ray_session

        with ray_session(workers) as ray:
            yield _Ray(ray)
        return
    if workers == 1:
        yield _Serial()
        return
    from vei.sweep.workers import WorkerPool

    with WorkerPool(workers) as pool:
        yield _Pool(pool)


@contextlib.contextmanager
def _progress(enabled: bool | None) -> Iterator[Callable[[str, int, int], None]]:
    """update(phase, done, total): per phase a bar on a terminal, a line at least every
    10 s otherwise (None), or nothing (False) (vei.io.progress)."""
    from vei.io.progress import progress

    with contextlib.ExitStack() as stack:
        phases: dict[str, Any] = {}

        def update(phase: str, done: int, total: int) -> None:
            if phase not in phases:
                for other in list(phases):  # the previous phase ends: its last line
                    stack.pop_all().close()
                    phases.pop(other)
                phases[phase] = stack.enter_context(
                    progress(f"catalogue: {phase}", total, enabled=enabled)
                )
            phases[phase].update(done, total)

        yield update


def run_catalogue(
    dataset: str | Path,
    out_dir: str | Path,
    config: CatalogueConfig | None = None,
    *,
    recordings: Sequence[str] | None = None,
    engine: str = "local",
    workers: int = 1,
    progress: bool | None = None,
    max_encounters: int | None = None,
    on_event: Callable[[str, dict[str, Any]], None] | None = None,
) -> CatalogueResult:
    """Build (or resume) the catalogue of a dataset in ``out_dir`` (layout: vei.catalogue.store).

    Args:
        dataset: a TrafficMonitoring root or a folder of interaction folders.
        out_dir: catalogue folder (created; a folder of another catalogue is refused).
        config: what to compute (default CatalogueConfig()).
        recordings: only these recordings (names as listed; default all).
        engine, workers: where jobs run ('local' | 'ray'; >= 1 workers).
        progress: None (default): a bar per phase on a terminal, else a line at least
            every 10 s (vei.io.progress); False: silent.
        max_encounters: run at most this many encounters not done before (>= 0; tests,
            partial runs); the catalogue stays resumable and is assembled from what is done.
        on_event: callback(kind, doc) for each finished job ('recording' / 'encounter').
    Returns:
        CatalogueResult.
    Raises:
        InputError: the dataset is unreadable or a named recording does not exist.
        ConfigError: bad engine/workers, or ``out_dir`` holds another catalogue.
    """
    t0 = time.perf_counter()
    config = config or CatalogueConfig()
    check_executor(engine, workers)  # every argument checked before out_dir is touched
    if max_encounters is not None and (
        isinstance(max_encounters, bool)
        or not isinstance(max_encounters, int)
        or max_encounters < 0
    ):
        raise ConfigError(f"max_encounters must be an integer >= 0, got {max_encounters!r}")
    dataset = Path(dataset).resolve()
    kind, names = list_recordings(dataset)
    if recordings is not None:
        unknown = [r for r in recordings if r not in names]
        if unknown:
            raise InputError(
                f"unknown recording {unknown[0]!r}; known: {', '.join(names)}", path=dataset
            )
        names = [n for n in names if n in set(recordings)]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    digest = config.digest()
    old = check_manifest(out, digest, str(dataset))
    manifest: dict[str, Any] = {
        "format": CATALOGUE_FORMAT,
        "dataset": str(dataset),
        "dataset_kind": kind,
        "settings_digest": digest,
        "settings": config.as_dict(),
        "status": "running",
        "started_utc": (old or {}).get("started_utc")
        or datetime.now(UTC).isoformat(timespec="seconds"),
        "recordings": (old or {}).get("recordings", {}),
    }
    write_manifest(out, manifest)
    emit = on_event or (lambda kind, doc: None)

    rec_docs: list[dict[str, Any]] = []
    enc_docs: list[dict[str, Any]] = []
    with executor(engine, workers) as ex, _progress(progress) as update:
        calls = [(str(dataset), kind, n, str(out), config) for n in names]
        update("recordings", 0, len(calls))
        for doc in ex.map(process_recording, calls):
            rec_docs.append(doc)
            update("recordings", len(rec_docs), len(calls))
            emit("recording", doc)
        rec_docs.sort(key=lambda d: d["recording"])
        encounters = [e for d in rec_docs for e in d.get("encounters", [])]
        # Done encounters are skipped before the limit applies, so a resumed partial run with
        # the same limit goes on with the next ones.
        done_before = [e for e in encounters if is_done(out, e["encounter_id"])]
        pending = [(str(out), e, config) for e in encounters if not is_done(out, e["encounter_id"])]
        jobs = pending if max_encounters is None else pending[:max_encounters]
        update("encounters", 0, len(jobs))
        for doc in ex.map(process_encounter, jobs):
            enc_docs.append(doc)
            update("encounters", len(enc_docs), len(jobs))
            emit("encounter", doc)

    failed = [
        {"encounter_id": d["encounter_id"], "reason": d["reason"]}
        for d in enc_docs
        if d["status"] == "failed"
    ]
    # A run over some recordings adds to what earlier runs in this folder recorded: the
    # manifest keeps their recordings and the table holds every done encounter.
    earlier = {k: v for k, v in manifest["recordings"].items() if k not in set(names)}
    failed += [
        f
        for f in (old or {}).get("failed_encounters", [])
        if any(f["encounter_id"] in r.get("encounters", []) for r in earlier.values())
        and not is_done(out, f["encounter_id"])
    ]
    manifest["recordings"] = earlier | {
        d["recording"]: {
            "status": d["status"],
            "reason": d.get("reason", ""),
            "encounters": [e["encounter_id"] for e in d.get("encounters", [])],
            "n_riders": d.get("n_riders", 0),
        }
        for d in rec_docs
    }
    manifest["recordings"] = dict(sorted(manifest["recordings"].items()))
    ids = [i for r in manifest["recordings"].values() for i in r.get("encounters", [])]
    rows, enc_table = assemble(out, ids)
    failed_recordings = sorted(
        k for k, r in manifest["recordings"].items() if r.get("status") == "failed"
    )
    # complete: nothing failed and every encounter done; else partial (exit code 3 at the CLI)
    complete = not failed and not failed_recordings and all(is_done(out, i) for i in ids)
    manifest["failed_encounters"] = failed
    manifest["failed_recordings"] = failed_recordings
    manifest["n_encounters"] = len(ids)
    manifest["n_rows"] = len(rows)
    manifest["status"] = "complete" if complete else "partial"
    manifest["updated_utc"] = datetime.now(UTC).isoformat(timespec="seconds")
    manifest["seconds_last_run"] = time.perf_counter() - t0
    write_manifest(out, manifest)
    return CatalogueResult(
        out_dir=out,
        rows=rows,
        encounters=enc_table,
        recordings=rec_docs,
        failed_encounters=failed,
        failed_recordings=failed_recordings,
        n_done_before=len(done_before) + sum(d["status"] == "done-before" for d in enc_docs),
        seconds=time.perf_counter() - t0,
        complete=complete,
    )
