"""Searching for failures: vei's searches beside the field's standard, pymoo's NSGA-II.

OpenSBT (Sorokin et al. 2023), the open search-based testing framework, searches the
scenario parameters with pymoo's NSGA-II (FloatRandomSampling, SBX crossover, polynomial
mutation, duplicates eliminated) and counts **distinct failures** as the occupied cells
of an n^d grid over the normalised search space (``quality_indicators/metrics/ncrit.py``).
vei runs every searcher on the same problem:

- **parameters**: the variation's d dimensions, normalised to the probability cube
  [0, 1]^d (each quantity through its own distribution function, x = Phi(u); the
  variation's box, as OpenSBT normalises its bounds);
- **objective**: a failure is a collision that was not seen too late (the probabilities'
  event); NSGA-II minimises (margin, -injury risk), the margin being -1 for a failure and
  the minimum gap [m] otherwise;
- **budget**: the same number of simulations for each;

and counts distinct failures with the same rule: failures in distinct cells of an n^d
grid over [0, 1]^d (:func:`distinct_failures`; n = CELLS per dimension). Searchers:

- ``random``: plain Monte Carlo of the variation (OpenSBT's own baseline);
- ``nsga2``: pymoo NSGA-II, population 50, OpenSBT's operators, stopped at the budget;
- ``ce``: vei's rare-event sampler (the cross-entropy stages and its final importance
  sample, :func:`vei.risk.rare.cross_entropy`);
- ``boundary``: vei's critical-boundary search (:func:`vei.experiments.boundary.
  adaptive_boundary`) in the plane of the first two dimensions, the others at their
  medians: a 2-D method, so its failures occupy one slice of the cube.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd
from scipy.special import ndtr, ndtri

from vei.errors import DependencyError

#: Cells per dimension of the distinct-failure grid.
CELLS = 5
SEARCHERS: tuple[str, ...] = ("random", "nsga2", "ce", "boundary")
_EPS = 1e-9


def distinct_failures(x: np.ndarray, cells: int = CELLS) -> int:
    """Occupied cells of a cells^d grid over [0, 1]^d by the failing points x [K, d]
    (OpenSBT's n_critical_distinct: floor(x cells), the upper edge in the last cell)."""
    x = np.atleast_2d(np.asarray(x, dtype=np.float64))
    if x.size == 0:
        return 0
    idx = np.minimum(np.floor(x * cells).astype(np.int64), cells - 1)
    return len(np.unique(idx, axis=0))


@dataclass(frozen=True)
class SearchResult:
    """One searcher's outcome on one problem.

    Attributes:
        searcher: its name. n_simulations: simulations spent. failures: failing samples.
        distinct: distinct failures (cells). seconds: wall time.
    """

    searcher: str
    n_simulations: int
    failures: int
    distinct: int
    seconds: float

    @property
    def distinct_per_1000(self) -> float:
        """Distinct failures per 1,000 simulations."""
        return 1000.0 * self.distinct / self.n_simulations if self.n_simulations else math.nan

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {
            "searcher": self.searcher,
            "n_simulations": self.n_simulations,
            "failures": self.failures,
            "distinct_failures": self.distinct,
            "distinct_per_1000": self.distinct_per_1000,
            "seconds": self.seconds,
        }


def _to_u(x: np.ndarray) -> np.ndarray:
    return ndtri(np.clip(x, _EPS, 1.0 - _EPS))


def _summary(name: str, frames: list[pd.DataFrame], cells: int, t0: float) -> SearchResult:
    rows = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    if rows.empty:
        return SearchResult(name, 0, 0, 0, time.perf_counter() - t0)
    u = rows[[c for c in rows.columns if c.startswith("u.")]].to_numpy(np.float64)
    fail = rows["failure"].to_numpy(bool)
    return SearchResult(name, len(rows), int(fail.sum()), distinct_failures(ndtr(u[fail]), cells),
                        time.perf_counter() - t0)  # fmt: skip


def search_random(
    problem: Any, policy: str, budget: int, seed: int, cells: int = CELLS
) -> SearchResult:
    """Plain Monte Carlo of the variation."""
    t0 = time.perf_counter()
    u = np.random.default_rng(seed).standard_normal((budget, problem.space.dimension))
    return _summary("random", [problem.evaluate(u, policy, stage="search-random")], cells, t0)


def search_nsga2(
    problem: Any, policy: str, budget: int, seed: int, cells: int = CELLS, pop_size: int = 50
) -> SearchResult:
    """pymoo NSGA-II with OpenSBT's operators on the probability cube (module docstring)."""
    try:
        from pymoo.algorithms.moo.nsga2 import NSGA2
        from pymoo.core.problem import Problem
        from pymoo.operators.crossover.sbx import SBX
        from pymoo.operators.mutation.pm import PM
        from pymoo.operators.sampling.rnd import FloatRandomSampling
        from pymoo.optimize import minimize
    except ImportError as exc:  # pragma: no cover - installed with the risk extra
        raise DependencyError(
            "the NSGA-II comparison needs pymoo: pip install 'vei[risk]'"
        ) from exc

    t0 = time.perf_counter()
    d = problem.space.dimension
    frames: list[pd.DataFrame] = []

    class _P(Problem):
        def __init__(self) -> None:
            super().__init__(n_var=d, n_obj=2, xl=np.zeros(d), xu=np.ones(d))

        def _evaluate(self, x: np.ndarray, out: dict, *args: Any, **kwargs: Any) -> None:
            # the last generation may overshoot the budget: its extra points are not
            # simulated and score worst
            left = max(budget - sum(len(f) for f in frames), 0)
            f = np.full((len(x), 2), 1e9)
            if left:
                rows = problem.evaluate(_to_u(x[:left]), policy, stage="search-nsga2")
                frames.append(rows)
                f[: len(rows), 0] = rows["margin"].to_numpy(np.float64)
                f[: len(rows), 1] = -rows["injury"].to_numpy(np.float64)
            out["F"] = f

    algo = NSGA2(pop_size=pop_size, sampling=FloatRandomSampling(), crossover=SBX(prob=0.9, eta=15),
                 mutation=PM(eta=20), eliminate_duplicates=True)  # fmt: skip
    minimize(_P(), algo, ("n_eval", budget), seed=seed, verbose=False)
    return _summary("nsga2", frames, cells, t0)


def search_ce(
    problem: Any, policy: str, budget: int, seed: int, cells: int = CELLS
) -> SearchResult:
    """vei's cross-entropy sampler: every stage's samples count (adaptive and final)."""
    from vei.risk.rare import cross_entropy

    t0 = time.perf_counter()
    frames: list[pd.DataFrame] = []

    def evaluate(u: np.ndarray, label: str) -> pd.DataFrame:
        rows = problem.evaluate(u, policy, stage=f"search-{label}")
        frames.append(rows)
        return rows

    stage = max(100, budget // 10)
    cross_entropy(evaluate, problem.space.dimension, stage_size=stage, budget=budget,
                  target_rel_ci=0.0, seed=seed)  # fmt: skip
    return _summary("ce", frames, cells, t0)


def search_boundary(
    problem: Any, policy: str, budget: int, seed: int, cells: int = CELLS
) -> SearchResult:
    """vei's critical-boundary search in the plane of the first two dimensions (the
    others at their medians), with coarse grid and levels chosen to stay within budget."""
    from vei.sweep.lattice import adaptive_boundary

    del seed  # deterministic
    t0 = time.perf_counter()
    d = problem.space.dimension
    frames: list[pd.DataFrame] = []

    def oracle(points: np.ndarray) -> dict[str, Any]:
        u = np.zeros((len(points), d))
        u[:, :2] = _to_u(points)
        left = budget - sum(len(f) for f in frames)
        rows = problem.evaluate(u[: max(left, 0)], policy, stage="search-boundary")
        frames.append(rows)
        coll = np.zeros(len(points), bool)
        coll[: len(rows)] = rows["failure"].to_numpy(bool)
        return {"collision": coll}

    if d < 2:
        return _summary("boundary", frames, cells, t0)
    # coarse n x n with n^2 ~ budget / 4, the rest for refinement
    n = max(3, int(math.sqrt(budget / 4)))
    adaptive_boundary(oracle, (0.0, 1.0), (0.0, 1.0), coarse=(n, n), levels=3)
    return _summary("boundary", frames, cells, t0)


def compare_searches(
    problem: Any, policy: str, *, budget: int, seed: int = 0, cells: int = CELLS,
    searchers: tuple[str, ...] = SEARCHERS,
) -> list[SearchResult]:  # fmt: skip
    """Every searcher on the same problem and budget (module docstring)."""
    run = {"random": search_random, "nsga2": search_nsga2, "ce": search_ce,
           "boundary": search_boundary}  # fmt: skip
    return [run[s](problem, policy, budget, seed, cells) for s in searchers]
