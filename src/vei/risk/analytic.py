"""A scripted risk problem with a known answer (for tests and benchmarks).

The "simulator" is a formula: the arrival offset ``x = F^-1(Phi(u_0))`` of a declared
distribution collides exactly when it falls in an interval ``[a, b]`` per planner, so
P(collision) = F(b) - F(a) is known in closed form; the other dimensions are noise the
estimators must not be fooled by. It has the interface of :class:`vei.risk.problem.
RiskProblem` that the estimators use (``evaluate``, ``space``, ``policy_names``,
``samples``), and evaluates 10^6 samples in well under a second.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.special import ndtri

from vei.config.distributions import Distribution

FloatArray = npt.NDArray[np.float64]


@dataclass
class _Space:
    names: tuple[str, ...]

    @property
    def dimension(self) -> int:
        return len(self.names)

    def normalised(self, u: npt.ArrayLike) -> FloatArray:
        from scipy.special import ndtr

        return ndtr(np.atleast_2d(np.asarray(u, dtype=np.float64)))


@dataclass
class IntervalProblem:
    """Collision iff the arrival offset lies in the planner's interval.

    Attributes:
        intervals: planner name -> (a, b), the colliding offsets [s].
        offset: the arrival offset's distribution (default N(0, 1)).
        dim: dimensions (the first is the offset, the others are ignored noise).
        impact_speed_mps: impact speed of every collision (injury risk from it with the
            default curve; injury-relevant when >= the threshold 20 km/h).
    """

    intervals: Mapping[str, tuple[float, float]]
    offset: Distribution = field(default_factory=lambda: Distribution("normal", mean=0.0, std=1.0))
    dim: int = 3
    impact_speed_mps: float = 8.0
    log: list[pd.DataFrame] = field(default_factory=list)

    def __post_init__(self) -> None:
        names = ("time_shift_s",) + tuple(f"noise_{i}" for i in range(1, self.dim))
        self.space = _Space(names)

    @property
    def policy_names(self) -> tuple[str, ...]:
        return tuple(self.intervals)

    def probability(self, policy: str | None = None) -> float:
        """The exact P(collision) of a planner."""
        a, b = self.intervals[policy or self.policy_names[0]]
        lo, hi = self.offset.cdf(np.array([a, b]))
        return float(hi - lo)

    @classmethod
    def with_probability(cls, p: float, dim: int = 3, centre: float = 2.0) -> IntervalProblem:
        """An interval starting at ``centre`` standard deviations of a N(0, 1) offset whose
        probability is exactly p (planner 'scripted')."""
        from scipy.special import ndtr

        a = float(centre)
        b = float(ndtri(ndtr(a) + p)) if ndtr(a) + p < 1 - 1e-15 else np.inf
        if not np.isfinite(b):  # far tail: compute through the upper tail
            b = float(-ndtri(ndtr(-a) - p))
        return cls({"scripted": (a, b)}, dim=dim)

    def evaluate(
        self, u: npt.ArrayLike, policy: str | None = None, *, stage: str = "mc",
        weights: npt.ArrayLike | None = None,
    ) -> pd.DataFrame:  # fmt: skip
        """Rows with u.* columns, the outcomes and the margin (failure: < 0)."""
        from vei.metrics.severity import injury_risk_of_speed

        u = np.atleast_2d(np.asarray(u, dtype=np.float64))
        pol = policy or self.policy_names[0]
        a, b = self.intervals[pol]
        x = self.offset.from_standard(u[:, 0])
        fail = (x >= a) & (x <= b)
        margin = np.where(fail, -1.0, np.maximum(a - x, x - b))
        risk = float(injury_risk_of_speed(np.array([self.impact_speed_mps]))[0])
        rows = pd.DataFrame({f"u.{n}": u[:, j] for j, n in enumerate(self.space.names)})
        rows["time_shift_s"] = x
        rows["failure"] = fail
        rows["collision"] = fail
        rows["injury_relevant"] = fail & (self.impact_speed_mps >= 20 / 3.6)
        rows["injury"] = np.where(fail, risk, 0.0)
        rows["no_approach"] = False
        rows["seen_too_late"] = False
        rows["impact_speed_mps"] = np.where(fail, self.impact_speed_mps, np.nan)
        rows["margin"] = margin
        rows["stage"] = stage
        rows["policy"] = pol
        rows["weight"] = 1.0 if weights is None else np.asarray(weights, dtype=np.float64)
        rows["variant_id"] = [f"{stage}-{len(self.log)}-{i}" for i in range(len(u))]
        self.log.append(rows)
        return rows

    def samples(self) -> pd.DataFrame:
        """Every evaluated sample so far."""
        return pd.concat(self.log, ignore_index=True) if self.log else pd.DataFrame()
