"""Is planner A safer than planner B? Paired differences on common random numbers.

Two planners are compared on the *same* samples of the variation (common random
numbers): every sample is simulated under both, and the difference of their outcomes
(collision, injury-relevant collision, injury risk) is averaged. Pairing removes the
variation both share from the comparison, so the interval is far narrower than that of
two independent estimates.

- Both planners estimated by plain Monte Carlo: they drew the same stream of samples;
  the shorter run is extended to the longer one's samples, and the difference of the
  collision indicators gets the Agresti-Min interval (:func:`vei.risk.estimators.
  paired_difference`).
- Otherwise (importance sampling for at least one): the final samples of every planner
  are pooled, each sample is simulated under every planner (those not yet simulated
  are), and weighted by the deterministic mixture ("balance heuristic", Veach & Guibas
  1995; Owen & Zhou 2000): ``w = phi(u) / sum_k (n_k / N) q_k(u)`` with q_k each
  planner's proposal (phi itself for a Monte Carlo planner). The paired weighted mean
  and its normal interval follow.

"A is safer than B" is said only where the 95 % interval of P_A - P_B excludes zero;
otherwise the verdict is "no significant difference".
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from vei.risk.assess import PlannerRisk
from vei.risk.estimators import Estimate, paired_difference


@dataclass(frozen=True)
class Comparison:
    """A - B on common samples.

    Attributes:
        a, b: the planners. n: paired samples. method: 'mc' or 'mixture-is'.
        collision, injury_relevant, injury: the paired differences (A - B).
        verdict: 'A safer', 'B safer' or 'no significant difference' (by collision).
        extra_simulations: simulations run only for the pairing.
    """

    a: str
    b: str
    n: int
    method: str
    collision: Estimate
    injury_relevant: Estimate
    injury: Estimate
    verdict: str
    extra_simulations: int

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {
            "a": self.a,
            "b": self.b,
            "n_paired": self.n,
            "method": self.method,
            "difference_p_collision": self.collision.as_dict(),
            "difference_p_injury_relevant": self.injury_relevant.as_dict(),
            "difference_expected_injury": self.injury.as_dict(),
            "verdict": self.verdict,
            "extra_simulations": self.extra_simulations,
        }

    def sentence(self) -> str:
        """One line that states the difference in the order it names the planners:
        '<safer> is safer than <other>: P_<safer> - P_<other> = -0.3 [...]', or no
        significant difference (A - B)."""
        d = self.collision
        first, second, sign = self.a, self.b, 1.0
        if self.verdict == "B safer":
            first, second, sign = self.b, self.a, -1.0
        lo, hi = sorted((sign * d.lo, sign * d.hi))
        rng = f"P({first}) - P({second}) = {sign * d.value:+.3g} [{lo:+.3g}, {hi:+.3g}]"
        if self.verdict in ("A safer", "B safer"):
            return f"{first} is safer than {second}: {rng} ({self.n:,} common samples)"
        return (
            f"{self.a} vs {self.b}: no significant difference ({rng}, the interval contains 0;"
            f" {self.n:,} common samples)"
        )


def _verdict(d: Estimate) -> str:
    if d.hi < 0:
        return "A safer"
    if d.lo > 0:
        return "B safer"
    return "no significant difference"


def _u(rows: pd.DataFrame) -> np.ndarray:
    return rows[[c for c in rows.columns if c.startswith("u.")]].to_numpy(np.float64)


def _log_q(u: np.ndarray, proposal: Any) -> np.ndarray:
    """log q(u) - log phi(u) [N] of a proposal: (mean, std), a normal mixture
    [(mean, std, share), ...], or None (the variation itself: 0)."""
    if proposal is None:
        return np.zeros(len(u))
    if isinstance(proposal, list):
        from vei.risk.rare import mixture_log_ratio

        return mixture_log_ratio(u, proposal)
    mu, sd = proposal
    z = (u - mu) / sd
    return np.sum(-0.5 * z * z - np.log(sd) + 0.5 * u * u, axis=1)


def compare(problem: Any, a: PlannerRisk, b: PlannerRisk, seed: int) -> Comparison:
    """Planner a vs planner b on common random numbers (module docstring)."""
    extra = 0
    if (
        a.proposal is None
        and b.proposal is None
        and a.method.startswith("mc")
        and b.method.startswith("mc")
    ):
        ra, rb = a.rows, b.rows
        n = max(len(ra), len(rb))
        if len(ra) < n:
            ra = pd.concat([ra, problem.evaluate(_u(rb)[len(ra) :], a.policy, stage="pair")],
                           ignore_index=True)  # fmt: skip
            extra += n - len(a.rows)
        if len(rb) < n:
            rb = pd.concat([rb, problem.evaluate(_u(ra)[len(rb) :], b.policy, stage="pair")],
                           ignore_index=True)  # fmt: skip
            extra += n - len(b.rows)
        col = paired_difference(ra["failure"], rb["failure"])
        rel = paired_difference(ra["injury_relevant"], rb["injury_relevant"])
        inj = paired_difference(ra["injury"], rb["injury"])
        return Comparison(a.policy, b.policy, n, "mc", col, rel, inj, _verdict(col), extra)
    # pooled final samples of both, every sample under both planners
    ua, ub = _u(a.rows), _u(b.rows)
    u = np.vstack([ua, ub])
    na, nb = len(ua), len(ub)
    log_terms = np.stack([_log_q(u, a.proposal) + np.log(na / (na + nb)),
                          _log_q(u, b.proposal) + np.log(nb / (na + nb))])  # fmt: skip
    w = np.exp(-np.logaddexp.reduce(log_terms, axis=0))
    rows_a = pd.concat([a.rows, problem.evaluate(ub, a.policy, stage="pair")], ignore_index=True)
    rows_b = pd.concat([problem.evaluate(ua, b.policy, stage="pair"), b.rows], ignore_index=True)
    extra = na + nb
    col = paired_difference(rows_a["failure"], rows_b["failure"], w)
    rel = paired_difference(rows_a["injury_relevant"], rows_b["injury_relevant"], w)
    inj = paired_difference(rows_a["injury"], rows_b["injury"], w)
    return Comparison(a.policy, b.policy, na + nb, "mixture-is", col, rel, inj, _verdict(col),
                      extra)  # fmt: skip
