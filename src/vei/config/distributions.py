"""One varied quantity's distribution: validated on construction, mapped from standard
normal space.

Every varied quantity of a variation model (:mod:`vei.risk.variation`) and of a sweep
spec's ``variation:`` section (:mod:`vei.sweep.spec`) is one :class:`Distribution`. The estimators work in *standard normal space*: a sample is a
vector ``u`` of independent N(0, 1) numbers, and each quantity is ``x = F^-1(Phi(u))``
(the isoprobabilistic transform), so Monte Carlo, cross-entropy importance sampling and
subset simulation see one space whatever the distributions are.

Kinds (YAML ``{dist: KIND, ...}``):

=============  ==========================================  ==============================
kind           keys                                        meaning
=============  ==========================================  ==============================
``uniform``    ``min``, ``max``                            U[min, max]
``normal``     ``mean``, ``std`` or ``cv``; ``min``/``max``  N(mean, std^2), truncated to
                                                           [min, max] when given
``lognormal``  ``median``, ``sigma_log``; ``min``/``max``  exp(N(ln median, sigma_log^2))
``fixed``      ``value``                                   one value (not a dimension)
=============  ==========================================  ==============================

``mean: recorded`` (``ego.cruise_speed_mps`` only) is the scenario's own value (the
recorded ego's median moving speed), resolved per scenario by :meth:`Distribution.resolve`;
``cv`` is the standard deviation as a share of the mean. Impossible parameters (std <= 0,
min >= max, a truncation window holding less than 1e-12 of the probability, ...) are
ConfigErrors naming the file and the key.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.errors import ConfigError

FloatArray = npt.NDArray[np.float64]

KINDS: tuple[str, ...] = ("uniform", "normal", "lognormal", "fixed")
#: ``mean: recorded``: the scenario's own value of the quantity.
RECORDED = "recorded"
#: A truncation window must hold at least this much probability.
MIN_WINDOW_PROBABILITY = 1e-12
_KEYS: dict[str, set[str]] = {
    "uniform": {"min", "max"},
    "normal": {"mean", "std", "cv", "min", "max"},
    "lognormal": {"median", "sigma_log", "min", "max"},
    "fixed": {"value"},
}


def _num(value: Any, where: str, key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ConfigError(f"{where}: {key} expects a number, got {value!r}")
    v = float(value)
    if not math.isfinite(v):
        raise ConfigError(f"{where}: {key} must be finite, got {value!r}")
    return v


@dataclass(frozen=True)
class Distribution:
    """The distribution of one varied quantity (see the module docstring).

    Attributes:
        kind: 'uniform', 'normal', 'lognormal' or 'fixed'.
        low, high: uniform bounds, or the truncation window of normal / lognormal
            (-inf / inf when not truncated).
        mean, std: normal parameters (mean = nan while ``mean_recorded`` is unresolved).
        cv: std as a share of the mean (normal; None when std is given).
        median, sigma_log: lognormal parameters.
        value: the fixed value.
        mean_recorded: the mean is the scenario's own value (resolved per scenario).
        where: file and key, for messages.
    """

    kind: str
    low: float = -math.inf
    high: float = math.inf
    mean: float = math.nan
    std: float = math.nan
    cv: float | None = None
    median: float = math.nan
    sigma_log: float = math.nan
    value: float = math.nan
    mean_recorded: bool = False
    where: str = "variation"

    def __post_init__(self) -> None:
        w = self.where
        if self.kind not in KINDS:
            raise ConfigError(f"{w}: dist must be one of {', '.join(KINDS)}, got {self.kind!r}")
        if self.kind == "fixed":
            if not math.isfinite(self.value):
                raise ConfigError(f"{w}: a fixed value must be finite")
            return
        if not self.low < self.high:
            raise ConfigError(f"{w}: needs min < max, got min {self.low:g}, max {self.high:g}")
        if self.kind == "uniform":
            if not (math.isfinite(self.low) and math.isfinite(self.high)):
                raise ConfigError(f"{w}: a uniform distribution needs finite min and max")
            return
        if self.kind == "normal":
            if self.cv is not None and not self.cv > 0:
                raise ConfigError(f"{w}: cv must be > 0, got {self.cv:g}")
            if not self.mean_recorded:
                if not math.isfinite(self.mean):
                    raise ConfigError(f"{w}: a normal distribution needs a finite mean")
                if not (self.std > 0 and math.isfinite(self.std)):
                    raise ConfigError(
                        f"{w}: std must be > 0 (cv > 0 needs a mean > 0), got {self.std:g}"
                    )
        if self.kind == "lognormal":
            if not (self.median > 0 and math.isfinite(self.median)):
                raise ConfigError(f"{w}: median must be > 0, got {self.median:g}")
            if not (self.sigma_log > 0 and math.isfinite(self.sigma_log)):
                raise ConfigError(f"{w}: sigma_log must be > 0, got {self.sigma_log:g}")
            if self.low < 0:
                raise ConfigError(f"{w}: a lognormal's min must be >= 0, got {self.low:g}")
        if self.resolved and self.window_probability() < MIN_WINDOW_PROBABILITY:
            raise ConfigError(
                f"{w}: the window [{self.low:g}, {self.high:g}] holds "
                f"{self.window_probability():.1e} of the distribution's probability: impossible "
                "parameters (move min/max towards the centre)"
            )

    @property
    def resolved(self) -> bool:
        """False while the mean is the scenario's recorded value, not yet known."""
        return not self.mean_recorded or math.isfinite(self.mean)

    @property
    def is_fixed(self) -> bool:
        """A fixed value: not a dimension of the standard space."""
        return self.kind == "fixed"

    def resolve(self, recorded: float) -> Distribution:
        """This distribution with ``mean: recorded`` set to ``recorded`` (a no-op otherwise).

        Raises:
            ConfigError: the resolved parameters are impossible (e.g. cv with a mean <= 0).
        """
        if not self.mean_recorded:
            return self
        std = self.std if self.cv is None else self.cv * float(recorded)
        return replace(self, mean=float(recorded), std=std, mean_recorded=False)

    def _std_params(self) -> tuple[float, float, float, float]:
        """(loc, scale, a, b): the normal of the kind and its window in standard units."""
        if self.kind == "normal":
            loc, scale = self.mean, self.std
            a, b = (self.low - loc) / scale, (self.high - loc) / scale
        else:  # lognormal: on the log scale
            loc, scale = math.log(self.median), self.sigma_log
            lo = math.log(self.low) if self.low > 0 else -math.inf
            hi = math.log(self.high) if math.isfinite(self.high) else math.inf
            a, b = (lo - loc) / scale, (hi - loc) / scale
        return loc, scale, a, b

    def window_probability(self) -> float:
        """Probability of the untruncated distribution inside [low, high] (1 for uniform)."""
        from scipy.special import ndtr

        if self.kind in ("uniform", "fixed"):
            return 1.0
        _, _, a, b = self._std_params()
        return float(ndtr(b) - ndtr(a))

    def ppf(self, p: npt.ArrayLike) -> FloatArray:
        """Quantiles x = F^-1(p) [N] of probabilities p in (0, 1) [N]."""
        from scipy.special import ndtr, ndtri

        p = np.asarray(p, dtype=np.float64)
        if self.kind == "fixed":
            return np.full(p.shape, self.value)
        if not self.resolved:
            raise ConfigError(f"{self.where}: mean 'recorded' is not resolved for a scenario")
        if self.kind == "uniform":
            return self.low + p * (self.high - self.low)
        loc, scale, a, b = self._std_params()
        lo, hi = ndtr(a), ndtr(b)
        z = ndtri(lo + p * (hi - lo))
        z = np.clip(z, a, b)
        x = loc + scale * z
        return np.exp(x) if self.kind == "lognormal" else x

    def from_standard(self, u: npt.ArrayLike) -> FloatArray:
        """x = F^-1(Phi(u)) [N] of standard normal numbers u [N] (tails kept: the
        transform uses log-probabilities on the far side so that u = 8 is not rounded to
        the window's edge)."""
        from scipy.special import log_ndtr, ndtr, ndtri_exp

        u = np.asarray(u, dtype=np.float64)
        if self.kind == "normal" and math.isinf(self.low) and math.isinf(self.high):
            return self.mean + self.std * u  # exact, no round trip through Phi
        if self.kind == "lognormal" and self.low <= 0 and math.isinf(self.high):
            return np.exp(math.log(self.median) + self.sigma_log * u)
        if self.kind in ("uniform", "fixed") or not self.resolved:
            return self.ppf(ndtr(u))
        # The window's quantile Phi(a) + Phi(u) (Phi(b) - Phi(a)) in log-probabilities, from
        # the near tail on each side: u = 10 stays inside the window instead of rounding
        # to p = 1 (z = inf, a cruise speed of inf m/s in a cross-entropy stage).
        loc, scale, a, b = self._std_params()
        with np.errstate(divide="ignore"):
            log_w = math.log(float(ndtr(b) - ndtr(a)))
            lower = u <= 0
            z = np.empty_like(u)
            ul = u[lower]
            z[lower] = ndtri_exp(np.logaddexp(log_ndtr(a), log_ndtr(ul) + log_w))
            uu = u[~lower]
            z[~lower] = -ndtri_exp(np.logaddexp(log_ndtr(-b), log_ndtr(-uu) + log_w))
        x = loc + scale * np.clip(z, a, b)
        return np.exp(x) if self.kind == "lognormal" else x

    def cdf(self, x: npt.ArrayLike) -> FloatArray:
        """F(x) [N] (the probability of values <= x)."""
        from scipy.special import ndtr

        x = np.asarray(x, dtype=np.float64)
        if self.kind == "fixed":
            return (x >= self.value).astype(np.float64)
        if self.kind == "uniform":
            return np.clip((x - self.low) / (self.high - self.low), 0.0, 1.0)
        loc, scale, a, b = self._std_params()
        with np.errstate(divide="ignore"):
            v = np.log(np.maximum(x, 0.0)) if self.kind == "lognormal" else x
        z = np.clip((v - loc) / scale, a, b)
        lo, hi = ndtr(a), ndtr(b)
        return (ndtr(z) - lo) / (hi - lo)

    def summary(self) -> str:
        """One line, e.g. ``uniform [-2, 2]`` or ``normal mean 6.1 std 1.34 in [1, inf]``."""
        if self.kind == "fixed":
            return f"fixed {self.value:g}"
        if self.kind == "uniform":
            return f"uniform [{self.low:g}, {self.high:g}]"
        window = (
            f" in [{self.low:g}, {self.high:g}]"
            if math.isfinite(self.low) or math.isfinite(self.high)
            else ""
        )
        if self.kind == "normal":
            if self.mean_recorded and not math.isfinite(self.mean):
                spread = f"cv {self.cv:g}" if self.cv is not None else f"std {self.std:g}"
                return f"normal mean recorded {spread}{window}"
            return f"normal mean {self.mean:.4g} std {self.std:.4g}{window}"
        return f"lognormal median {self.median:.4g} sigma_log {self.sigma_log:.4g}{window}"

    def to_dict(self) -> dict[str, Any]:
        """The YAML form (``{dist: ..., ...}``); round-trips through :func:`parse_distribution`."""
        if self.kind == "fixed":
            return {"dist": "fixed", "value": self.value}
        if self.kind == "uniform":
            return {"dist": "uniform", "min": self.low, "max": self.high}
        out: dict[str, Any] = {"dist": self.kind}
        if self.kind == "normal":
            out["mean"] = RECORDED if self.mean_recorded else self.mean
            if self.cv is not None:
                out["cv"] = self.cv
            else:
                out["std"] = self.std
        else:
            out.update(median=self.median, sigma_log=self.sigma_log)
        if math.isfinite(self.low):
            out["min"] = self.low
        if math.isfinite(self.high):
            out["max"] = self.high
        return out


def parse_distribution(raw: Any, where: str, *, allow_recorded: bool = False) -> Distribution:
    """``{dist: KIND, ...}`` (or a bare number: fixed) -> a :class:`Distribution`.

    Args:
        raw: the YAML value. where: 'file: variation.NAME' for messages.
        allow_recorded: whether ``mean: recorded`` is allowed (a quantity with a
            recorded value per scenario).
    Raises:
        ConfigError: an unknown kind or key, a missing key, or impossible parameters.
    """
    if not isinstance(raw, Mapping):
        if isinstance(raw, bool) or not isinstance(raw, int | float):
            raise ConfigError(
                f"{where}: expected {{dist: uniform|normal|lognormal, ...}} or a number"
            )
        return Distribution("fixed", value=_num(raw, where, "value"), where=where)
    kind = raw.get("dist")
    if kind not in KINDS:
        raise ConfigError(f"{where}: dist must be one of {', '.join(KINDS)}, got {kind!r}")
    unknown = set(map(str, raw)) - _KEYS[kind] - {"dist"}
    if unknown:
        raise ConfigError(
            f"{where}: unknown key(s) {', '.join(sorted(unknown))} for dist {kind}; expected "
            f"{', '.join(sorted(_KEYS[kind]))}"
        )

    def need(key: str) -> float:
        if key not in raw:
            raise ConfigError(f"{where}: dist {kind} needs '{key}'")
        return _num(raw[key], where, key)

    low = _num(raw["min"], where, "min") if "min" in raw else -math.inf
    high = _num(raw["max"], where, "max") if "max" in raw else math.inf
    if kind == "fixed":
        return Distribution("fixed", value=need("value"), where=where)
    if kind == "uniform":
        return Distribution("uniform", low=need("min"), high=need("max"), where=where)
    if kind == "lognormal":
        return Distribution(
            "lognormal", low=max(low, 0.0), high=high, median=need("median"),
            sigma_log=need("sigma_log"), where=where,
        )  # fmt: skip
    if ("std" in raw) == ("cv" in raw):
        raise ConfigError(f"{where}: dist normal needs exactly one of 'std' and 'cv'")
    recorded = raw.get("mean") == RECORDED
    if recorded and not allow_recorded:
        raise ConfigError(f"{where}: mean 'recorded' is only known for ego.cruise_speed_mps")
    cv = _num(raw["cv"], where, "cv") if "cv" in raw else None
    if recorded:
        if "std" in raw:
            std = _num(raw["std"], where, "std")
            if not std > 0:
                raise ConfigError(f"{where}: std must be > 0, got {std:g}")
        else:
            std = math.nan
        return Distribution(
            "normal", low=low, high=high, std=std, cv=cv, mean_recorded=True, where=where
        )
    mean = need("mean")
    std = _num(raw["std"], where, "std") if "std" in raw else float(cv) * mean  # type: ignore[arg-type]
    return Distribution("normal", low=low, high=high, mean=mean, std=std, cv=cv, where=where)
