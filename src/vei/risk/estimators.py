"""Estimates with 95 % confidence intervals and their diagnostics.

- A probability from plain Monte Carlo (k failures in n independent samples): the Wilson
  score interval (Wilson 1927; Agresti & Coull 1998 recommend it over the Wald interval
  for small k); with k = 0 no point estimate is given, only the Clopper-Pearson upper
  bound ``1 - (alpha/2)^(1/n)`` (about 3.7 / n at 95 %), never 0.
- A mean of a quantity in [0, 1] (the expected injury risk): the sample mean with a
  normal-approximation interval; with no failure at all, an upper bound.
- Importance sampling (weights w_i = f(u_i) / q(u_i)): the mean of w h, its standard
  error from the sample variance, a Wald interval; diagnostics: effective sample size
  ESS = (sum w)^2 / sum w^2 (Kong 1992), the ESS among the failures, the largest single
  weight's share of the estimate (weight degeneracy) and the coefficient of variation.
  :func:`is_reliable` says when these do not support the interval.
- A paired difference (two planners on the same samples, common random numbers): the
  mean of h_A - h_B with its paired standard error; for plain Monte Carlo the
  Agresti-Min interval (Agresti & Min 2005, Biometrics 61:515: add 1/2 to each cell of
  the 2x2 table of paired outcomes, then Wald), which keeps its coverage with few
  discordant pairs.

The relative CI of an estimate is its half-width over the estimate, ``(hi - lo) / (2 p)``
(the ``--target-rel-ci`` of ``vei risk``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Confidence level of every interval.
CONFIDENCE = 0.95
#: Reliability rules for importance sampling (docs/risk.md): at least this many
#: effective failure samples, and no single sample carrying more than this share.
MIN_FAILURE_ESS = 30.0
MAX_WEIGHT_SHARE = 0.2


def z_value(confidence: float = CONFIDENCE) -> float:
    """The two-sided normal quantile (1.96 at 95 %)."""
    from scipy.special import ndtri

    return float(ndtri(0.5 + confidence / 2.0))


@dataclass(frozen=True)
class Estimate:
    """One estimate with its 95 % confidence interval.

    Attributes:
        value: the point estimate (nan when only a bound is known).
        lo, hi: the interval (lo = 0 and hi = the upper bound when ``bound``).
        n: simulations it rests on. failures: the failures among them (-1 when not a count).
        method: 'wilson', 'clopper-pearson-bound', 'normal', 'importance-sampling',
            'subset-simulation', 'agresti-min', 'paired-normal'.
        bound: True when only an upper bound is known (no failure seen).
        reliable: the estimator's diagnostics support the interval.
        diagnostics: estimator-specific figures (ESS, weight share, CoV, ...).
        notes: plain-language remarks (what could not be reached, why unreliable).
    """

    value: float
    lo: float
    hi: float
    n: int
    method: str
    failures: int = -1
    bound: bool = False
    reliable: bool = True
    diagnostics: dict[str, float] = field(default_factory=dict)
    notes: tuple[str, ...] = ()

    @property
    def rel_ci(self) -> float:
        """Relative half-width (hi - lo) / (2 value); inf for a bound or a zero estimate."""
        if self.bound or not self.value > 0:
            return math.inf
        return (self.hi - self.lo) / (2.0 * self.value)

    def excludes_zero(self) -> bool:
        """The interval lies entirely on one side of 0 (for differences)."""
        return self.lo > 0 or self.hi < 0

    def with_note(self, note: str, reliable: bool | None = None) -> Estimate:
        """A copy with one more note (and reliability when given)."""
        return replace(
            self,
            notes=(*self.notes, note),
            reliable=self.reliable if reliable is None else reliable,
        )

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields (non-finite numbers as None)."""

        def clean(v: Any) -> Any:
            if isinstance(v, float | np.floating):
                v = float(v)
                return v if math.isfinite(v) else None
            return v

        return {
            "value": clean(self.value),
            "ci95": [clean(self.lo), clean(self.hi)],
            "rel_ci": clean(self.rel_ci),
            "n": int(self.n),
            "failures": int(self.failures),
            "method": self.method,
            "upper_bound_only": self.bound,
            "reliable": self.reliable,
            "diagnostics": {k: clean(v) for k, v in self.diagnostics.items()},
            "notes": list(self.notes),
        }

    def text(self, digits: int = 3) -> str:
        """One line: '2.31e-04 [1.9e-04, 2.8e-04]' or '< 3.7e-04 (no failure in 10,000)'."""
        if self.bound:
            return f"< {self.hi:.{digits - 1}e} (95 % upper bound, none in {self.n:,})"
        return f"{self.value:.{digits - 1}e} [{self.lo:.{digits - 1}e}, {self.hi:.{digits - 1}e}]"


def wilson_interval(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Wilson score interval of k successes in n trials (vei.sweep.riskmap's)."""
    from vei.sweep.riskmap import wilson_interval as wilson

    return wilson(k, n, z_value(confidence))


def clopper_pearson(k: int, n: int, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Exact (Clopper-Pearson) interval of k successes in n trials."""
    from scipy.stats import beta

    a = 1.0 - confidence
    lo = 0.0 if k == 0 else float(beta.ppf(a / 2, k, n - k + 1))
    hi = 1.0 if k == n else float(beta.ppf(1 - a / 2, k + 1, n - k))
    return lo, hi


def mc_probability(hits: npt.ArrayLike, confidence: float = CONFIDENCE) -> Estimate:
    """P(event) from n independent samples' indicators [n] (Wilson; a bound with k = 0)."""
    h = np.asarray(hits, dtype=bool)
    n, k = int(h.size), int(h.sum())
    if n == 0:
        return Estimate(math.nan, 0.0, 1.0, 0, "wilson", 0, bound=True, reliable=False,
                        notes=("no simulation",))  # fmt: skip
    if k == 0:
        hi = clopper_pearson(0, n, confidence)[1]
        return Estimate(
            math.nan, 0.0, hi, n, "clopper-pearson-bound", 0, bound=True,
            notes=(f"no failure in {n:,} simulations: only an upper bound",),
        )  # fmt: skip
    lo, hi = wilson_interval(k, n, confidence)
    return Estimate(k / n, lo, hi, n, "wilson", k, diagnostics={"cov": _binomial_cov(k, n)})


def _binomial_cov(k: int, n: int) -> float:
    p = k / n
    return math.sqrt((1 - p) / (n * p)) if 0 < p else math.inf


def mc_mean(
    values: npt.ArrayLike, failures: npt.ArrayLike, confidence: float = CONFIDENCE
) -> Estimate:
    """Mean of values [n] in [0, 1] (0 where no failure) from n independent samples, with a
    normal-approximation interval; with no failure ([n] bool ``failures`` all False) an
    upper bound: the failure probability's bound (the value is <= 1 per failure)."""
    v = np.asarray(values, dtype=np.float64)
    f = np.asarray(failures, dtype=bool)
    n, k = int(v.size), int(f.sum())
    if k == 0:
        b = mc_probability(f, confidence)
        return replace(b, notes=(*b.notes, "bounded by P(collision)'s bound (risk <= 1)"))
    mean = float(v.mean())
    se = float(v.std(ddof=1) / math.sqrt(n)) if n > 1 else math.inf
    z = z_value(confidence)
    return Estimate(
        mean, max(0.0, mean - z * se), min(1.0, mean + z * se), n, "normal", k,
        diagnostics={"cov": se / mean if mean > 0 else math.inf},
    )  # fmt: skip


def importance_sampling(
    h: npt.ArrayLike, w: npt.ArrayLike, failures: npt.ArrayLike, confidence: float = CONFIDENCE
) -> Estimate:
    """E_f[h] from samples of q with weights w = f/q [n], h [n] (an indicator or a value in
    [0, 1]) and the failure indicator [n] (for the diagnostics), with diagnostics."""
    h = np.asarray(h, dtype=np.float64)
    w = np.asarray(w, dtype=np.float64)
    f = np.asarray(failures, dtype=bool)
    n, k = int(h.size), int(f.sum())
    wh = w * h
    diag = _weight_diagnostics(w, f)
    if k == 0 or not np.any(wh > 0):
        return Estimate(
            math.nan, 0.0, math.nan, n, "importance-sampling", k, bound=True, reliable=False,
            diagnostics=diag,
            notes=("no failure among the importance samples: no estimate (the proposal "
                   "missed the failure region)",),
        )  # fmt: skip
    p = float(wh.mean())
    se = float(wh.std(ddof=1) / math.sqrt(n))
    z = z_value(confidence)
    diag["cov"] = se / p
    diag["max_weight_share"] = float(wh.max() / wh.sum())
    est = Estimate(
        p, max(0.0, p - z * se), p + z * se, n, "importance-sampling", k, diagnostics=diag
    )
    return is_reliable(est)


def _weight_diagnostics(w: FloatArray, failures: FloatArray) -> dict[str, float]:
    """ESS over all samples and over the failures."""

    def ess(x: FloatArray) -> float:
        s2 = float(np.sum(x * x))
        return float(np.sum(x)) ** 2 / s2 if s2 > 0 else 0.0

    return {"ess": ess(w), "ess_failures": ess(w[failures]), "n_failures": float(failures.sum())}


def is_reliable(est: Estimate) -> Estimate:
    """Mark an importance-sampling estimate unreliable when its diagnostics say so: fewer
    than MIN_FAILURE_ESS effective failure samples, or one sample carrying more than
    MAX_WEIGHT_SHARE of the estimate (weight degeneracy)."""
    d = est.diagnostics
    out = est
    if d.get("ess_failures", 0.0) < MIN_FAILURE_ESS:
        out = out.with_note(
            f"unreliable: effective failure sample size {d.get('ess_failures', 0):.0f} "
            f"< {MIN_FAILURE_ESS:.0f}",
            reliable=False,
        )
    if d.get("max_weight_share", 0.0) > MAX_WEIGHT_SHARE:
        out = out.with_note(
            f"unreliable: weight degeneracy, one sample carries "
            f"{100 * d['max_weight_share']:.0f} % of the estimate",
            reliable=False,
        )
    return out


def paired_difference(
    a: npt.ArrayLike,
    b: npt.ArrayLike,
    w: npt.ArrayLike | None = None,
    confidence: float = CONFIDENCE,
) -> Estimate:
    """E[a - b] from paired outcomes a, b [n] on the same samples (common random numbers),
    optionally importance-weighted (w [n]). Plain Monte Carlo of indicators: the
    Agresti-Min interval; otherwise the paired normal interval."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    n = int(a.size)
    z = z_value(confidence)
    binary = np.all((a == 0) | (a == 1)) and np.all((b == 0) | (b == 1))
    if w is None and binary:
        n10 = float(np.sum((a == 1) & (b == 0)))
        n01 = float(np.sum((a == 0) & (b == 1)))
        d = (n10 - n01) / n
        # Agresti & Min 2005: add 1/2 to each of the four cells (n + 2)
        n10a, n01a, na = n10 + 0.5, n01 + 0.5, n + 2.0
        da = (n10a - n01a) / na
        var = ((n10a + n01a) / na - da * da) / na
        half = z * math.sqrt(max(var, 0.0))
        return Estimate(
            d, max(-1.0, da - half), min(1.0, da + half), n, "agresti-min",
            diagnostics={"discordant_a_only": n10, "discordant_b_only": n01},
        )  # fmt: skip
    ww = np.ones(n) if w is None else np.asarray(w, dtype=np.float64)
    x = ww * (a - b)
    d = float(x.mean())
    se = float(x.std(ddof=1) / math.sqrt(n)) if n > 1 else math.inf
    return Estimate(d, d - z * se, d + z * se, n, "paired-normal", diagnostics={"se": se})


def needed_samples(p: float, rel_ci: float, confidence: float = CONFIDENCE) -> int:
    """Plain Monte Carlo samples for a relative half-width ``rel_ci`` at probability p:
    z^2 (1 - p) / (p rel_ci^2)."""
    if not 0 < p < 1:
        return 0 if p >= 1 else 2**62
    z = z_value(confidence)
    return int(math.ceil(z * z * (1 - p) / (p * rel_ci * rel_ci)))
