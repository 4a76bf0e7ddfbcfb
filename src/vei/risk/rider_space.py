"""The rider part of a risk spec's standard space (issue 31.2/31.3).

Two forms of ``variation.rider``:

- ``speed: population`` (the calibrated population, five correlated log-normal
  parameters: v0, tau, look-ahead, speed limit, acceleration limit; dimensions
  ``rider.<param>``);
- ``speed: recorded`` (conditional on the recorded rider): the rider's cruise speed is its
  own recorded median moving speed times ``exp(speed_sigma_log z)`` (dimension
  ``rider.speed``); v0 is the desired speed that gives that cruise speed at the sampled
  look-ahead (:func:`vei.calibrate.profile.cruise_v0_mps`); the speed limit is the cruise
  speed times the recorded rider's own ratio p99 / median; tau, look-ahead and the
  acceleration limit come from the population (their marginal log-normal, dimensions
  ``rider.tau_s``, ``rider.lookahead_m``, ``rider.max_accel_mps2``).

Either form is bounded by ``max_speed_mps`` ({category: m/s}): a rider's cruise speed,
desired speed and speed limit never exceed its category's bound (the cited and data
bounds of :mod:`vei.calibrate.variation`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.errors import ConfigError

FloatArray = npt.NDArray[np.float64]

RIDER_CATEGORIES: tuple[str, ...] = ("auto", "escooter", "cyclist", "all")
RIDER_SPEEDS: tuple[str, ...] = ("population", "recorded")
_RIDER_KEYS = {"profile", "category", "speed", "speed_sigma_log", "max_speed_mps"}

#: Population parameters varied beside the speed when ``speed: recorded``.
CONDITIONAL_PARAMETERS: tuple[str, ...] = ("tau_s", "lookahead_m", "max_accel_mps2")
#: The riders' moving threshold [m/s] (as the calibrated tracks).
MOVING_MPS = 0.5


@dataclass(frozen=True)
class RiderVariation:
    """The rider population that varies the social-force rider.

    Attributes:
        profile: a rider profile file or 'calibrated' (the shipped profile).
        category: 'auto' (the primary rider's category), 'escooter', 'cyclist' or 'all'.
        speed: 'population' (v0 and the speed limit from the population) or 'recorded'
            (centred on the recorded rider's own speed, vei.risk.rider_space).
        speed_sigma_log: with speed 'recorded': the log spread of the rider's cruise speed.
        max_speed_mps: ((category, bound [m/s]), ...): upper bound of a rider's cruise /
            desired speed and speed limit per category (empty: the population's bounds).
    """

    profile: str = "calibrated"
    category: str = "auto"
    speed: str = "population"
    speed_sigma_log: float | None = None
    max_speed_mps: tuple[tuple[str, float], ...] = ()

    def __post_init__(self) -> None:
        if self.speed not in RIDER_SPEEDS:
            raise ConfigError(f"rider.speed must be population or recorded, got {self.speed!r}")
        sig = self.speed_sigma_log
        if self.speed == "recorded":
            if isinstance(sig, bool) or not isinstance(sig, int | float) or not 0 < sig < 5:
                raise ConfigError(
                    f"rider.speed_sigma_log must be a number in (0, 5) with speed: recorded, got {sig!r}"
                )
        elif sig is not None:
            raise ConfigError("rider.speed_sigma_log needs speed: recorded")
        for cat, b in self.max_speed_mps:
            if cat not in RIDER_CATEGORIES[1:]:
                raise ConfigError(
                    f"rider.max_speed_mps: unknown category {cat!r}; expected escooter, cyclist, all"
                )
            if isinstance(b, bool) or not isinstance(b, int | float) or not 0.5 <= b <= 15.0:
                raise ConfigError(f"rider.max_speed_mps.{cat} must be in [0.5, 15] m/s, got {b!r}")
        if not isinstance(self.profile, str) or not self.profile:
            raise ConfigError(f"rider.profile must be a file or 'calibrated', got {self.profile!r}")
        if self.category not in RIDER_CATEGORIES:
            raise ConfigError(
                f"rider.category must be one of {', '.join(RIDER_CATEGORIES)}, got {self.category!r}"
            )


def rider_dict(rider: RiderVariation) -> dict[str, Any]:
    """The YAML form of a rider variation."""
    out: dict[str, Any] = {"profile": rider.profile, "category": rider.category}
    if rider.speed != "population":
        out["speed"] = rider.speed
        out["speed_sigma_log"] = rider.speed_sigma_log
    if rider.max_speed_mps:
        out["max_speed_mps"] = dict(rider.max_speed_mps)
    return out


def parse_about(raw: Any, where: str) -> tuple[tuple[str, str], ...]:
    """A spec's ``model:`` mapping -> ((key, text), ...) (its derived description left out)."""
    if raw is None:
        return ()
    if not isinstance(raw, Mapping) or not all(
        isinstance(v, str | int | float) and not isinstance(v, bool) for v in raw.values()
    ):
        raise ConfigError(
            f"{where}: model must be a mapping of texts (name, fitted_from, validation, ...)"
        )
    return tuple((str(k), str(v)) for k, v in raw.items() if str(k) != "description")


def parse_rider(val: Any, where: str) -> RiderVariation:
    """A spec's ``variation.rider`` mapping -> a RiderVariation (ConfigError naming the key)."""
    loc = f"{where}: variation.rider"
    if not isinstance(val, Mapping) or set(map(str, val)) - _RIDER_KEYS:
        raise ConfigError(
            f"{loc}: expected {{profile: calibrated, category: auto[, speed: recorded, "
            "speed_sigma_log: S, max_speed_mps: {cyclist: B, escooter: B}]}"
        )
    kw = {str(k): v for k, v in val.items()}
    bounds = kw.pop("max_speed_mps", None) or {}
    if not isinstance(bounds, Mapping):
        raise ConfigError(f"{loc}.max_speed_mps: expected {{category: m/s}}")
    kw["max_speed_mps"] = tuple(sorted((str(k), v) for k, v in bounds.items()))
    try:
        return RiderVariation(**kw)
    except ConfigError as exc:
        raise ConfigError(f"{where}: variation.{exc}") from None


def rider_dimension_names(speed: str) -> tuple[str, ...]:
    """The standard-space dimensions of a rider variation ('population' / 'recorded')."""
    from vei.calibrate.profile import POP_PARAMETERS

    if speed == "recorded":
        return ("rider.speed",) + tuple(f"rider.{p}" for p in CONDITIONAL_PARAMETERS)
    return tuple(f"rider.{p}" for p in POP_PARAMETERS)


def recorded_rider_speeds(scenario: Any, agent_id: str) -> tuple[float, float]:
    """(median moving speed, 99th percentile of speed) [m/s] of one rider's recorded
    samples (continuations left out); (nan, nan) when it never moves."""
    from vei.continuation.scenario import recorded_rows

    rows = recorded_rows(scenario.trajectories)
    rows = rows[rows["agent_id"] == agent_id].sort_values("t_s")
    sp = rows["speed_mps"].to_numpy(dtype=np.float64) if "speed_mps" in rows else np.zeros(0)
    if sp.size == 0 or not np.isfinite(sp).all():
        t = rows["t_s"].to_numpy(dtype=np.float64)
        x, y = rows["x_m"].to_numpy(dtype=np.float64), rows["y_m"].to_numpy(dtype=np.float64)
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
        sp = np.gradient(arc, t) if t.size > 1 else np.zeros_like(arc)
    moving = sp[sp > MOVING_MPS]
    if moving.size == 0:
        return float("nan"), float("nan")
    return float(np.median(moving)), float(np.percentile(sp, 99))


def rider_params(
    space: Any, z: FloatArray, bounds: Mapping[str, float] | None
) -> dict[str, FloatArray]:
    """VariantParams-ready rider arrays [N] of standard-normal rider samples z [N, k].

    Args:
        space: the ScenarioSpace (rider_mean, rider_chol, rider_profile, category,
            rider_speed, model.rider.speed / speed_sigma_log).
        z: [N, k] the rider dimensions of the samples.
        bounds: {category: m/s} upper bound of cruise / desired speed and speed limit.
    """
    from vei.calibrate.profile import (
        POP_PARAMETERS,
        SAMPLE_BOUNDS,
        cruise_v0_mps,
        population_params,
    )

    n = z.shape[0]
    cap = np.inf
    if bounds:
        cap = float(bounds.get(space.category, bounds.get("all", max(bounds.values()))))
    rider = space.model.rider
    if rider.speed != "recorded":
        logs = space.rider_mean[None, :] + z @ space.rider_chol.T
        vals = {
            p: np.clip(np.exp(logs[:, i]), *SAMPLE_BOUNDS[p]) for i, p in enumerate(POP_PARAMETERS)
        }
        vals["v0_mps"] = np.minimum(vals["v0_mps"], cap)
        vals["max_speed_mps"] = np.minimum(vals["max_speed_mps"], cap)
        return population_params(space.rider_profile, vals, n)
    median, p99 = space.rider_speed
    idx = [POP_PARAMETERS.index(p) for p in CONDITIONAL_PARAMETERS]
    mean = space.rider_mean[idx]
    cov = space.rider_chol @ space.rider_chol.T
    sub = cov[np.ix_(idx, idx)]
    chol = np.linalg.cholesky(sub + 1e-12 * max(float(np.trace(sub)), 1e-12) * np.eye(len(idx)))
    logs = mean[None, :] + z[:, 1:] @ chol.T
    vals = {
        p: np.clip(np.exp(logs[:, i]), *SAMPLE_BOUNDS[p])
        for i, p in enumerate(CONDITIONAL_PARAMETERS)
    }
    cruise = median * np.exp(rider.speed_sigma_log * z[:, 0])
    cruise = np.clip(cruise, MOVING_MPS, min(cap, SAMPLE_BOUNDS["max_speed_mps"][1]))
    sigma = float(space.rider_profile["model"].get("sigma_m", 1.0))
    v0 = cruise_v0_mps(cruise, vals["lookahead_m"], sigma)
    vals["v0_mps"] = np.clip(v0, SAMPLE_BOUNDS["v0_mps"][0], min(cap, SAMPLE_BOUNDS["v0_mps"][1]))
    ratio = max(p99 / median, 1.0)
    vals["max_speed_mps"] = np.clip(
        cruise * ratio,
        SAMPLE_BOUNDS["max_speed_mps"][0],
        min(cap, SAMPLE_BOUNDS["max_speed_mps"][1]),
    )
    return population_params(space.rider_profile, vals, n)


def centre_speed(
    profile: Mapping[str, Any], category: str, rider_speed: tuple[float, float]
) -> tuple[tuple[float, float], str]:
    """The (median moving, p99) speed [m/s] ``speed: recorded`` centres on, and a note.

    A rider that never moves in its recording (nan or <= MOVING_MPS) has no speed of its
    own: the population's median rider stands in (cruise speed = its median v0 at its
    median look-ahead, p99 = its median speed limit), and the note says so.
    """
    import math

    from vei.calibrate.profile import cruise_v0_mps

    med, p99 = rider_speed
    if math.isfinite(med) and med > MOVING_MPS:
        return (float(med), float(p99 if math.isfinite(p99) else med)), ""
    pops = profile["populations"]
    m = (pops[category] if category in pops else pops["all"])["median"]
    sigma = float(profile["model"].get("sigma_m", 1.0))
    ratio = float(cruise_v0_mps(1.0, m["lookahead_m"], sigma))  # v0 per unit cruise speed
    cruise = float(m["v0_mps"]) / ratio
    limit = max(float(m["max_speed_mps"]), cruise)
    note = (
        f"the rider does not move in its recording: its speed is centred on the population's "
        f"median rider ({cruise:.2f} m/s), not on its own"
    )
    return (cruise, limit), note
