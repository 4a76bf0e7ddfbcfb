"""Estimate one planner's risk in one encounter: the method, the loop, the figures.

``method``:

- ``mc``: plain Monte Carlo in growing batches (the first ``pilot`` samples, then as
  many as the current estimate says the target needs, :func:`vei.risk.estimators.
  needed_samples`) until P(collision)'s relative CI reaches the target or the budget ends;
  every planner draws the same stream of samples (seeded), so planners share their first
  samples (common random numbers).
- ``ce`` / ``subset``: the rare-event estimators of :mod:`vei.risk.rare`.
- ``auto`` (default): a Monte Carlo pilot; if it saw at least ``MIN_PILOT_FAILURES``
  collisions and plain Monte Carlo can reach the target within the budget, Monte Carlo
  goes on; otherwise cross-entropy importance sampling takes the remaining budget. When
  that does not reach a failure region (the budget ends, or its level stalls: there may
  be none), the rest of the budget continues the pilot's plain Monte Carlo, and the
  honest answer is its estimate or its Clopper-Pearson upper bound.

The figures of a planner (:class:`PlannerRisk`): P(collision), P(injury-relevant
collision), the expected injury risk (the mean of the rider's injury risk over the
variation, 0 without collision: probability x injury risk), P(seen too late) (runs no
planner could have reacted in, excluded from the others) and the share of collisions
without an approach (their injury risk is unknown: the expected injury risk is a lower
bound by that share), each with its 95 % interval, and the simulations spent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from vei.errors import ConfigError
from vei.risk import estimators as est
from vei.risk.estimators import Estimate
from vei.risk.weighted import share_of as _ratio

METHODS: tuple[str, ...] = ("auto", "mc", "ce", "subset")
#: Fewest collisions in the pilot for auto to trust plain Monte Carlo.
MIN_PILOT_FAILURES = 20
#: Smallest budget that can say anything: a pilot whose zero-failure bound is < 5 %.
MIN_BUDGET = 100
#: Default pilot / stage size.
STAGE_SIZE = 2000


@dataclass
class PlannerRisk:
    """One planner's figures in one encounter (module docstring).

    Attributes:
        policy: the planner. method: the estimator that gave the figures ('mc', 'ce',
            'subset'). n_simulations: every simulation spent (pilot and adaptive stages).
        p_collision, p_injury_relevant, expected_injury, p_seen_too_late,
            share_no_approach: the estimates.
        rows: the final sample the figures rest on (``weight`` = importance weight).
        rare: the rare-event run (None for Monte Carlo).
        proposal: the sampling density of ``rows`` as (mean [d], std [d]), or a normal
            mixture [(mean, std, share), ...] (cross-entropy stages that never reached
            the region); None = the variation itself (plain Monte Carlo).
        target_reached: P(collision)'s relative CI reached the target.
        notes: what could not be reached, and why.
        p_collision_recorded: P(collision on the rider's recorded behaviour) from the same
            sample. share_synthetic: the share of P(collision) on the rider's synthetic
            run-in / run-out.
    """

    policy: str
    method: str
    n_simulations: int
    p_collision: Estimate
    p_injury_relevant: Estimate
    expected_injury: Estimate
    p_seen_too_late: Estimate
    share_no_approach: Estimate
    rows: pd.DataFrame
    rare: Any = None
    proposal: Any = None
    target_reached: bool = False
    notes: list[str] = field(default_factory=list)
    p_collision_recorded: Estimate | None = None
    share_synthetic: Estimate | None = None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready summary."""
        out: dict[str, Any] = {
            "policy": self.policy,
            "method": self.method,
            "n_simulations": self.n_simulations,
            "target_reached": self.target_reached,
            "p_collision": self.p_collision.as_dict(),
            "p_injury_relevant_collision": self.p_injury_relevant.as_dict(),
            "expected_injury_risk": self.expected_injury.as_dict(),
            "p_seen_too_late": self.p_seen_too_late.as_dict(),
            "share_of_collisions_without_approach": self.share_no_approach.as_dict(),
            "notes": list(self.notes),
        }
        if self.p_collision_recorded is not None:
            out["p_collision_recorded"] = self.p_collision_recorded.as_dict()
        if self.share_synthetic is not None:
            out["share_of_p_collision_synthetic"] = self.share_synthetic.as_dict()
        if self.rare is not None:
            out["adaptive_stages"] = self.rare.stages
            if self.rare.proposal:
                out["proposal"] = self.rare.proposal
        return out


def check_budget(budget: int, target_rel_ci: float) -> None:
    """Refuse a budget too small to say anything and an impossible target.

    Raises:
        ConfigError: budget < MIN_BUDGET, or target_rel_ci not in (0, 1].
    """
    if isinstance(budget, bool) or not isinstance(budget, int) or budget < MIN_BUDGET:
        raise ConfigError(
            f"--budget {budget!r} is too small to say anything: with fewer than {MIN_BUDGET} "
            "simulations even a collision-free result bounds P(collision) only above 3.6 % "
            f"(give at least {MIN_BUDGET})"
        )
    if not (isinstance(target_rel_ci, int | float) and 0 < target_rel_ci <= 1):
        raise ConfigError(
            f"--target-rel-ci must lie in (0, 1] (a half-width relative to the estimate, 0.1 "
            f"= +-10 %), got {target_rel_ci!r}"
        )


def figures(
    rows: pd.DataFrame, weighted: bool, pilot: pd.DataFrame | None = None
) -> dict[str, Estimate]:
    """The estimates of a final sample (weighted: importance sampling): P(collision),
    P(collision on recorded behaviour), P(injury-relevant collision), the expected injury
    risk, P(seen too late), the share of collisions without approach and the share of
    P(collision) on the rider's synthetic run-in / run-out. An importance sample that
    holds no sample of a secondary event gives an honest upper bound
    (:mod:`vei.risk.weighted`; ``pilot``: a Monte Carlo sample of the variation for events
    outside the failure event)."""
    from vei.risk import weighted as wt

    fail = rows["failure"].to_numpy(bool)
    late = rows["seen_too_late"].to_numpy(bool)
    rel = rows["injury_relevant"].to_numpy(bool)
    inj = rows["injury"].to_numpy(np.float64)
    noap = rows["no_approach"].to_numpy(bool)
    rec = wt.recorded_column(rows)
    if weighted:
        w = rows["weight"].to_numpy(np.float64)
        pc = est.importance_sampling(fail, w, fail)
        pilot_late = None
        if pilot is not None and len(pilot):
            pilot_late = est.mc_probability(pilot["seen_too_late"].to_numpy(bool))
        out = {
            "p_collision": pc,
            "p_collision_recorded": wt.weighted_figure(rec, w, fail, pc, part_of_failure=True),
            "p_injury_relevant": wt.weighted_figure(rel, w, fail, pc, part_of_failure=True),
            "expected_injury": wt.weighted_figure(inj, w, fail, pc, part_of_failure=True),
            "p_seen_too_late": wt.weighted_figure(
                late, w, late, pc, part_of_failure=False, pilot=pilot_late
            ),  # fmt: skip
        }
        share = _ratio(noap, fail, w)
    else:
        out = {
            "p_collision": est.mc_probability(fail),
            "p_collision_recorded": est.mc_probability(rec),
            "p_injury_relevant": est.mc_probability(rel),
            "expected_injury": est.mc_mean(inj, fail),
            "p_seen_too_late": est.mc_probability(late),
        }
        share = _ratio(noap, fail, None)
    out["share_no_approach"] = share
    out["share_synthetic"] = wt.synthetic_share(rows, weighted)
    return out


def _draw(rng: np.random.Generator, n: int, d: int) -> np.ndarray:
    return rng.standard_normal((n, d))


def monte_carlo(
    problem: Any, policy: str, *, budget: int, target_rel_ci: float, seed: int,
    pilot: int = STAGE_SIZE, already: pd.DataFrame | None = None,
) -> PlannerRisk:  # fmt: skip
    """Plain Monte Carlo until the target relative CI or the budget (module docstring).

    ``already``: rows of this planner on the first samples of the same stream (a pilot),
    continued rather than re-simulated.
    """
    d = problem.space.dimension
    rng = np.random.default_rng(seed)
    frames = [] if already is None or already.empty else [already]
    n = 0 if already is None else len(already)
    if n:
        _draw(rng, n, d)  # skip the samples the pilot used: the same stream
    step = max(1, min(pilot, budget - n))
    done = bool(n) and est.mc_probability(already["failure"].to_numpy(bool)).rel_ci <= target_rel_ci
    while n < budget and not done:
        u = _draw(rng, step, d)
        frames.append(problem.evaluate(u, policy, stage="mc"))
        n += step
        rows = pd.concat(frames, ignore_index=True)
        p = est.mc_probability(rows["failure"].to_numpy(bool))
        if p.rel_ci <= target_rel_ci:
            break
        guess = p.value if not p.bound else p.hi / 3.0
        want = est.needed_samples(guess, target_rel_ci)
        step = int(min(budget - n, max(want - n, step // 2, 100), 8 * n))
        if step <= 0:
            break
    rows = pd.concat(frames, ignore_index=True)
    return _result(policy, "mc", rows, n, target_rel_ci, weighted=False)


def _result(
    policy: str, method: str, rows: pd.DataFrame, n_sim: int, target: float, *,
    weighted: bool, rare: Any = None, proposal: Any = None, notes: list[str] | None = None,
    pilot: pd.DataFrame | None = None,
) -> PlannerRisk:  # fmt: skip
    f = figures(rows, weighted, pilot)
    notes = list(notes or [])
    reached = f["p_collision"].rel_ci <= target
    if not reached and not f["p_collision"].bound:
        notes.append(
            f"target relative CI {target:g} not reached within the budget "
            f"(reached {f['p_collision'].rel_ci:.3g} with {n_sim:,} simulations)"
        )
    if f["p_collision"].bound:
        notes.append(f"no collision in {n_sim:,} simulations: P(collision) is only bounded above")
    return PlannerRisk(
        policy, method, n_sim, f["p_collision"], f["p_injury_relevant"], f["expected_injury"],
        f["p_seen_too_late"], f["share_no_approach"], rows, rare, proposal, reached, notes,
        f["p_collision_recorded"], f["share_synthetic"],
    )  # fmt: skip


def assess_planner(
    problem: Any,
    policy: str,
    *,
    method: str = "auto",
    budget: int = 50_000,
    target_rel_ci: float = 0.1,
    seed: int = 0,
    stage_size: int = STAGE_SIZE,
) -> PlannerRisk:
    """One planner's figures with the chosen method (module docstring).

    Args:
        problem: a :class:`vei.risk.problem.RiskProblem` (or anything with ``evaluate``
            and ``space``, e.g. :class:`vei.risk.analytic.IntervalProblem`).
        policy: the planner. method: 'auto', 'mc', 'ce' or 'subset'.
        budget: most simulations. target_rel_ci: P(collision)'s relative CI to reach.
        seed: the sampling seed. stage_size: pilot / stage size.
    Raises:
        ConfigError: unknown method, too small a budget, impossible target.
    """
    from vei.risk import rare

    if method not in METHODS:
        raise ConfigError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    check_budget(budget, target_rel_ci)
    stage = max(MIN_BUDGET, min(stage_size, budget // 4 if method != "mc" else stage_size))
    d = problem.space.dimension
    if method == "mc":
        return monte_carlo(problem, policy, budget=budget, target_rel_ci=target_rel_ci,
                           seed=seed, pilot=stage)  # fmt: skip
    # the Monte Carlo pilot: the first samples of the planner's stream; auto decides on
    # it, and every rare-event method reuses it as its first stage (not re-simulated)
    pilot_u = _draw(np.random.default_rng(seed), stage, d)
    pilot_rows = problem.evaluate(pilot_u, policy, stage="mc")
    if method == "auto":
        k = int(pilot_rows["failure"].sum())
        p = k / len(pilot_rows)
        if k >= MIN_PILOT_FAILURES and est.needed_samples(p, target_rel_ci) <= budget:
            return monte_carlo(problem, policy, budget=budget, target_rel_ci=target_rel_ci,
                               seed=seed, pilot=stage, already=pilot_rows)  # fmt: skip
    used = len(pilot_rows)

    def evaluate(u: np.ndarray, label: str) -> pd.DataFrame:
        return problem.evaluate(u, policy, stage=label)

    if method == "subset":
        r = rare.subset_simulation(evaluate, d, level_size=stage, budget=budget - used,
                                   seed=seed, target_rel_ci=target_rel_ci,
                                   initial=(pilot_u, pilot_rows))  # fmt: skip
    else:
        r = rare.cross_entropy(evaluate, d, stage_size=stage, budget=budget - used,
                               target_rel_ci=target_rel_ci, seed=seed,
                               initial=(pilot_u, pilot_rows))  # fmt: skip
    n_sim = used + r.n_simulations
    if r.method == "ce" and r.mixture is not None:
        # the stages held failures but never reached the region: the mixture estimate
        return _result(policy, "ce (mixture of its stages)", r.rows, n_sim, target_rel_ci,
                       weighted=True, rare=r, proposal=r.mixture, notes=list(r.notes),
                       pilot=pilot_rows)  # fmt: skip
    if not r.reached:
        # no failure in any stage: the rest of the budget as plain Monte Carlo (the
        # pilot's stream, continued): the tightest honest answer, an estimate or a bound
        left = budget - n_sim
        mc = monte_carlo(problem, policy, budget=len(pilot_rows) + max(left, 0),
                         target_rel_ci=target_rel_ci, seed=seed, pilot=stage,
                         already=pilot_rows)  # fmt: skip
        mc.n_simulations = n_sim + (len(mc.rows) - len(pilot_rows))
        mc.notes = list(r.notes) + [n.replace(f"in {len(mc.rows):,} simulations",
                                              f"in {len(mc.rows):,} Monte Carlo simulations")
                                    for n in mc.notes]  # fmt: skip
        mc.rare = r
        mc.method = f"mc ({r.method} did not reach a failure region)"
        return mc
    if r.method == "ce":
        mu, sd = (np.asarray(r.proposal["mean"]), np.asarray(r.proposal["std"]))
        return _result(policy, "ce", r.rows, n_sim, target_rel_ci, weighted=True, rare=r,
                       proposal=(mu, sd), notes=list(r.notes), pilot=pilot_rows)  # fmt: skip
    return _subset_result(policy, r, n_sim, target_rel_ci)


def _subset_result(policy: str, r: Any, n_sim: int, target: float) -> PlannerRisk:
    """Subset simulation's figures: P(F) (:mod:`vei.risk.subset`); the other outcomes as
    P(F) times their share among the failing samples of the last levels (approximately
    f(. | F)); P(seen too late) from the Monte Carlo pilot (level 0)."""
    from vei.risk import weighted as wt

    p = r.probability
    rows = r.rows
    fail = rows["failure"].to_numpy(bool) if len(rows) else np.zeros(0, bool)

    def scaled(part: np.ndarray, kind: str) -> Estimate:
        share = _ratio(part, fail, None)
        if share.bound:
            return share
        v = p.value * share.value
        return Estimate(v, p.lo * share.lo, p.hi * share.hi, n_sim, "subset-simulation",
                        reliable=p.reliable, notes=(f"P(collision) x share of {kind}",))  # fmt: skip

    rel = scaled(rows["injury_relevant"].to_numpy(bool) & fail, "injury-relevant collisions")
    inj_share = float(rows.loc[fail, "injury"].mean()) if fail.any() else math.nan
    inj = Estimate(p.value * inj_share, p.lo * inj_share, p.hi * inj_share, n_sim,
                   "subset-simulation", reliable=p.reliable,
                   notes=("P(collision) x mean injury risk of the failing samples",))  # fmt: skip
    first = r.first if r.first is not None else pd.DataFrame()
    late = est.mc_probability(first["seen_too_late"].to_numpy(bool) if len(first) else [])
    late = late.with_note("from the Monte Carlo pilot (level 0 of subset simulation)")
    noap = _ratio(rows["no_approach"].to_numpy(bool) & fail, fail, None)
    rec = scaled(wt.recorded_column(rows), "collisions on recorded behaviour")
    syn = wt.synthetic_share(rows, False) if len(rows) else _ratio(fail, fail, None)
    res = PlannerRisk(policy, "subset", n_sim, p, rel, inj, late, noap, rows, r, None,
                      p.rel_ci <= target, list(r.notes), rec, syn)  # fmt: skip
    if not res.target_reached:
        res.notes.append(f"target relative CI {target:g} not reached (reached {p.rel_ci:.3g})")
    return res
