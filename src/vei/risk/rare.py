"""Rare events: cross-entropy importance sampling and subset simulation (both vei's own).

Both work in standard normal space on the limit-state ``margin`` of
:mod:`vei.risk.problem` (failure: margin < 0) and evaluate the engine in batches: a
stage of 1,000 samples is one engine call, never 1,000.

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
- **Subset simulation** (``subset``; Au & Beck 2001): vei's own (:mod:`vei.risk.subset`):
  nested levels of conditional probability p0 = 0.1 sampled by modified Metropolis,
  the interval from the Au & Beck coefficient of variation with the chains'
  correlation, independent runs until the target or the budget. The other outcomes are
  P(F) times their share among the last levels' failing samples.

When a method ends without an estimate (no failure in any stage), the caller
(:func:`vei.risk.assess.assess_planner`) continues the first stage, a sample of the
variation itself, as plain Monte Carlo: an estimate or an honest upper bound.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

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
#: Cross-entropy: a stage with this many failures (but fewer than rho N) takes its
#: failures as the elite.
MIN_ELITE_FAILURES = 10

#: evaluate(u [N, d], stage label) -> the rows (with 'margin', 'failure' and outcomes).
Evaluate = Callable[[FloatArray, str], pd.DataFrame]


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
        mixture: an estimate from the mixture of every stage (the stages held failures
            but never reached the region): its components (mean, std, share).
        first: the first stage's rows (a sample of the variation itself) when no
            estimate was reached, for an honest Monte Carlo bound.
    """

    method: str
    rows: pd.DataFrame
    probability: Estimate
    n_simulations: int
    stages: list[dict[str, Any]] = field(default_factory=list)
    reached: bool = True
    proposal: dict[str, list[float]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    mixture: list[tuple[FloatArray, FloatArray, float]] | None = None
    first: pd.DataFrame | None = None


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
    initial: tuple[FloatArray, pd.DataFrame] | None = None,
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
    narrow rather than far) and, finally, to the failing samples. A stage that holds at
    least MIN_ELITE_FAILURES failures but fewer than rho N takes its failures as the
    elite (the margin quantile may point elsewhere: a near miss is not on the way to a
    collision). Then the final importance sample is drawn from the fitted proposal in
    stages until the target relative CI or the budget.

    When the stages end before the failure region (budget, stall) but some stage held
    failures, the estimate is the deterministic-mixture importance sample of every
    stage (each stage's proposal, balance heuristic): an estimate, not a bound.

    Args:
        evaluate: simulates u [N, d] under a stage label, returns rows with 'margin',
            'failure' (and the other outcomes).
        dim: d. stage_size: samples per stage (one engine batch). budget: simulations at
            most. target_rel_ci: stop drawing when P(failure)'s relative CI is below it.
        seed: NumPy's seed (same seed, same result).
        initial: (u [n, d], rows) already simulated from the variation itself (a Monte
            Carlo pilot): the first stage, reused rather than re-simulated, and not
            counted in ``budget``.
    """
    rng = np.random.default_rng(seed)
    mu = np.zeros(dim)
    sigma = np.ones(dim)
    used = 0
    stages: list[dict[str, Any]] = []
    history: list[tuple[FloatArray, pd.DataFrame, FloatArray, FloatArray]] = []
    reached = False
    best = math.inf
    flat = 0
    while len(stages) < MAX_STAGES and flat < STALL_STAGES:
        if not stages and initial is not None:
            u, rows = np.asarray(initial[0], dtype=np.float64), initial[1]
            rng.standard_normal(u.shape)  # the stream moves on as if it had drawn them
        elif used + stage_size <= budget:
            u = mu + sigma * rng.standard_normal((stage_size, dim))
            rows = evaluate(u, f"ce-{len(stages)}")
            used += stage_size
        else:
            break
        history.append((u, rows, mu.copy(), sigma.copy()))
        margin = rows["margin"].to_numpy(np.float64)
        q = float(np.quantile(margin, RHO))
        level = max(q, 0.0)
        fail = margin < 0
        n_fail = int(fail.sum())
        elite = margin <= level
        by_failures = not q <= 0.0 and n_fail >= MIN_ELITE_FAILURES
        if by_failures:
            elite = fail
        w = np.exp(_log_ratio(u[elite], mu, sigma))
        w = w / w.sum()
        mu_fit = w @ u[elite]
        sd_fit = np.sqrt(np.maximum(w @ (u[elite] - mu_fit) ** 2, SIGMA_FLOOR**2))
        moved = float(np.linalg.norm(mu_fit - mu))
        reached = q <= 0.0
        stages.append({"stage": len(stages), "level": level, "samples": len(u),
                       "mean_moved": moved, "failures": n_fail,
                       "reused": bool(len(stages) == 0 and initial is not None),
                       "elite": "failures" if by_failures else "quantile"})  # fmt: skip
        if reached:
            reach_rows = rows.copy()  # an importance sample of the proposal it came from
            reach_rows["weight"] = np.exp(_log_ratio(u, mu, sigma))
            reach_q = (mu.copy(), sigma.copy())
            wf = np.exp(_log_ratio(u[fail], mu, sigma))
            wf = wf / wf.sum()
            mu = wf @ u[fail]
            sigma = np.sqrt(np.maximum(wf @ (u[fail] - mu) ** 2, SIGMA_FLOOR**2))
            break
        if moved < STAGNATION:
            sigma = sd_fit
        mu = mu_fit
        # the level stalls (no failure region within reach): give up, keep the budget
        flat = 0 if by_failures else (flat + 1 if level > best * (1.0 - STALL_GAIN) else 0)
        best = min(best, level)
    notes: list[str] = []
    if not reached:
        return _unreached(history, stages, used, budget, flat, mu, sigma)
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


def _unreached(
    history: list[tuple[FloatArray, pd.DataFrame, FloatArray, FloatArray]],
    stages: list[dict[str, Any]], used: int, budget: int, flat: int,
    mu: FloatArray, sigma: FloatArray,
) -> RareResult:  # fmt: skip
    """The stages ended before the failure region: the mixture estimate of every stage
    where some stage held failures, else no estimate (``probability.bound``)."""
    last = stages[-1]["level"] if stages else math.nan
    why = (
        f"the level stalled for {STALL_STAGES} stages (no failure region within reach)"
        if flat >= STALL_STAGES
        else f"the budget ({budget:,} simulations) ended"
    )
    proposal = {"mean": mu.tolist(), "std": sigma.tolist()}
    n_fail = sum(int(r["failure"].sum()) for _, r, _, _ in history)
    if n_fail:
        rows, comps = mixture_sample(history)
        est = _is_failure(rows).with_note(
            f"{why} after {len(stages)} adaptive stages before the proposal reached the "
            f"failure region; the estimate is the mixture importance sample of all "
            f"{len(stages)} stages ({n_fail:,} failures)"
        )
        return RareResult("ce", rows, est, used, stages, False, proposal, list(est.notes),
                          mixture=comps)  # fmt: skip
    note = (
        f"partial answer: {why} after {len(stages)} adaptive stages before the proposal "
        f"reached the failure region (last margin quantile {last:.3g} m > 0): no estimate"
    )
    est = Estimate(math.nan, 0.0, math.nan, used, "importance-sampling", 0, bound=True,
                   reliable=False, notes=(note,))  # fmt: skip
    first = history[0][1] if history else pd.DataFrame()
    return RareResult("ce", pd.DataFrame(), est, used, stages, False, proposal, [note],
                      first=first)  # fmt: skip


def mixture_sample(
    history: list[tuple[FloatArray, pd.DataFrame, FloatArray, FloatArray]],
) -> tuple[pd.DataFrame, list[tuple[FloatArray, FloatArray, float]]]:
    """Every stage's samples weighted by the deterministic mixture (balance heuristic,
    Owen & Zhou 2000): w = phi(u) / sum_k (n_k / N) q_k(u), q_k = N(mu_k, sigma_k^2).

    Returns:
        (the rows with ``weight``, the mixture's components (mean [d], std [d], share)).
    """
    n_tot = sum(len(u) for u, _, _, _ in history)
    comps = [(m, s, len(u) / n_tot) for u, _, m, s in history]
    u_all = np.vstack([u for u, _, _, _ in history])
    rows = pd.concat([r for _, r, _, _ in history], ignore_index=True).copy()
    rows["weight"] = np.exp(-mixture_log_ratio(u_all, comps))
    return rows, comps


def mixture_log_ratio(
    u: FloatArray, comps: list[tuple[FloatArray, FloatArray, float]]
) -> FloatArray:
    """log q(u) - log phi(u) [N] of a normal mixture sum_k share_k N(mu_k, sigma_k^2)."""
    terms = np.stack([-_log_ratio(u, m, s) + math.log(c) for m, s, c in comps])
    return np.logaddexp.reduce(terms, axis=0)


def _is_failure(rows: pd.DataFrame) -> Estimate:
    fail = rows["failure"].to_numpy(bool)
    return importance_sampling(fail, rows["weight"].to_numpy(np.float64), fail)


def subset_simulation(
    evaluate: Evaluate,
    dim: int,
    *,
    level_size: int,
    budget: int,
    seed: int,
    target_rel_ci: float = 0.1,
    initial: tuple[FloatArray, pd.DataFrame] | None = None,
) -> RareResult:
    """Subset simulation (:mod:`vei.risk.subset`): ``level_size`` samples per level,
    independent runs until the target relative CI or the budget; the last level's
    samples of every run are the rows of the secondary outcomes."""
    from vei.risk import subset

    est, runs, used = subset.subset_estimate(
        evaluate, dim, level_size=level_size, budget=budget, target_rel_ci=target_rel_ci,
        seed=seed, initial=initial,
    )  # fmt: skip
    frames = [r.last for r in runs if len(r.last)]
    last = pd.concat(frames, ignore_index=True) if frames else pd.DataFrame()
    notes = list(est.notes)
    reached = not est.bound
    if not reached:
        notes.append(
            f"partial answer: no failure in {len(runs)} subset simulation run(s) within the "
            f"budget ({budget:,} simulations): no estimate"
        )
    first = initial[1] if initial is not None else pd.DataFrame()
    return RareResult("subset", last, est, used, subset.as_stages(runs), reached, notes=notes,
                      first=first)  # fmt: skip
