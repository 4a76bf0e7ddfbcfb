"""Subset simulation (Au & Beck 2001) with the Markov chains' own coefficient of variation.

P(F) is written as a product of conditional probabilities of nested levels
F_1 > F_2 > ... > F_m = F, F_j = {margin <= b_j}, each b_j the p0-quantile (p0 = 0.1) of
the margins of level j's N samples. Level 0 is plain Monte Carlo from the variation;
level j > 0 starts N p0 Markov chains at the samples of level j - 1 inside F_j and
runs each for 1 / p0 states by the modified (component-wise) Metropolis algorithm of
Au & Beck (2001), section 4: per dimension a candidate u_k + N(0, 1) accepted with
probability min(1, phi(candidate) / phi(u_k)), the whole candidate kept only if its
margin is <= b_j. One step of all chains is one engine batch.

Coefficient of variation (Au & Beck 2001, eqs. 27-29): delta^2 = sum_j delta_j^2,
delta_0^2 = (1 - p_0) / (p_0 N) (independent samples) and, for a level sampled by chains,
delta_j^2 = (1 - p_j) / (p_j N) (1 + gamma_j) with gamma_j = 2 sum_{k=1}^{Ns-1}
(1 - k Nc / N) rho_j(k) and rho_j(k) the chains' autocorrelation of the indicator
1{margin <= b_j} at lag k (estimated over all chains). The correlation between levels is
neglected (as in Au & Beck); the interval is log-normal, p exp(+-1.96 sqrt(ln(1 +
delta^2))), since the estimator is a product and skewed at small p.

The rest of the budget: when a run reaches the failure level before the budget ends and
its relative CI misses the target, further independent runs are made while a whole run
still fits the budget; the answer is their mean, with CoV^2 = sum_i delta_i^2 p_i^2 /
(sum_i p_i)^2 (independent runs), or the runs' own spread where that is larger (it
holds the correlation between levels too; then the interval takes Student's t quantile
with m - 1 degrees of freedom). A run the budget ends before its failure level
still gives an estimate when its last level holds failures: p0^j x (failures / N) (an
estimate that stopped short of the target); without any failure it gives no estimate.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.risk.estimators import CONFIDENCE, Estimate, z_value

FloatArray = npt.NDArray[np.float64]

#: Conditional probability of a level.
P0 = 0.1
#: The most levels of one run.
MAX_LEVELS = 40
#: A run gives up when the level threshold has not moved for this many levels.
STALL_LEVELS = 3
#: Standard deviation of the component-wise Metropolis proposal (standard units).
SPREAD = 1.0

Evaluate = Callable[[FloatArray, str], pd.DataFrame]


@dataclass
class SubsetRun:
    """One subset simulation run.

    Attributes:
        probability: the estimate p (nan when no level held a failure).
        cov: its coefficient of variation (Au & Beck).
        thresholds: b_j per level. conditional: p_j per level. gammas: gamma_j per level.
        n_simulations: simulations of this run (the reused initial level not counted).
        last: the rows of the last level (its failures: samples of f(. | F)).
        reached: the last threshold is the failure threshold (<= 0).
        stalled: the thresholds stopped moving.
    """

    probability: float
    cov: float
    thresholds: list[float] = field(default_factory=list)
    conditional: list[float] = field(default_factory=list)
    gammas: list[float] = field(default_factory=list)
    n_simulations: int = 0
    last: pd.DataFrame = field(default_factory=pd.DataFrame)
    reached: bool = False
    stalled: bool = False


def chain_gamma(indicator: npt.ArrayLike, p: float) -> float:
    """gamma_j of Au & Beck (2001, eq. 29) from the chains' indicators [Nc, Ns].

    R(k) = (1 / (N - k Nc)) sum_chains sum_{l < Ns - k} I_l I_{l+k} - p^2,
    rho(k) = R(k) / R(0) with R(0) = p (1 - p), gamma = 2 sum_{k=1}^{Ns-1} (1 - k Nc / N)
    rho(k), N = Nc Ns.
    """
    ind = np.asarray(indicator, dtype=np.float64)
    nc, ns = ind.shape
    n = nc * ns
    r0 = p * (1.0 - p)
    if r0 <= 0 or ns < 2:
        return 0.0
    gamma = 0.0
    for k in range(1, ns):
        rk = float(np.sum(ind[:, : ns - k] * ind[:, k:])) / (n - k * nc) - p * p
        gamma += 2.0 * (1.0 - k * nc / n) * rk / r0
    return gamma


def _level_threshold(margin: FloatArray, nc: int) -> float:
    """The nc-th smallest margin (the p0-quantile of the level)."""
    return float(np.partition(margin, nc - 1)[nc - 1])


def one_run(
    evaluate: Evaluate,
    dim: int,
    *,
    level_size: int,
    budget: int,
    rng: np.random.Generator,
    prefix: str = "ss",
    initial: tuple[FloatArray, pd.DataFrame] | None = None,
) -> SubsetRun:
    """One run of subset simulation (module docstring).

    Args:
        evaluate: simulates u [N, d] under a stage label; rows with 'margin', 'failure'.
        dim: d. level_size: N samples per level (N p0 chains of 1 / p0 states).
        budget: most simulations of this run. rng: the random stream.
        prefix: stage labels '<prefix>-<level>'.
        initial: (u [N, d], rows) of level 0 already simulated from the variation (a
            Monte Carlo pilot): reused, not counted in the budget.
    """
    nc = max(1, int(round(level_size * P0)))
    ns = max(2, int(round(1.0 / P0)))
    n = nc * ns
    if initial is not None:
        u, rows = initial
        u = np.asarray(u, dtype=np.float64)
        rng.standard_normal(u.shape)  # the stream moves on as if it had drawn them
        used = 0
    else:
        u = rng.standard_normal((n, dim))
        rows = evaluate(u, f"{prefix}-0")
        used = n
    margin = rows["margin"].to_numpy(np.float64)
    n = len(u)
    run = SubsetRun(math.nan, math.nan, n_simulations=used, last=rows)
    log_p = 0.0
    var = 0.0
    for level in range(MAX_LEVELS):
        fails = int(np.sum(margin < 0))
        b = _level_threshold(margin, nc)
        if b < 0 or fails >= nc:  # the failure level: the last factor is the failure share
            p_last = fails / n
            gamma = run.gammas[-1] if level and run.gammas else 0.0
            run.conditional.append(p_last)
            run.thresholds.append(0.0)
            var += (1 - p_last) / (p_last * n) * (1 + gamma)
            run.probability = math.exp(log_p) * p_last
            run.cov = math.sqrt(var)
            run.reached = True
            return run
        run.thresholds.append(b)
        if (
            len(run.thresholds) > STALL_LEVELS
            and run.thresholds[-1] >= run.thresholds[-1 - STALL_LEVELS]
        ):
            run.stalled = True
        cost = n - nc
        if run.stalled or run.n_simulations + cost > budget:
            # stop short: the failure share of this level is still an estimate
            if fails:
                p_last = fails / n
                gamma = run.gammas[-1] if level and run.gammas else 0.0
                var += (1 - p_last) / (p_last * n) * (1 + gamma)
                run.probability = math.exp(log_p) * p_last
                run.cov = math.sqrt(var)
                run.conditional.append(p_last)
            return run
        # level j's share p_j = nc / n at threshold b (ties kept out: strictly the seeds)
        p_j = nc / n
        gamma = run.gammas[-1] if level and run.gammas else 0.0
        var += (1 - p_j) / (p_j * n) * (1 + gamma)
        log_p += math.log(p_j)
        run.conditional.append(p_j)
        seeds = np.argsort(margin, kind="stable")[:nc]
        state = u[seeds].copy()
        state_m = margin[seeds].copy()
        chain_u = [state.copy()]
        chain_m = [state_m.copy()]
        chain_rows = [rows.iloc[seeds].reset_index(drop=True)]
        for _step in range(1, ns):
            cand = state + SPREAD * rng.standard_normal(state.shape)
            ratio = np.exp(-0.5 * (cand * cand - state * state))
            keep = rng.random(state.shape) < np.minimum(1.0, ratio)
            cand = np.where(keep, cand, state)
            moved = np.any(keep, axis=1)
            new_rows = evaluate(cand, f"{prefix}-{level + 1}")
            run.n_simulations += len(cand)
            cm = new_rows["margin"].to_numpy(np.float64)
            ok = moved & (cm <= b)
            state = np.where(ok[:, None], cand, state)
            state_m = np.where(ok, cm, state_m)
            both = pd.concat([chain_rows[-1], new_rows.reset_index(drop=True)],
                             ignore_index=True)  # fmt: skip
            pick = np.where(ok, nc + np.arange(nc), np.arange(nc))
            merged = both.iloc[pick].reset_index(drop=True)
            chain_u.append(state.copy())
            chain_m.append(state_m.copy())
            chain_rows.append(merged)
        # samples in chain order: chain i's states i, i + nc, ...
        u = np.concatenate(chain_u)
        margin = np.concatenate(chain_m)
        rows = pd.concat(chain_rows, ignore_index=True)
        run.last = rows
        # gamma of the next conditional probability from these chains: evaluated at the
        # next threshold (or the failure threshold) once it is known
        nxt_fail = int(np.sum(margin < 0))
        b_next = _level_threshold(margin, nc)
        thr = 0.0 if (b_next < 0 or nxt_fail >= nc) else b_next
        ind = (margin <= thr) if thr > 0 else (margin < 0)
        p_next = float(ind.mean())
        run.gammas.append(chain_gamma(ind.reshape(ns, nc).T, p_next))
    return run


def combine(runs: list[SubsetRun]) -> tuple[float, float, float]:
    """(mean p, its CoV, degrees of freedom) of independent runs with estimates.

    CoV^2 = max(sum_i delta_i^2 p_i^2, sum_i (p_i - p)^2 m / (m - 1)) / (sum_i p_i)^2:
    the Au & Beck coefficients of the runs, or, where larger, the runs' own spread
    (which also holds the correlation between levels that Au & Beck neglect); the
    degrees of freedom are m - 1 where the spread is used (a Student t interval), else
    infinite.
    """
    ok = [r for r in runs if r.probability > 0 and math.isfinite(r.cov)]
    if not ok:
        return math.nan, math.nan, math.inf
    m = len(ok)
    ps = np.array([r.probability for r in ok])
    tot = float(ps.sum())
    var = sum((r.cov * r.probability) ** 2 for r in ok)
    df = math.inf
    if m >= 2:
        spread = float(np.sum((ps - ps.mean()) ** 2)) * m / (m - 1)
        if spread > var:
            var, df = spread, float(m - 1)
    return tot / m, math.sqrt(var) / tot, df


def lognormal_interval(p: float, cov: float, df: float = math.inf) -> tuple[float, float]:
    """p exp(+-q sqrt(ln(1 + cov^2))): the 95 % interval of a log-normal estimate, q the
    normal quantile (1.96) or Student's t quantile with ``df`` degrees of freedom."""
    s = math.sqrt(math.log1p(cov * cov))
    if math.isfinite(df):
        from scipy.stats import t

        q = float(t.ppf(0.5 + CONFIDENCE / 2.0, df))
    else:
        q = z_value()
    return p * math.exp(-q * s), p * math.exp(q * s)


def subset_estimate(
    evaluate: Evaluate,
    dim: int,
    *,
    level_size: int,
    budget: int,
    target_rel_ci: float,
    seed: int,
    initial: tuple[FloatArray, pd.DataFrame] | None = None,
) -> tuple[Estimate, list[SubsetRun], int]:
    """Independent runs until the target relative CI or the budget (module docstring).

    Returns:
        (the estimate, the runs, simulations spent). The estimate is a bound-less 'no
        estimate' (value nan, bound True, hi nan) when no run held a failure.
    """
    rng = np.random.default_rng(seed)
    runs: list[SubsetRun] = []
    used = 0
    while True:
        left = budget - used
        # a fresh run also simulates its level 0 (the first may have reused a pilot's)
        cost = (
            runs[-1].n_simulations + (level_size if len(runs) == 1 and initial else 0)
            if runs
            else 0
        )
        if runs and (not runs[-1].reached or cost > left):
            break
        r = one_run(evaluate, dim, level_size=level_size, budget=left, rng=rng,
                    prefix=f"ss{len(runs)}" if runs else "ss",
                    initial=initial if not runs else None)  # fmt: skip
        runs.append(r)
        used += r.n_simulations
        p, cov, df = combine(runs)
        if p > 0 and 0.5 * np.diff(lognormal_interval(p, cov, df))[0] / p <= target_rel_ci:
            break
        if not r.reached:
            break
    p, cov, df = combine(runs)
    notes = [
        "interval: log-normal with the Au & Beck (2001) coefficient of variation (the "
        "Markov chains' correlation), or the independent runs' spread where larger"
    ]
    if not p > 0:
        est = Estimate(math.nan, 0.0, math.nan, used, "subset-simulation", 0, bound=True,
                       reliable=False, notes=tuple(notes))  # fmt: skip
        return est, runs, used
    lo, hi = lognormal_interval(p, cov, df)
    reached = all(r.reached for r in runs)
    stalled = any(r.stalled for r in runs)
    fails = sum(int(r.last["failure"].sum()) for r in runs if len(r.last))
    diag: dict[str, float] = {"cov": cov, "runs": float(len(runs)), "dof": df,
                              "levels": float(np.mean([len(r.thresholds) for r in runs]))}  # fmt: skip
    est = Estimate(p, lo, hi, used, "subset-simulation", fails, reliable=reached and not stalled,
                   diagnostics=diag, notes=tuple(notes))  # fmt: skip
    if stalled:
        est = est.with_note("unreliable: the Markov chains stalled (the level stopped moving)")
    elif not reached:
        est = est.with_note(
            "unreliable: the budget ended before the failure level; the estimate is the "
            "last level's failure share times the levels before it"
        )
    return est, runs, used


def as_stages(runs: list[SubsetRun]) -> list[dict[str, Any]]:
    """JSON-ready per run and level: threshold, conditional probability, gamma."""
    out = []
    for i, r in enumerate(runs):
        for j, b in enumerate(r.thresholds):
            out.append({
                "run": i, "stage": j, "threshold": b,
                "conditional_probability": r.conditional[j] if j < len(r.conditional) else None,
                "gamma": r.gammas[j - 1] if 0 < j <= len(r.gammas) else 0.0,
            })  # fmt: skip
    return out
