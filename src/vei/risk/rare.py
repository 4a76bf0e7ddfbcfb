"""Rare events: cross-entropy importance sampling (vei) and subset simulation (OpenTURNS).

Both work in standard normal space on the limit-state ``margin`` of
:mod:`vei.risk.problem` (failure: margin < 0) and evaluate the engine in batches: a
stage of 1,000 samples is one engine call, never 1,000 (OpenTURNS: ``setBlockSize`` =
the stage size, one outer sample).

- **Cross-entropy importance sampling** (``ce``; Rubinstein & Kroese 2004; Zhao et al.
  2017 for automated-vehicle testing): a normal proposal q = N(mu, diag sigma^2) is
  adapted towards the failure region stage by stage through the rho-quantiles of the
  margin (rho = 0.1) until the quantile reaches the failure threshold; then the final
  importance sample is drawn from q, with weights w = phi(u) / q(u), until the estimate
  reaches the target relative CI or the budget ends, and every estimate (collision,
  injury-relevant collision, injury risk) and the diagnostics (ESS, weight share, CoV)
  come from that weighted sample (:func:`vei.risk.estimators.importance_sampling`).
  vei's own loop, not OpenTURNS' ``StandardSpaceCrossEntropyImportanceSampling``: that
  one refits the standard deviations at every stage, they shrink geometrically (the top
  10 % of a normal has 0.44 of its spread), and the proposal stalls before a failure
  region more than ~3 sigma away along one coordinate (tests/risk/test_rare.py shows it on
  a scripted problem; on the engine's scripted crossing of tests/risk/test_engine_known.py
  it spent 12 stages with the level stuck at 0.34 m). vei refits only
  the mean while the level moves, the standard deviations once the mean stagnates (a
  narrow rather than far failure region) and, at the end, to the failing samples.
- **Subset simulation** (``subset``; Au & Beck 2001): ``openturns.SubsetSampling``
  writes P(F) as a product of conditional probabilities p0 = 0.1 of nested levels, each
  sampled by modified Metropolis from the level before. Its coefficient of variation
  (OpenTURNS' estimate, with the within-level chain correlation) gives the interval
  p (1 +- 1.96 CoV); vei marks it approximate (the levels' correlation is neglected).
  The other outcomes are P(F) times their share among the last level's failing samples.

Subset simulation is OpenTURNS': maintained and documented, in standard space, with
batch evaluation and a stop callback (the budget). It can
stall on a very narrow failure region (the Metropolis chains stop moving; seen on a
1-D interval of probability 1e-5 in 7 dimensions), which is why ``auto`` uses the
cross-entropy method and subset simulation is offered as a choice.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.errors import DependencyError
from vei.risk.estimators import Estimate, importance_sampling

FloatArray = npt.NDArray[np.float64]

#: CE quantile level rho and subset simulation's conditional probability p0.
RHO = 0.1
#: The most adaptive stages either method may take.
MAX_STAGES = 40
#: Cross-entropy: the mean "stagnates" when it moves less than this (standard units).
STAGNATION = 0.5
#: Smallest standard deviation of a cross-entropy proposal (standard units).
SIGMA_FLOOR = 1e-6
#: Cross-entropy gives up when the level has not dropped by STALL_GAIN (relative) for
#: STALL_STAGES stages in a row.
STALL_STAGES = 4
STALL_GAIN = 0.01

#: evaluate(u [N, d], stage label) -> the rows (with 'margin', 'failure' and outcomes).
Evaluate = Callable[[FloatArray, str], pd.DataFrame]


def _openturns() -> Any:
    try:
        import openturns as ot
    except ImportError as exc:  # pragma: no cover - the extra is installed in CI
        raise DependencyError(
            "the rare-event estimators need OpenTURNS: pip install 'vei[risk]'"
        ) from exc
    return ot


@dataclass
class RareResult:
    """What a rare-event run produced.

    Attributes:
        method: 'ce' or 'subset'.
        rows: the final weighted sample (ce: the importance sample with its ``weight``
            column; subset: the last level's samples).
        probability: the failure probability estimate.
        n_simulations: every simulation spent (adaptive stages included).
        stages: per adaptive stage: threshold and samples.
        reached: the failure region was reached (else the estimate is a partial answer).
        proposal: ce: the final proposal's mean and standard deviation per dimension.
        notes: plain-language remarks.
    """

    method: str
    rows: pd.DataFrame
    probability: Estimate
    n_simulations: int
    stages: list[dict[str, Any]] = field(default_factory=list)
    reached: bool = True
    proposal: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)


class _Tracked:
    """The limit-state as an OpenTURNS function of whole samples, each call one stage,
    stopping (via the stop callback) when the budget is spent."""

    def __init__(self, evaluate: Evaluate, dim: int, prefix: str, budget: int) -> None:
        self.evaluate = evaluate
        self.prefix = prefix
        self.budget = budget
        self.used = 0
        self.frames: list[pd.DataFrame] = []
        self.dim = dim

    def __call__(self, x: Any) -> Any:
        u = np.asarray(x, dtype=np.float64).reshape(-1, self.dim)
        rows = self.evaluate(u, f"{self.prefix}-{len(self.frames)}")
        self.frames.append(rows)
        self.used += len(u)
        return rows["margin"].to_numpy(np.float64).reshape(-1, 1)

    def stop(self) -> bool:
        return self.used >= self.budget


def _event(ot: Any, tracked: _Tracked, dim: int) -> Any:
    fn = ot.PythonFunction(dim, 1, func_sample=tracked)
    vec = ot.CompositeRandomVector(fn, ot.RandomVector(ot.Normal(dim)))
    return ot.ThresholdEvent(vec, ot.Less(), 0.0)


def _log_ratio(u: FloatArray, mu: FloatArray, sigma: FloatArray) -> FloatArray:
    """log phi(u) - log q(u) [N] for q = prod N(mu_j, sigma_j^2)."""
    z = (u - mu) / sigma
    return np.sum(-0.5 * u * u + 0.5 * z * z + np.log(sigma), axis=1)


def cross_entropy(
    evaluate: Evaluate,
    dim: int,
    *,
    stage_size: int,
    budget: int,
    target_rel_ci: float,
    seed: int,
) -> RareResult:
    """Cross-entropy importance sampling with a normal proposal N(mu, diag sigma^2)
    (module docstring).

    Adaptive stages: draw ``stage_size`` samples from the proposal, find the rho-quantile
    q of their margins (q <= 0: the failure region is reached), and refit the proposal
    to the elite samples (margin <= max(q, 0)) weighted by phi / q_k (Rubinstein &
    Kroese 2004). While the level moves, only the mean is refitted (the standard
    deviations stay: refitting them too shrinks them geometrically and the proposal
    stalls before a failure region more than ~3 sigma away); they are refitted once the
    mean stagnates (moves < STAGNATION in standard units: a failure region that is
    narrow rather than far) and, finally, to the failing samples. Then the final
    importance sample is drawn from the fitted proposal in stages until the target
    relative CI or the budget.

    Args:
        evaluate: simulates u [N, d] under a stage label, returns rows with 'margin',
            'failure' (and the other outcomes).
        dim: d. stage_size: samples per stage (one engine batch). budget: simulations at
            most. target_rel_ci: stop drawing when P(failure)'s relative CI is below it.
        seed: NumPy's seed (same seed, same result).
    """
    rng = np.random.default_rng(seed)
    mu = np.zeros(dim)
    sigma = np.ones(dim)
    used = 0
    stages: list[dict[str, Any]] = []
    reached = False
    best = math.inf
    flat = 0
    while len(stages) < MAX_STAGES and used + stage_size <= budget and flat < STALL_STAGES:
        u = mu + sigma * rng.standard_normal((stage_size, dim))
        rows = evaluate(u, f"ce-{len(stages)}")
        used += stage_size
        margin = rows["margin"].to_numpy(np.float64)
        q = float(np.quantile(margin, RHO))
        level = max(q, 0.0)
        elite = margin <= level
        w = np.exp(_log_ratio(u[elite], mu, sigma))
        w = w / w.sum()
        mu_fit = w @ u[elite]
        sd_fit = np.sqrt(np.maximum(w @ (u[elite] - mu_fit) ** 2, SIGMA_FLOOR**2))
        moved = float(np.linalg.norm(mu_fit - mu))
        reached = q <= 0.0
        stages.append({"stage": len(stages), "level": level, "samples": stage_size,
                       "mean_moved": moved, "failures": int((margin < 0).sum())})  # fmt: skip
        if reached:
            reach_rows = rows.copy()  # an importance sample of the proposal it came from
            reach_rows["weight"] = np.exp(_log_ratio(u, mu, sigma))
            reach_q = (mu.copy(), sigma.copy())
            fail = margin < 0
            wf = np.exp(_log_ratio(u[fail], mu, sigma))
            wf = wf / wf.sum()
            mu = wf @ u[fail]
            sigma = np.sqrt(np.maximum(wf @ (u[fail] - mu) ** 2, SIGMA_FLOOR**2))
            break
        if moved < STAGNATION:
            sigma = sd_fit
        mu = mu_fit
        # the level stalls (no failure region within reach): give up, keep the budget
        flat = flat + 1 if level > best * (1.0 - STALL_GAIN) else 0
        best = min(best, level)
    notes: list[str] = []
    if not reached:
        last = stages[-1]["level"] if stages else math.nan
        why = (
            f"the level stalled for {STALL_STAGES} stages (no failure region within reach)"
            if flat >= STALL_STAGES
            else f"the budget ({budget:,} simulations) ended"
        )
        notes.append(
            f"partial answer: {why} after {len(stages)} adaptive stages before the proposal "
            f"reached the failure region (last margin quantile {last:.3g} m > 0): no estimate"
        )
        est = Estimate(math.nan, 0.0, math.nan, used, "importance-sampling", bound=True,
                       reliable=False, notes=tuple(notes))  # fmt: skip
        return RareResult("ce", pd.DataFrame(), est, used, stages, False,
                          {"mean": mu.tolist(), "std": sigma.tolist()}, notes)  # fmt: skip
    frames: list[pd.DataFrame] = []
    est = _is_failure(reach_rows)
    if used + stage_size > budget:  # no budget for a stage of the fitted proposal
        frames.append(reach_rows)
        mu, sigma = reach_q
    while used + stage_size <= budget:
        u = mu + sigma * rng.standard_normal((stage_size, dim))
        rows = evaluate(u, f"ce-final-{len(frames)}").copy()
        used += stage_size
        rows["weight"] = np.exp(_log_ratio(u, mu, sigma))
        frames.append(rows)
        est = _is_failure(pd.concat(frames, ignore_index=True))
        if est.rel_ci <= target_rel_ci:
            break
    final = pd.concat(frames, ignore_index=True)
    if est.rel_ci > target_rel_ci:
        notes.append(
            f"target relative CI {target_rel_ci:g} not reached within the budget of "
            f"{budget:,} simulations (reached {est.rel_ci:.3g})"
        )
    return RareResult("ce", final, est, used, stages, True,
                      {"mean": mu.tolist(), "std": sigma.tolist()}, notes)  # fmt: skip


def _u(rows: pd.DataFrame, dim: int) -> FloatArray:
    cols = [c for c in rows.columns if c.startswith("u.")]
    if len(cols) != dim:
        raise ValueError(f"rows carry {len(cols)} u.* columns, expected {dim}")
    return rows[cols].to_numpy(np.float64)


def _is_failure(rows: pd.DataFrame) -> Estimate:
    fail = rows["failure"].to_numpy(bool)
    return importance_sampling(fail, rows["weight"].to_numpy(np.float64), fail)


def subset_simulation(
    evaluate: Evaluate, dim: int, *, level_size: int, budget: int, seed: int
) -> RareResult:
    """Subset simulation (module docstring): ``level_size`` samples per level.

    The estimate's interval is p (1 +- 1.96 CoV) from OpenTURNS' coefficient of
    variation, marked approximate; when the budget ends before the failure level, the
    answer is partial (no estimate).
    """
    from vei.risk.estimators import z_value

    ot = _openturns()
    ot.RandomGenerator.SetSeed(int(seed))
    tracked = _Tracked(evaluate, dim, "ss", budget)
    algo = ot.SubsetSampling(_event(ot, tracked, dim))
    # 1 / p0 outer samples per level (the Metropolis chains' steps; with one outer sample
    # OpenTURNS' estimate was biased low by 2-8x on P(u > 4) = 3.2e-5), each a batch
    chains = round(1 / RHO)
    algo.setMaximumOuterSampling(chains)
    algo.setBlockSize(max(1, int(level_size) // chains))
    algo.setConditionalProbability(RHO)

    def stop() -> bool:
        return tracked.stop() or len(tracked.frames) >= MAX_STAGES * chains

    algo.setStopCallback(stop)  # a named function: OpenTURNS keeps no reference of its own
    algo.run()
    res = algo.getResult()
    thresholds = [float(t) for t in algo.getThresholdPerStep()]
    stages = [{"stage": i, "threshold": t} for i, t in enumerate(thresholds)]
    reached = bool(thresholds) and thresholds[-1] <= 0.0
    p = float(res.getProbabilityEstimate())
    cov = float(res.getCoefficientOfVariation())
    # the last level's samples (its 1 / p0 batches)
    last = (
        pd.concat(tracked.frames[-chains:], ignore_index=True) if tracked.frames else pd.DataFrame()
    )
    notes = ["approximate interval: p (1 +- 1.96 CoV) with OpenTURNS' CoV of the subset estimate"]
    if not reached or not p > 0:
        notes.append(
            f"partial answer: the budget ({budget:,} simulations) ended before subset "
            "simulation reached the failure level: no estimate"
        )
        est = Estimate(math.nan, 0.0, math.nan, tracked.used, "subset-simulation",
                       bound=True, reliable=False, notes=tuple(notes))  # fmt: skip
        return RareResult("subset", last, est, tracked.used, stages, False, notes=notes)
    z = z_value()
    stalled = len(thresholds) >= 2 and thresholds[-2] == thresholds[-1]
    est = Estimate(
        p, max(0.0, p * (1 - z * cov)), p * (1 + z * cov), tracked.used, "subset-simulation",
        int(last["failure"].sum()) if len(last) else -1,
        reliable=math.isfinite(cov) and not stalled, diagnostics={"cov": cov,
        "levels": float(len(thresholds))}, notes=tuple(notes),
    )  # fmt: skip
    if stalled:
        est = est.with_note("unreliable: the Metropolis chains stalled (equal thresholds)")
    return RareResult("subset", last, est, tracked.used, stages, True, notes=notes)
