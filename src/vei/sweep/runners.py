"""Sweep executors: serial, a process pool whose workers die with the sweep
(:class:`vei.sweep.workers.WorkerPool`), or Ray tasks.

A job is one chunk of variants: ``(scenario key, variants [B rows], part file, id seed)``.
Every executor names its rows where they come unnamed (id seed: the spec's seed, else
None; :func:`vei.sweep.ids.name_variants`, so the ids are taken in parallel),
evaluates them, joins the metrics to the variant rows and writes the part file
(atomically); :meth:`run` yields the number of rows of each part once it is on disk.

With ``workers`` = N > 1, N processes evaluate chunks: the sweep's own process and a pool
of N - 1 children (forked or spawned, below). The sweep's process has the scenario
prepared and the kernel loaded already, so it computes from the first chunk on while the
children start, and one process start fewer is paid; each child is handed its next chunk
from the pool's manager thread the moment it finishes one (the compiled kernel releases
the GIL, so this goes on while the sweep's process computes its own chunk). The last
chunks of a sweep are a quarter of the size (``vei.sweep.run._chunks``), so the
processes finish close together. Every fixed cost is paid once per child, not per chunk:

- the evaluator reaches each child once (the pool's initializer), with the number of
  numba threads of each process (:func:`threads_per_worker`: the cores shared out, so two
  workers on two cores run one thread each instead of fighting over both; the sweep's
  process uses as many while it computes), and its optional ``warm_up(load_kernel)``
  imports what the chunks need (a forked child also loads the compiled kernel);
- the children are launched without waiting for them (their imports and initializer run
  while this process prepares a single scenario itself and builds the variants table);
  they are forked when :func:`vei.sweep.workers.fork_is_safe` (``vei sweep``: this
  process has run no kernel yet), so they start with its imports (~0.5 s less each),
  else spawned;
  several scenarios are prepared in the pool, in parallel;
- each prepared scenario (its ScenarioArrays, possibly MBs) is pickled once into a file of
  a temporary folder; a worker loads it on its first chunk of that scenario and keeps it
  (:data:`_WORKER` cache, the last :data:`_CACHE_SCENARIOS` scenarios); the worker that
  prepared a scenario keeps its own copy. A job carries only the key and the file name;
- the child writes the part file itself, so the parent neither unpickles nor encodes the
  rows of the children's chunks.
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

from vei.sweep.evaluator import Evaluator

#: A chunk of work: (scenario key, variants rows, part file path, the spec's seed when the
#: rows are not named yet, else None).
Job = tuple[str, pd.DataFrame, Path, int | None]

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


def evaluate_rows(
    evaluator: Evaluator, prepared: Any, chunk: pd.DataFrame, id_seed: int | None = None
) -> pd.DataFrame:
    """Run one chunk [B rows] and join its metrics to its variant rows (same order).

    ``id_seed``: the chunk's rows are not named yet (no variant_id / seed columns): name
    them first with this spec seed (:func:`vei.sweep.ids.name_variants`)."""
    if id_seed is not None:
        from vei.sweep.ids import name_variants

        chunk = name_variants(chunk, id_seed)
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
    """Write a chunk's rows [B] as a part file (atomically); returns B. No dictionary
    encoding: a part is read once (results.parquet), and it is as small without (~2x
    faster to write)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from vei.io.atomic import atomic_path

    table = pa.Table.from_pandas(rows, preserve_index=False)
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, use_dictionary=False)
    return len(rows)


def _evaluate_job(
    evaluator: Evaluator, prepared: Any, chunk: pd.DataFrame, id_seed: int | None
) -> pd.DataFrame:
    """Run one chunk (a Ray task: the rows go back to the parent, which writes them)."""
    return evaluate_rows(evaluator, prepared, chunk, id_seed)


def _prepare_job(evaluator: Evaluator, scenario_dir: str) -> Any:
    """Prepare one scenario (runs in a Ray task)."""
    return evaluator.prepare(Path(scenario_dir))


# --------------------------------------------------------------------------- pool workers


def _init_sweep_worker(evaluator: Evaluator, numba_threads: int, forked: bool = False) -> None:
    """Initializer of a sweep's pool worker: keep the evaluator, set the numba threads,
    and let the evaluator import what its chunks need (its optional
    ``warm_up(load_kernel=forked)``; a forked worker loads the compiled kernel too) while
    the parent prepares the scenario."""
    if numba_threads > 0:
        set_numba_threads(numba_threads)
    _WORKER.clear()
    _WORKER.update(evaluator=evaluator, prepared=OrderedDict())
    warm_up = getattr(evaluator, "warm_up", None)
    if callable(warm_up):
        warm_up(load_kernel=forked)


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


def _pool_job(key: str, file: str, chunk: pd.DataFrame, part: str, id_seed: int | None) -> int:
    """Evaluate a chunk in a worker and write its part file; returns its number of rows."""
    cache: OrderedDict = _WORKER["prepared"]
    if key in cache:
        cache.move_to_end(key)
        prepared = cache[key]
    else:
        with open(file, "rb") as fh:
            prepared = _cache(key, pickle.load(fh))
    return _write_part(Path(part), evaluate_rows(_WORKER["evaluator"], prepared, chunk, id_seed))


# --------------------------------------------------------------------------- executors


class _SerialRunner:
    """Everything in this process."""

    def __init__(self, evaluator: Evaluator) -> None:
        self.evaluator = evaluator

    def prepare_all(self, dirs: Sequence[Path]) -> dict[str, Any]:
        return {str(d): self.evaluator.prepare(Path(d)) for d in dirs}

    def run(self, jobs: Iterable[Job], prepared: dict[str, Any]) -> Iterator[int]:
        for d, chunk, part, id_seed in jobs:
            yield _write_part(part, evaluate_rows(self.evaluator, prepared[d], chunk, id_seed))


class _PoolRunner:
    """``workers`` processes evaluate chunks: this one and a pool of ``workers - 1``
    children (module docstring). Every child has up to 2 chunks at a time (one computing,
    one queued), refilled as each finishes; this process evaluates the next chunk itself
    meanwhile: no core waits while the children start, and one process start fewer is
    paid."""

    def __init__(
        self, evaluator: Evaluator, pool: Any, workers: int, scratch: Path, threads: int
    ) -> None:
        self.evaluator, self.pool, self.workers, self.scratch = evaluator, pool, workers, scratch
        self.children = workers - 1
        self.threads = threads
        self.files: dict[str, str] = {}

    def prepare_all(self, dirs: Sequence[Path]) -> dict[str, Any]:
        self.files = {str(d): str(self.scratch / f"scenario-{i}.pkl") for i, d in enumerate(dirs)}
        if len(dirs) == 1:  # here, while the children start
            from vei.io.atomic import write_bytes

            d = str(dirs[0])
            prepared = self.evaluator.prepare(Path(d))
            write_bytes(self.files[d], pickle.dumps(prepared, protocol=pickle.HIGHEST_PROTOCOL))
            return {d: prepared}
        futures = {d: self.pool.submit(_pool_prepare, d, f) for d, f in self.files.items()}
        return {d: f.result() for d, f in futures.items()}

    def run(self, jobs: Iterable[Job], prepared: dict[str, Any]) -> Iterator[int]:
        import queue
        import threading

        it = iter(jobs)
        lock = threading.Lock()
        finished: queue.SimpleQueue = queue.SimpleQueue()
        in_flight = [0]
        stopped = threading.Event()
        errors: list[BaseException] = []

        def take(for_child: bool) -> Job | None:
            # Taken and (for a child) counted at once, so the loop below never misses it.
            with lock:
                job = next(it, None)
                if job is not None and for_child:
                    in_flight[0] += 1
                return job

        def collect() -> int:
            # A child's finished chunk (its rows on disk), counted off.
            with lock:
                in_flight[0] -= 1
            return finished.get().result()

        def feed(done: Any = None) -> None:
            # Runs here and in the pool's manager thread (a child's chunk is done): the
            # child gets its next chunk at once, while this process computes its own (the
            # compiled kernel releases the GIL). Nothing more once a chunk failed or the
            # sweep stops (Ctrl-C, an error): the pool is being killed.
            if stopped.is_set() or (
                done is not None and (done.cancelled() or done.exception() is not None)
            ):
                return
            job = take(for_child=True)
            if job is None:
                return
            d, chunk, part, id_seed = job
            try:
                f = self.pool.submit(_pool_job, d, self.files[d], chunk, str(part), id_seed)
            except RuntimeError as exc:  # a broken pool (a child died) or one shut down
                with lock:
                    in_flight[0] -= 1
                errors.append(exc)  # raised by the loop below: the chunk was not run
                return
            f.add_done_callback(finished.put)
            f.add_done_callback(feed)

        try:
            import numba
        except ImportError:  # pragma: no cover - numba is a core dependency
            numba = None
        before = numba.get_num_threads() if numba is not None else 0
        if numba is not None:  # this process's share of the cores while it computes
            numba.set_num_threads(max(1, min(self.threads, numba.config.NUMBA_NUM_THREADS)))
        try:
            for _ in range(2 * self.children):  # one computing, one queued per child
                feed()
            while True:
                if errors:
                    raise errors[0]
                while not finished.empty():
                    yield collect()
                job = take(for_child=False)
                if job is not None:  # this process's own chunk
                    d, chunk, part, id_seed = job
                    rows = evaluate_rows(self.evaluator, prepared[d], chunk, id_seed)
                    yield _write_part(part, rows)
                    continue
                with lock:
                    busy = in_flight[0]
                if busy == 0:
                    if errors:
                        raise errors[0]
                    return
                yield collect()
        finally:
            stopped.set()
            if numba is not None:
                numba.set_num_threads(before)


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
            for d, chunk, part, id_seed in it:
                ref = remote.remote(self.ev_ref, self.refs[d], chunk, id_seed)
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
        from vei.sweep.workers import ray_session

        # The session of this process, the cluster at $RAY_ADDRESS, or a local Ray.
        with ray_session(workers) as ray:
            yield _RayRunner(evaluator, ray, workers)
        return
    if workers == 1:
        yield _SerialRunner(evaluator)
        return
    from vei.sweep.workers import WorkerPool, fork_is_safe

    # Children die with this process (kill -9 included) and ignore Ctrl-C; leaving the
    # block with an exception (KeyboardInterrupt) kills them at once. Forked where that is
    # safe (vei sweep: before any kernel ran here): they start with this process's imports.
    threads = threads_per_worker(workers)
    method = "fork" if fork_is_safe() else "spawn"
    with (
        tempfile.TemporaryDirectory(prefix="vei-sweep-") as scratch,
        WorkerPool(
            workers - 1,
            initializer=_init_sweep_worker,
            initargs=(evaluator, threads, method == "fork"),
            wait_ready=False,
            kill_on_exit=True,  # every part is on disk: no wait for the children to exit
            start_method=method,
        ) as pool,
    ):
        yield _PoolRunner(evaluator, pool, workers, Path(scratch), threads)
