"""Sweep executors: serial, a process pool whose workers die with the sweep
(:class:`vei.experiments.workers.WorkerPool`), or Ray tasks.

A job is one chunk of variants: ``(scenario key, variants [B rows], part file)``. Every
executor evaluates it, joins the metrics to the variant rows and writes the part file
(atomically); :meth:`run` yields the number of rows of each part once it is on disk.

The process pool pays every fixed cost once per worker, not per chunk:

- the evaluator reaches each worker once (the pool's initializer), with the number of
  numba threads of that worker (:func:`threads_per_worker`: the cores shared out, so two
  workers on two cores run one thread each instead of fighting over both);
- the workers are launched without waiting for them (their imports and initializer run
  while this process prepares a single scenario itself and builds the variants table);
  several scenarios are prepared in the pool, in parallel;
- each prepared scenario (its ScenarioArrays, possibly MBs) is pickled once into a file of
  a temporary folder; a worker loads it on its first chunk of that scenario and keeps it
  (:data:`_WORKER` cache, the last :data:`_CACHE_SCENARIOS` scenarios); the worker that
  prepared a scenario keeps its own copy. A job carries only the key and the file name;
- the worker writes the part file itself, so the parent neither unpickles nor encodes the
  rows: it only hands out chunks and counts.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import tempfile
from collections import OrderedDict
from collections.abc import Iterable, Iterator, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.experiments.sweep_engine import Evaluator

#: A chunk of work: (scenario key, variants rows, part file path).
Job = tuple[str, pd.DataFrame, Path]

#: Prepared scenarios a worker keeps (jobs come grouped by scenario, so a few suffice).
_CACHE_SCENARIOS = 4

#: State of a pool worker (set by :func:`_init_sweep_worker`): the evaluator and the
#: prepared scenarios by key (LRU).
_WORKER: dict[str, Any] = {}


def _key_of(resolved: str, prepared: dict[str, Any]) -> str:
    """The key of ``prepared`` whose folder resolves to ``resolved``."""
    for k in prepared:
        if str(Path(k).resolve()) == resolved:
            return k
    raise KeyError(resolved)


def threads_per_worker(workers: int, cpus: int | None = None) -> int:
    """numba threads for each of ``workers`` processes: the CPUs shared out, at least 1.

    Args:
        workers: worker processes (>= 1). cpus: CPUs to share (default: those this process
            may run on, ``os.sched_getaffinity`` where it exists, else ``os.cpu_count``).
    """
    if cpus is None:
        try:
            cpus = len(os.sched_getaffinity(0))
        except AttributeError:  # pragma: no cover - not Linux
            cpus = os.cpu_count() or 1
    return max(1, int(cpus) // max(1, int(workers)))


def set_numba_threads(n: int) -> int:
    """Let the compiled kernel's parallel loops use ``n`` threads in this process (and
    thread); returns the number set (0 when numba is not installed).

    Before numba is imported, ``NUMBA_NUM_THREADS`` is set too, so its thread pool is
    started with ``n`` threads only.
    """
    import sys

    if "numba" not in sys.modules:
        os.environ["NUMBA_NUM_THREADS"] = str(int(n))
    try:
        import numba
    except ImportError:  # pragma: no cover - numba is a core dependency
        return 0
    n = max(1, min(int(n), numba.config.NUMBA_NUM_THREADS))
    numba.set_num_threads(n)
    return n


def evaluate_rows(evaluator: Evaluator, prepared: Any, chunk: pd.DataFrame) -> pd.DataFrame:
    """Run one chunk [B rows] and join its metrics to its variant rows (same order)."""
    metrics = evaluator.evaluate(prepared, chunk)
    if len(metrics) != len(chunk) or not np.array_equal(
        metrics["variant_id"].to_numpy(object), chunk["variant_id"].to_numpy(object)
    ):
        raise RuntimeError("evaluator returned rows that do not match the chunk's variants")
    rows = chunk.reset_index(drop=True)
    extra = metrics.drop(columns=["variant_id"]).reset_index(drop=True)
    clash = set(extra.columns) & set(rows.columns)
    if clash:
        raise RuntimeError(f"metric columns clash with variant columns: {sorted(clash)}")
    return pd.concat([rows, extra], axis=1)


def _write_part(path: Path, rows: pd.DataFrame) -> int:
    from vei.io.atomic import write_parquet

    write_parquet(path, rows)
    return len(rows)


def _evaluate_job(evaluator: Evaluator, prepared: Any, chunk: pd.DataFrame) -> pd.DataFrame:
    """Run one chunk (a Ray task: the rows go back to the parent, which writes them)."""
    return evaluate_rows(evaluator, prepared, chunk)


def _prepare_job(evaluator: Evaluator, scenario_dir: str) -> Any:
    """Prepare one scenario (runs in a Ray task)."""
    return evaluator.prepare(Path(scenario_dir))


# --------------------------------------------------------------------------- pool workers


def _init_sweep_worker(evaluator: Evaluator, numba_threads: int) -> None:
    """Initializer of a sweep's pool worker: keep the evaluator, set the numba threads."""
    if numba_threads > 0:
        set_numba_threads(numba_threads)
    _WORKER.clear()
    _WORKER.update(evaluator=evaluator, prepared=OrderedDict())


def _cache(key: str, prepared: Any) -> Any:
    cache: OrderedDict = _WORKER["prepared"]
    cache[key] = prepared
    cache.move_to_end(key)
    while len(cache) > _CACHE_SCENARIOS:
        cache.popitem(last=False)
    return prepared


def _pool_prepare(scenario_dir: str, file: str) -> Any:
    """Prepare a scenario in a worker, pickle it once into ``file`` for the other workers,
    keep it; returns it (to the parent)."""
    from vei.io.atomic import write_bytes

    prepared = _WORKER["evaluator"].prepare(Path(scenario_dir))
    write_bytes(file, pickle.dumps(prepared, protocol=pickle.HIGHEST_PROTOCOL))
    return _cache(scenario_dir, prepared)


def _pool_job(key: str, file: str, chunk: pd.DataFrame, part: str) -> int:
    """Evaluate a chunk in a worker and write its part file; returns its number of rows."""
    cache: OrderedDict = _WORKER["prepared"]
    if key in cache:
        cache.move_to_end(key)
        prepared = cache[key]
    else:
        with open(file, "rb") as fh:
            prepared = _cache(key, pickle.load(fh))
    return _write_part(Path(part), evaluate_rows(_WORKER["evaluator"], prepared, chunk))


# --------------------------------------------------------------------------- executors


class _SerialRunner:
    """Everything in this process."""

    def __init__(self, evaluator: Evaluator) -> None:
        self.evaluator = evaluator

    def prepare_all(self, dirs: Sequence[Path]) -> dict[str, Any]:
        return {str(d): self.evaluator.prepare(Path(d)) for d in dirs}

    def run(self, jobs: Iterable[Job], prepared: dict[str, Any]) -> Iterator[int]:
        for d, chunk, part in jobs:
            yield _write_part(part, evaluate_rows(self.evaluator, prepared[d], chunk))


class _PoolRunner:
    """A pool of ``workers`` spawned processes (module docstring); at most 2 chunks per
    worker in flight."""

    def __init__(self, evaluator: Evaluator, pool: Any, workers: int, scratch: Path) -> None:
        self.evaluator, self.pool, self.workers, self.scratch = evaluator, pool, workers, scratch
        self.files: dict[str, str] = {}

    def prepare_all(self, dirs: Sequence[Path]) -> dict[str, Any]:
        self.files = {str(d): str(self.scratch / f"scenario-{i}.pkl") for i, d in enumerate(dirs)}
        if len(dirs) == 1:  # here, while the workers start
            from vei.io.atomic import write_bytes

            d = str(dirs[0])
            prepared = self.evaluator.prepare(Path(d))
            write_bytes(self.files[d], pickle.dumps(prepared, protocol=pickle.HIGHEST_PROTOCOL))
            return {d: prepared}
        futures = {d: self.pool.submit(_pool_prepare, d, f) for d, f in self.files.items()}
        return {d: f.result() for d, f in futures.items()}

    def run(self, jobs: Iterable[Job], prepared: dict[str, Any]) -> Iterator[int]:
        from concurrent.futures import FIRST_COMPLETED, wait

        it = iter(jobs)
        pending: set = set()

        def fill() -> None:
            for d, chunk, part in it:
                pending.add(self.pool.submit(_pool_job, d, self.files[d], chunk, str(part)))
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
    """Ray tasks: scenarios prepared in parallel, each kept once in the object store; the
    rows come back to this process, which writes the part files (the workers may not
    share its disk)."""

    def __init__(self, evaluator: Evaluator, ray: Any, workers: int) -> None:
        self.ray, self.workers = ray, workers
        self.ev_ref = ray.put(evaluator)
        self.refs: dict[str, Any] = {}

    def prepare_all(self, dirs: Sequence[Path]) -> dict[str, Any]:
        remote = self.ray.remote(num_cpus=1)(_prepare_job)
        self.refs = {str(d): remote.remote(self.ev_ref, str(d)) for d in dirs}
        return {d: self.ray.get(r) for d, r in self.refs.items()}

    def run(self, jobs: Iterable[Job], prepared: dict[str, Any]) -> Iterator[int]:
        remote = self.ray.remote(num_cpus=1)(_evaluate_job)
        it = iter(jobs)
        pending: list = []
        parts: dict[Any, Path] = {}

        def fill() -> None:
            for d, chunk, part in it:
                ref = remote.remote(self.ev_ref, self.refs[d], chunk)
                parts[ref] = part
                pending.append(ref)
                if len(pending) >= 2 * self.workers:
                    break

        fill()
        while pending:
            ready, rest = self.ray.wait(pending, num_returns=1)
            pending[:] = rest
            for r in ready:
                yield _write_part(parts.pop(r), self.ray.get(r))
            fill()


@contextlib.contextmanager
def _runner(engine: str, workers: int, evaluator: Evaluator) -> Iterator[Any]:
    """The executor of a sweep: serial, a process pool, or a Ray session (started and shut
    down here unless Ray is already initialised)."""
    if engine == "ray":
        from vei.experiments.workers import ray_session

        # The session of this process, the cluster at $RAY_ADDRESS, or a local Ray.
        with ray_session(workers) as ray:
            yield _RayRunner(evaluator, ray, workers)
        return
    if workers == 1:
        yield _SerialRunner(evaluator)
        return
    from vei.experiments.workers import WorkerPool

    # Workers die with this process (kill -9 included) and ignore Ctrl-C; leaving the
    # block with an exception (KeyboardInterrupt) kills them at once.
    with (
        tempfile.TemporaryDirectory(prefix="vei-sweep-") as scratch,
        WorkerPool(
            workers,
            initializer=_init_sweep_worker,
            initargs=(evaluator, threads_per_worker(workers)),
            wait_ready=False,
        ) as pool,
    ):
        yield _PoolRunner(evaluator, pool, workers, Path(scratch))
