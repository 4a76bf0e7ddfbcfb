"""The variation model: which quantities of an encounter vary, and how (``variation:``).

A risk spec (``vei risk --spec FILE``; the ``risk:`` section of catalogue settings)::

    base: normal-cap              # the configuration whatever is not varied keeps
    time_shift_reference: auto    # auto: time_shift_s offsets the automatic shift; zero:
                                  # time_shift_s is the absolute shift (0 = the recording)
    seed: 0                       # sampling seed (every estimator; per-sample run configs
                                  # do not depend on it)
    variation:                    # one distribution per varied quantity (sweep names)
      time_shift_s: {dist: uniform, min: -2.0, max: 2.0}
      ego.cruise_speed_mps: {dist: normal, mean: recorded, cv: 0.36, min: 1.0, max: 15.3}
      cap.perception_delay_s: {dist: uniform, min: 0.0, max: 0.3}
      rider: {profile: calibrated, category: auto,   # null: the base configuration's rider
              speed: recorded, speed_sigma_log: 0.34,   # or speed: population
              max_speed_mps: {cyclist: 8.33, escooter: 5.56}}
    model: {name: ..., fitted_from: ..., validation: ...}   # optional: what the model is
                                  # (vei calibrate variation writes it; every answer names it)
    fixed: {cap.t_safe_s: 2.0}    # optional: parameters held at a value (sweep names)
    perception: {enabled: true, position_noise_std_m: 0.3}   # optional sensor model
    v2x: {enabled: true, penetration_rate: 0.5}   # optional V2X (docs/v2x.md)
    injury_relevant_speed_mps: 5.56   # optional: the injury-relevant impact speed [m/s]
    reconstruction: {samples: 50}   # optional: the rider's reconstruction uncertainty as a
                                  # dimension (reconstruction.sample: one of N posterior samples)

Without ``variation:`` the defaults of :mod:`vei.risk.defaults` apply (every default with
its unit and source; docs/risk.md). The quantities are sweep parameters
(:mod:`vei.sweep.params`: a float parameter's name is its run-config path), so every
sample is a sweep variant and its run configuration is written the way sweeps write
theirs. ``rider`` is the calibrated population (:mod:`vei.calibrate.profile`): five
correlated log-normal parameters, i.e. five standard-normal dimensions through the
Cholesky factor of the population's log-covariance (dimension ``rider.<param>`` is the
part of that parameter not explained by the ones before it).
With ``speed: recorded`` the rider's speed is centred on the recorded rider's own and
only tau, look-ahead and the acceleration limit come from the population
(:mod:`vei.risk.rider_space`); ``max_speed_mps`` bounds every rider's speeds.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.config import CASE_PRESETS
from vei.config.distributions import Distribution, parse_distribution
from vei.config.perception import PerceptionConfig
from vei.config.v2x import V2XConfig
from vei.errors import ConfigError, InputError
from vei.risk.defaults import DEFAULT_ABOUT, INJURY_RELEVANT_SPEED_MPS, default_variation
from vei.risk.rider_space import RIDER_CATEGORIES as RIDER_CATEGORIES
from vei.risk.rider_space import RiderVariation, parse_about, parse_rider, rider_dict

FloatArray = npt.NDArray[np.float64]

TIME_SHIFT_REFERENCES: tuple[str, ...] = ("auto", "zero")
_SPEC_KEYS = {
    "base",
    "time_shift_reference",
    "time_shift_window",
    "seed",
    "variation",
    "fixed",
    "perception",
    "v2x",
    "injury_relevant_speed_mps",
    "model",
    "reconstruction",
    "failure",
}
#: The dimension of the reconstruction's posterior sample (``reconstruction: {samples: N}``).
RECON_DIMENSION = "reconstruction.sample"
#: ``failure: {count: ...}``: which collisions count as failures: every collision, or
#: only those on the primary rider's recorded behaviour (vei.metrics.where).
FAILURE_COUNTS: tuple[str, ...] = ("all", "recorded")


@dataclass(frozen=True)
class VariationModel:
    """A validated risk spec (module docstring for the YAML form).

    Attributes:
        distributions: (sweep parameter name, Distribution) of each varied float quantity,
            in :data:`vei.sweep.params.PARAMETERS` order.
        rider: the rider population, or None (the base configuration's rider).
        base: configuration preset (``vei.config.CASE_PRESETS``).
        time_shift_reference: 'auto' or 'zero'.
        time_shift_window: 'recorded' (narrow a uniform time_shift_s to the offsets at
            which the recorded rider meets the car's path, vei.risk.window) or 'full'.
        seed: sampling seed (>= 0).
        fixed: (sweep parameter name, value) held fixed.
        perception: the ego's sensor model for every sample, or None (the base's).
        v2x: V2X for every sample (docs/v2x.md), or None (the base's: off); a varied or
            fixed ``v2x.*`` needs it enabled.
        injury_relevant_speed_mps: a collision is injury-relevant at an impact speed >= this.
        about: ((key, text), ...): what the model is and how it was validated (the spec's
            ``model:`` mapping, e.g. name, fitted_from, validation; every risk answer
            names it).
        failure_count: 'all' (every collision is a failure) or 'recorded' (only a
            collision on the primary rider's recorded behaviour; spec ``failure: {count:
            recorded}``).
        source: the file it came from (for messages).
    """

    distributions: tuple[tuple[str, Distribution], ...]
    rider: RiderVariation | None = None
    base: str = "normal-cap"
    time_shift_reference: str = "auto"
    time_shift_window: str = "recorded"
    seed: int = 0
    fixed: tuple[tuple[str, Any], ...] = ()
    perception: PerceptionConfig | None = None
    v2x: V2XConfig | None = None
    injury_relevant_speed_mps: float = INJURY_RELEVANT_SPEED_MPS
    about: tuple[tuple[str, str], ...] = field(default=(), compare=False)
    reconstruction_samples: int | None = None
    failure_count: str = "all"
    source: str | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        where = self.source or "risk spec"
        if self.base not in CASE_PRESETS:
            raise ConfigError(
                f"{where}: base must be one of {', '.join(CASE_PRESETS)}, got {self.base!r}"
            )
        if self.time_shift_reference not in TIME_SHIFT_REFERENCES:
            raise ConfigError(
                f"{where}: time_shift_reference must be auto or zero, got {self.time_shift_reference!r}"
            )
        if self.time_shift_window not in ("recorded", "full"):
            raise ConfigError(
                f"{where}: time_shift_window must be recorded or full, got {self.time_shift_window!r}"
            )
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"{where}: seed must be an integer >= 0, got {self.seed!r}")
        v = self.injury_relevant_speed_mps
        if isinstance(v, bool) or not isinstance(v, int | float) or not (0 < v < math.inf):
            raise ConfigError(f"{where}: injury_relevant_speed_mps must be > 0, got {v!r}")
        if self.failure_count not in FAILURE_COUNTS:
            raise ConfigError(
                f"{where}: failure.count must be one of {', '.join(FAILURE_COUNTS)}, got "
                f"{self.failure_count!r}"
            )
        from vei.sweep.params import check_v2x_spec

        check_v2x_spec([n for n, _ in (*self.distributions, *self.fixed)], self.v2x, where)
        if not self.dimension_names:
            raise ConfigError(
                f"{where}: the variation is empty: nothing varies (give at least one "
                "distribution, e.g. time_shift_s: {dist: uniform, min: -2, max: 2})"
            )
        if self.rider is not None and CASE_PRESETS[self.base].rider != "sfm":
            raise ConfigError(
                f"{where}: variation.rider varies the social-force rider, but base "
                f"'{self.base}' replays the rider: use an SFM base (e.g. normal-cap) or rider: null"
            )
        names = [n for n, _ in self.distributions] + [n for n, _ in self.fixed]
        if len(set(names)) != len(names):
            raise ConfigError(f"{where}: a parameter is both varied and fixed: {sorted(names)}")

    @property
    def varied(self) -> tuple[tuple[str, Distribution], ...]:
        """The distributions that are dimensions (not fixed values)."""
        return tuple((n, d) for n, d in self.distributions if not d.is_fixed)

    @property
    def rider_dimensions(self) -> tuple[str, ...]:
        """Names of the rider population's dimensions (empty without a population)."""
        from vei.risk.rider_space import rider_dimension_names

        return rider_dimension_names(self.rider.speed) if self.rider is not None else ()

    @property
    def dimension_names(self) -> tuple[str, ...]:
        """The standard-space dimensions, in order: the varied distributions, the rider's,
        then the reconstruction sample's (RECON_DIMENSION, with reconstruction samples)."""
        recon = (RECON_DIMENSION,) if self.reconstruction_samples else ()
        return tuple(n for n, _ in self.varied) + self.rider_dimensions + recon

    @property
    def dimension(self) -> int:
        """d, the number of standard-normal dimensions."""
        return len(self.dimension_names)

    def to_dict(self) -> dict[str, Any]:
        """The YAML form (parse_variation of it gives an equal model)."""
        import dataclasses

        var: dict[str, Any] = {n: d.to_dict() for n, d in self.distributions}
        var["rider"] = None if self.rider is None else rider_dict(self.rider)
        out: dict[str, Any] = {
            "base": self.base,
            "time_shift_reference": self.time_shift_reference,
            "time_shift_window": self.time_shift_window,
            "seed": self.seed,
            "variation": var,
            "fixed": dict(self.fixed),
            "injury_relevant_speed_mps": self.injury_relevant_speed_mps,
        }
        if self.reconstruction_samples:
            out["reconstruction"] = {"samples": self.reconstruction_samples}
        if self.failure_count != "all":  # the default stays out (digests unchanged)
            out["failure"] = {"count": self.failure_count}
        if self.perception is not None:
            out["perception"] = dataclasses.asdict(self.perception)
        if self.v2x is not None:
            out["v2x"] = dataclasses.asdict(self.v2x)
        out["model"] = {**dict(self.about), "description": self.description()}
        return out

    def digest(self) -> str:
        """A stable hash of the model's content."""
        import hashlib
        import json

        text = json.dumps(self.to_dict(), sort_keys=True, default=str)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def description(self) -> str:
        """One line naming the variation model and its validation (every risk answer)."""
        about = dict(self.about)
        name = about.get("name") or (
            "the built-in defaults (vei.risk.defaults)"
            if self.source in (None, "risk spec")
            else f"the risk spec {self.source}"
        )
        text = f"conditional on the variation model {name}"
        if about.get("fitted_from"):
            text += f", fitted from {about['fitted_from']}"
        val = about.get("validation")
        return text + (f"; validation: {val}" if val else "; not validated against held-out data")


def _check_parameter(name: str, where: str) -> None:
    from vei.sweep.params import PARAMETERS, POLICY_PARAM, check_name

    check_name(name, where)
    if name == POLICY_PARAM:
        raise ConfigError(f"{where}: the policy is chosen with --policy (or 'fixed'), not varied")
    if name not in PARAMETERS or PARAMETERS[name].kind != "float":
        floats = [n for n, p in PARAMETERS.items() if p.kind == "float"]
        raise ConfigError(
            f"{where}: '{name}' is not a varied quantity; expected one of {', '.join(floats)}"
        )


def _check_support(name: str, dist: Distribution, where: str) -> None:
    """A distribution must stay within the parameter's physical bounds (sfm.k_des_nspm > 0,
    cap.a_min_mps2 < 0, ...): its window must lie inside them."""
    from vei.sweep.params import PARAMETERS

    p = PARAMETERS[name]
    lo, hi = (dist.value, dist.value) if dist.is_fixed else (dist.low, dist.high)
    if dist.kind == "lognormal":
        lo = max(lo, 0.0)
    for bound, val, is_low in ((p.lower, lo, True), (p.upper, hi, False)):
        if bound is None:
            continue
        open_ = p.lower_open if is_low else p.upper_open
        bad = (
            (val < bound or (open_ and val == bound))
            if is_low
            else (val > bound or (open_ and val == bound))
        )
        if bad:
            side = "min" if is_low else "max"
            op = (">" if open_ else ">=") if is_low else ("<" if open_ else "<=")
            raise ConfigError(
                f"{where}: {name} must be {op} {bound:g} [{p.unit}], but the distribution "
                f"reaches {val:g}: give a {side} (e.g. {side}: {bound:g})"
            )


def parse_variation(raw: Any, where: str = "risk spec") -> VariationModel:
    """A risk spec mapping (module docstring) -> a validated :class:`VariationModel`.

    Raises:
        ConfigError: unknown keys, impossible distributions, an empty variation, values
            outside a parameter's bounds (each naming ``where`` and the key).
    """
    from vei.sweep.params import PARAMETERS, parse_perception, parse_reconstruction, parse_v2x

    if raw is None:
        raw = {}
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{where}: expected a mapping at the top level")
    unknown = set(map(str, raw)) - _SPEC_KEYS
    if unknown:
        raise ConfigError(
            f"{where}: unknown key(s) {', '.join(sorted(unknown))}; expected "
            f"{', '.join(sorted(_SPEC_KEYS))}"
        )
    var = default_variation() if "variation" not in raw else raw["variation"]
    about_raw = raw.get("model", DEFAULT_ABOUT if "variation" not in raw else None)
    if var is None or (isinstance(var, Mapping) and not var):
        raise ConfigError(
            f"{where}: variation is empty: nothing varies (give at least one distribution, "
            "or leave the key out for the defaults)"
        )
    if not isinstance(var, Mapping):
        raise ConfigError(f"{where}: variation must be a mapping of quantities to distributions")
    dists: dict[str, Distribution] = {}
    rider: RiderVariation | None = None
    for key, val in var.items():
        name = str(key)
        loc = f"{where}: variation.{name}"
        if name == "rider":
            if val is not None:
                rider = parse_rider(val, where)
            continue
        _check_parameter(name, loc)
        dist = parse_distribution(val, loc, allow_recorded=name == "ego.cruise_speed_mps")
        _check_support(name, dist, loc)
        dists[name] = dist
    fixed_raw = raw.get("fixed") or {}
    if not isinstance(fixed_raw, Mapping):
        raise ConfigError(f"{where}: fixed must be a mapping of parameter names to values")
    fixed: dict[str, Any] = {}
    for key, val in fixed_raw.items():
        name = str(key)
        from vei.sweep.params import check_name

        check_name(name, f"{where}: fixed")
        if name not in PARAMETERS:
            raise ConfigError(f"{where}: fixed: unknown parameter '{name}'")
        fixed[name] = PARAMETERS[name].check(val, f"{where}: fixed")
    order = list(PARAMETERS)
    seed = raw.get("seed", 0)
    model = VariationModel(
        distributions=tuple(sorted(dists.items(), key=lambda kv: order.index(kv[0]))),
        rider=rider,
        base=raw.get("base", "normal-cap"),
        time_shift_reference=raw.get("time_shift_reference", "auto"),
        time_shift_window=raw.get("time_shift_window", "recorded"),
        seed=seed,
        fixed=tuple(sorted(fixed.items(), key=lambda kv: order.index(kv[0]))),
        perception=parse_perception(raw.get("perception"), where),
        v2x=parse_v2x(raw.get("v2x"), where),
        injury_relevant_speed_mps=raw.get("injury_relevant_speed_mps", INJURY_RELEVANT_SPEED_MPS),
        about=parse_about(about_raw, where),
        reconstruction_samples=parse_reconstruction(raw.get("reconstruction"), where),
        failure_count=_failure_count(raw.get("failure"), where),
        source=where,
    )
    return model


def _failure_count(raw: Any, where: str) -> str:
    """``failure: {count: all | recorded}`` -> the count (default 'all').

    Raises:
        ConfigError: not a mapping, an unknown key (named), an unknown value.
    """
    if raw is None:
        return "all"
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{where}: failure must be a mapping such as {{count: recorded}}")
    unknown = sorted(set(map(str, raw)) - {"count"})
    if unknown:
        raise ConfigError(f"{where}: failure: unknown key(s) {', '.join(unknown)}; expected count")
    value = raw.get("count", "all")
    if value not in FAILURE_COUNTS:
        raise ConfigError(
            f"{where}: failure.count must be one of {', '.join(FAILURE_COUNTS)}, got {value!r}"
        )
    return str(value)


def load_variation(path: str | Path) -> VariationModel:
    """Read a risk spec (YAML / JSON) into a :class:`VariationModel`.

    Raises:
        InputError: the file is missing or not valid YAML. ConfigError: its content.
    """
    import yaml

    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise InputError(f"cannot read the risk spec: {exc.strerror}", path=path) from exc
    try:
        raw = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise InputError(f"not valid YAML: {exc}", path=path) from exc
    return parse_variation(raw, str(path))


# --------------------------------------------------------------------------------------
# The standard space of one scenario
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ScenarioSpace:
    """A variation model resolved for one scenario: standard normal u [N, d] -> the
    sweep parameters of N samples.

    Attributes:
        model: the variation model.
        distributions: (name, Distribution) with 'recorded' resolved, varied ones only.
        fixed: {sweep parameter: value} (the model's fixed values and fixed distributions).
        rider_mean, rider_chol: log-mean [5] and lower Cholesky factor [5, 5] of the rider
            population (empty arrays without one).
        rider_profile: the loaded rider profile (None without one).
        category: the rider population used.
        rider_speed: (median moving speed, p99 speed) of the recorded rider [m/s] (what
            ``speed: recorded`` centres on; nan when unknown).
        notes: lines every answer on this scenario carries (the time-shift window, a
            rider without a speed of its own).
    """

    model: VariationModel
    distributions: tuple[tuple[str, Distribution], ...]
    fixed: dict[str, Any]
    rider_mean: FloatArray
    rider_chol: FloatArray
    rider_profile: Any = None
    category: str = ""
    rider_speed: tuple[float, float] = (math.nan, math.nan)
    notes: tuple[str, ...] = ()

    @property
    def names(self) -> tuple[str, ...]:
        """Dimension names (= model.dimension_names)."""
        return self.model.dimension_names

    @property
    def dimension(self) -> int:
        """d."""
        return self.model.dimension

    def to_params(self, u: npt.ArrayLike) -> pd.DataFrame:
        """The sweep parameters of samples u [N, d]: one column per varied quantity (its
        sweep name), the fixed parameters, and the population rider's ``rider.*``
        (RIDER_PARAM_COLUMNS, VariantParams-ready: k_des = mass / tau) when there is one."""
        u = np.atleast_2d(np.asarray(u, dtype=np.float64))
        if u.shape[1] != self.dimension:
            raise ValueError(f"expected samples of dimension {self.dimension}, got {u.shape}")
        cols: dict[str, Any] = {}
        for j, (name, dist) in enumerate(self.distributions):
            cols[name] = dist.from_standard(u[:, j])
        for name, value in self.fixed.items():
            cols[name] = [value] * len(u)
        if self.rider_profile is not None and self.model.rider is not None:
            from vei.risk.rider_space import rider_params

            nd = len(self.distributions)
            z = u[:, nd : nd + len(self.model.rider_dimensions)]
            riders = rider_params(self, z, dict(self.model.rider.max_speed_mps))
            for fname, arr in riders.items():
                if fname != "tau_s":
                    cols[f"rider.{fname}"] = arr
        n_rec = self.model.reconstruction_samples
        if n_rec:  # u -> Phi(u) -> one of the N posterior samples, equally likely
            from scipy.special import ndtr

            from vei.sweep.spec import SAMPLE_COLUMN

            k = np.floor(ndtr(u[:, -1]) * n_rec).astype(np.int64)
            cols[SAMPLE_COLUMN] = np.clip(k, 0, n_rec - 1)
        return pd.DataFrame(cols, index=pd.RangeIndex(len(u)))

    def normalised(self, u: npt.ArrayLike) -> FloatArray:
        """Phi(u) [N, d] in [0, 1]^d: the variation's probability-integral cube (the
        space where "distinct failures" are counted, docs/risk.md)."""
        from scipy.special import ndtr

        return ndtr(np.atleast_2d(np.asarray(u, dtype=np.float64)))


def reach_speed_mps(model: VariationModel, recorded_cruise_mps: float) -> float | None:
    """The cruise speed every sample's run-ins and run-outs reach for [m/s]: the
    :data:`vei.sweep.params.REACH_QUANTILE` quantile of ``ego.cruise_speed_mps``'s
    distribution (its value when fixed; issue 22: every rider enters from beyond the car's
    reach at the speeds it samples), None when the model does not set the cruise speed
    (the base's recorded 'median-moving', as ``vei run`` does).

    Args:
        model: the variation model.
        recorded_cruise_mps: the scenario's recorded ego median moving speed [m/s].
    """
    from vei.sweep.params import CRUISE_PARAM as CRUISE_NAME
    from vei.sweep.params import REACH_QUANTILE

    fixed = dict(model.fixed)
    if CRUISE_NAME in fixed:
        return float(fixed[CRUISE_NAME])
    for name, dist in model.distributions:
        if name == CRUISE_NAME:
            return float(dist.resolve(recorded_cruise_mps).ppf(REACH_QUANTILE))
    return None


def resolve_space(
    model: VariationModel,
    recorded_cruise_mps: float,
    rider_category: str,
    rider_speed: tuple[float, float] = (math.nan, math.nan),
    auto_shift: Any = None,
) -> ScenarioSpace:
    """The model's standard space for one scenario.

    Args:
        model: the variation model.
        recorded_cruise_mps: the scenario's recorded ego median moving speed [m/s] (what
            ``mean: recorded`` means).
        rider_category: the primary rider's category ('escooter' / 'cyclist'), used by
            ``category: auto``.
        rider_speed: (median moving, p99) speed of the recorded rider [m/s]
            (vei.risk.rider_space.recorded_rider_speeds), needed by ``speed: recorded``.
        auto_shift: the scenario's automatic TimeShiftResult (reference 'auto'): the
            time-shift window (vei.risk.window).
    Raises:
        ConfigError: a resolved distribution is impossible (e.g. its truncation window
            holds no probability for this scenario's recorded speed); the rider profile
            cannot be read.
    """
    from vei.calibrate.profile import load_profile
    from vei.risk.window import narrow_time_shift

    dists = tuple((n, d.resolve(recorded_cruise_mps)) for n, d in model.varied)
    ts = dict(dists).get("time_shift_s")
    narrowed, note = narrow_time_shift(ts, auto_shift, model.time_shift_window)
    dists = tuple((n, narrowed if n == "time_shift_s" else d) for n, d in dists)
    fixed = dict(model.fixed)
    fixed.update({n: d.value for n, d in model.distributions if d.is_fixed})
    if model.rider is None:
        return ScenarioSpace(
            model, dists, fixed, np.zeros(0), np.zeros((0, 0)), notes=(note,) if note else ()
        )
    try:
        profile = load_profile(model.rider.profile)
    except InputError as exc:
        raise ConfigError(f"{model.source or 'risk spec'}: variation.rider: {exc}") from None
    cat = rider_category if model.rider.category == "auto" else model.rider.category
    pops = profile["populations"]
    pop = pops[cat] if cat in pops else pops["all"]
    mean = np.asarray(pop["log_mean"], dtype=np.float64)
    cov = np.asarray(pop["log_cov"], dtype=np.float64)
    # Cholesky of the (positive semi-definite) covariance; a tiny ridge where singular
    scale = max(float(np.trace(cov)) / len(mean), 1e-12)
    chol = np.linalg.cholesky(cov + 1e-12 * scale * np.eye(len(mean)))
    notes = (note,) if note else ()
    if model.rider.speed == "recorded":
        from vei.risk.rider_space import centre_speed

        rider_speed, rnote = centre_speed(profile, cat, rider_speed)
        notes += (rnote,) if rnote else ()
    return ScenarioSpace(
        model, dists, fixed, mean, chol, profile, cat if cat in pops else "all", rider_speed,
        notes,
    )  # fmt: skip
