"""Sweep executors: serial, a process pool whose workers die with the sweep
(:class:`vei.experiments.workers.WorkerPool`), or Ray tasks."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

import pandas as pd

from vei.experiments.sweep_engine import Evaluator


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
    with WorkerPool(workers) as pool:
        yield _PoolRunner(evaluator, pool, workers)
