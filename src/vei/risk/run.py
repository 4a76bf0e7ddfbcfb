"""``vei risk``: one encounter's risk under a variation model, per planner, end to end.

:func:`assess_risk` prepares the scenario (:class:`vei.risk.problem.RiskProblem`),
estimates every planner's figures (:func:`vei.risk.assess.assess_planner`), compares
the planners pairwise on common random numbers (:mod:`vei.risk.compare`), describes the
failure modes (:mod:`vei.risk.modes`) and the sensitivity (:mod:`vei.risk.sensitivity`),
and writes the output folder (:mod:`vei.risk.output`).
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from vei.risk.assess import PlannerRisk, assess_planner, check_budget
from vei.risk.compare import Comparison, compare
from vei.risk.modes import failure_kinds, failure_regions
from vei.risk.problem import RiskProblem
from vei.risk.sensitivity import SOBOL_N, importance_factors, sobol_indices
from vei.risk.variation import VariationModel

CONFIG_CHOICES: tuple[str, ...] = ("failures", "all", "none")


@dataclass
class RiskResult:
    """Everything ``vei risk`` found for one encounter.

    Attributes:
        problem: the prepared problem (scenario, variation, every simulated sample).
        planners: per planner, its figures. comparisons: every pair, A - B.
        modes: per planner {'kinds': [...], 'regions': [...]}.
        sobol: the Sobol indices (of the first planner; {} when not computed).
        importance: per planner with a cross-entropy run, its importance factors.
        timings: seconds per phase. out_dir: where it was written (None: not written).
    """

    problem: RiskProblem
    planners: list[PlannerRisk]
    comparisons: list[Comparison]
    modes: dict[str, dict[str, Any]]
    sobol: dict[str, Any] = field(default_factory=dict)
    importance: dict[str, dict[str, float]] = field(default_factory=dict)
    timings: dict[str, float] = field(default_factory=dict)
    out_dir: Path | None = None

    @property
    def n_simulations(self) -> int:
        """Every simulation run (estimates, pairing, Sobol)."""
        return sum(len(f) for f in self.problem.log)


def region_columns(problem: Any) -> list[str]:
    """The physical columns the failure regions split on: the varied quantities and the
    population rider's parameters (k_des instead of tau)."""
    names = [n for n, _ in problem.space.distributions]
    if problem.space.rider_profile is not None:
        names += ["rider.v0_mps", "rider.k_des_nspm", "rider.lookahead_m",
                  "rider.max_speed_mps", "rider.max_accel_mps2"]  # fmt: skip
    return names


def assess_risk(
    scenario_dir: str | Path,
    model: VariationModel,
    *,
    policies: Sequence[str] = (),
    method: str = "auto",
    budget: int = 50_000,
    target_rel_ci: float = 0.1,
    sobol_n: int = SOBOL_N,
    out_dir: str | Path | None = None,
    configs: str = "failures",
    progress: Callable[[str], None] | None = None,
) -> RiskResult:
    """One encounter's risk (module docstring).

    Args:
        scenario_dir: a scenario folder (``vei reconstruct``). model: the variation.
        policies: planners to assess ('none', 'paper-cap', 'aeb', 'idm', a user policy
            'path/file.py:Class'); () = the base configuration's controller.
        method: 'auto', 'mc', 'ce' or 'subset'. budget: most simulations per planner
            (the pairing and the Sobol sample come on top). target_rel_ci: relative
            half-width of P(collision)'s interval to reach (0.1 = +-10 %).
        sobol_n: Saltelli base sample size of the Sobol indices (0: none).
        out_dir: where to write (None: nothing written).
        configs: which samples get a run configuration: 'failures' (every collision and
            the first 20 others), 'all', 'none'.
        progress: callback for one-line progress messages.
    Raises:
        InputError / ConfigError: bad scenario, policy, budget, target or distribution.
    """
    from vei.errors import ConfigError

    check_budget(budget, target_rel_ci)
    if configs not in CONFIG_CHOICES:
        raise ConfigError(f"--configs must be one of {', '.join(CONFIG_CHOICES)}, got {configs!r}")
    if isinstance(sobol_n, bool) or not isinstance(sobol_n, int) or sobol_n < 0:
        raise ConfigError(f"--sobol must be an integer >= 0, got {sobol_n!r}")
    say = progress or (lambda _msg: None)
    t0 = time.perf_counter()
    problem = RiskProblem.prepare(scenario_dir, model, policies)
    problem.progress = progress
    timings = {"prepare": time.perf_counter() - t0}
    planners = []
    for pol in problem.policy_names:
        t = time.perf_counter()
        say(f"{pol}: estimating ({method}, budget {budget:,}, target +-{target_rel_ci:g})")
        res = assess_planner(problem, pol, method=method, budget=budget,
                             target_rel_ci=target_rel_ci, seed=model.seed)  # fmt: skip
        planners.append(res)
        timings[f"estimate {pol}"] = time.perf_counter() - t
        say(f"{pol}: P(collision) {res.p_collision.text()} ({res.method}, "
            f"{res.n_simulations:,} simulations)")  # fmt: skip
    t = time.perf_counter()
    comparisons = [
        compare(problem, a, b, model.seed) for a, b in itertools.combinations(planners, 2)
    ]
    timings["compare"] = time.perf_counter() - t
    names = region_columns(problem)
    modes = {
        p.policy: {
            "kinds": failure_kinds(p.rows, weighted=p.proposal is not None),
            "regions": [
                r.as_dict() for r in failure_regions(p.rows, names, p.proposal is not None)
            ],
        }
        for p in planners
    }
    importance = {
        p.policy: importance_factors(
            problem.space.names,
            p.proposal[-1][0] if isinstance(p.proposal, list) else p.proposal[0],
        )
        for p in planners
        if p.proposal is not None
    }
    sobol: dict[str, Any] = {}
    if sobol_n:
        t = time.perf_counter()
        say(f"Sobol indices: {sobol_n * (problem.space.dimension + 2):,} simulations")
        sobol = sobol_indices(problem, planners[0].policy, n=sobol_n, seed=model.seed)
        sobol["policy"] = planners[0].policy
        timings["sobol"] = time.perf_counter() - t
    result = RiskResult(problem, planners, comparisons, modes, sobol, importance, timings)
    if out_dir is not None:
        from vei.risk.output import write_risk

        t = time.perf_counter()
        write_risk(result, Path(out_dir), configs=configs)
        timings["write"] = time.perf_counter() - t
        result.out_dir = Path(out_dir)
    timings["total"] = time.perf_counter() - t0
    return result
