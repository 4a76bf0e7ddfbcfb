"""Rider profiles: per-track fits + the population per category, as a JSON file.

Format ``vei.rider_profile/1`` (JSON; YAML with the same keys is read too)::

    {"format": "vei.rider_profile/1",
     "source": {...},                       # dataset, scenarios, filter rule, horizon
     "model": {"mass_kg": 95, "sigma_m": 1, "desired_velocity": "normalised"},
     "vehicle_repulsion": {"a_veh_n", "b_veh_per_m", "identified", "a_ci_n", ...},
     "populations": {"escooter": POP, "cyclist": POP, "all": POP},
     "tracks": [{"key", "category", "v0_mps", "tau_s", "lookahead_m", ...}, ...]}

    POP = {"n_tracks", "parameters": [names], "log_mean": [..], "log_cov": [[..]],
           "covariance_from": "own" | "all", "median": {name: value},
           "quantiles": {"0.05": {name: value}, "0.25": .., "0.5": .., "0.75": .., "0.95": ..}}

The population parameters (``POP_PARAMETERS``) are positive, so the population is a
log-normal: mean and covariance of their logarithms. A category with fewer than
``MIN_TRACKS_OWN_COV`` tracks keeps its own log-mean but borrows the covariance of all
riders (a covariance from two tracks is degenerate).

Sampling (:func:`sample_population`): draws from the log-normal, clipped to
``SAMPLE_BOUNDS`` (the fit's bounds). ``k_des = mass / tau``.

Applying the profile to one recorded rider (:func:`params_for_recorded_rider`): the speed
parameters come from the rider's own recording, the others from the population medians:
``v0`` such that the cruise speed ``v0 L / sqrt(L^2 + sigma^2)`` of the normalised desired
velocity equals its median moving speed, and ``max_speed`` = the 99th percentile of its
speed; ``tau``, ``lookahead``, ``max_accel`` are population medians; A and b the profile's.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import asdict
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.calibrate.fit import MASS_KG, SIGMA_M, FitResult, TrackFit, vehicle_values
from vei.errors import InputError
from vei.io.atomic import write_json

FloatArray = npt.NDArray[np.float64]

PROFILE_FORMAT = "vei.rider_profile/1"
#: Name of the profile shipped with vei (fitted on the shared TrafficMonitoring data).
CALIBRATED_PROFILE_NAME = "calibrated"
_SHIPPED_FILE = "riders_trafficmonitoring.json"
POP_PARAMETERS: tuple[str, ...] = (
    "v0_mps",
    "tau_s",
    "lookahead_m",
    "max_speed_mps",
    "max_accel_mps2",
)
#: Sampling bounds per population parameter (the fit's bounds; limits: physical ranges).
SAMPLE_BOUNDS: dict[str, tuple[float, float]] = {
    "v0_mps": (0.2, 12.0),
    "tau_s": (0.1, 10.0),
    "lookahead_m": (0.5, 20.0),
    "max_speed_mps": (0.5, 15.0),
    "max_accel_mps2": (0.3, 8.0),
}
QUANTILES: tuple[float, ...] = (0.05, 0.25, 0.5, 0.75, 0.95)
MIN_TRACKS_OWN_COV = 10


def population(fits: Sequence[TrackFit], pooled_cov: FloatArray | None = None) -> dict[str, Any]:
    """Population statistics of some track fits (see the module docstring).

    Args:
        fits: the tracks of one category (>= 1).
        pooled_cov: log-covariance to use when there are fewer than MIN_TRACKS_OWN_COV
            tracks (None: use the own one anyway).
    Returns:
        The POP mapping.
    """
    if not fits:
        raise ValueError("a population needs at least one track")
    vals = np.array([[getattr(f, n) for n in POP_PARAMETERS] for f in fits], dtype=np.float64)
    logs = np.log(vals)
    mean = logs.mean(axis=0)
    own = len(fits) >= MIN_TRACKS_OWN_COV or pooled_cov is None
    if own:
        cov = np.cov(logs, rowvar=False) if len(fits) > 1 else np.zeros((len(POP_PARAMETERS),) * 2)
    else:
        cov = np.asarray(pooled_cov)
    return {
        "n_tracks": len(fits),
        "parameters": list(POP_PARAMETERS),
        "log_mean": mean.tolist(),
        "log_cov": np.atleast_2d(cov).tolist(),
        "covariance_from": "own" if own else "all",
        "median": {n: float(np.median(vals[:, i])) for i, n in enumerate(POP_PARAMETERS)},
        "quantiles": {
            f"{q:g}": {n: float(np.quantile(vals[:, i], q)) for i, n in enumerate(POP_PARAMETERS)}
            for q in QUANTILES
        },
    }


def populations(fits: Sequence[TrackFit]) -> dict[str, dict[str, Any]]:
    """Populations 'all' and one per category present in the fits."""
    out = {"all": population(fits)}
    cov_all = np.asarray(out["all"]["log_cov"])
    for cat in sorted({f.category for f in fits}):
        out[cat] = population([f for f in fits if f.category == cat], cov_all)
    return out


def build_profile(result: FitResult, source: Mapping[str, Any]) -> dict[str, Any]:
    """The profile mapping of a fit (see the module docstring)."""
    v = result.vehicle
    a_n, b_pm = vehicle_values(v)
    return {
        "format": PROFILE_FORMAT,
        "source": dict(source),
        "model": {"mass_kg": MASS_KG, "sigma_m": SIGMA_M, "desired_velocity": "normalised"},
        "vehicle_repulsion": {
            "a_veh_n": a_n,
            "b_veh_per_m": b_pm,
            "identified": v.identified,
            "fitted_a_veh_n": v.a_veh_n,
            "fitted_b_veh_per_m": v.b_veh_per_m,
            "a_ci_n": list(v.a_ci_n),
            "b_ci_per_m": list(v.b_ci_per_m),
            "n_windows": v.n_windows,
            "n_tracks": v.n_tracks,
            "ade_with_m": v.ade_with_m,
            "ade_without_m": v.ade_without_m,
        },
        "populations": populations(result.tracks),
        "tracks": [asdict(f) for f in result.tracks],
    }


def write_profile(path: str | Path, profile: Mapping[str, Any]) -> Path:
    """Write a profile atomically (JSON)."""
    validate_profile(profile, str(path))
    return write_json(path, profile)


def shipped_profile_path() -> Path:
    """Path of the profile shipped with vei (the 'calibrated' rider)."""
    return Path(str(resources.files("vei").joinpath(_SHIPPED_FILE)))


def load_profile(source: str | Path) -> dict[str, Any]:
    """Read and validate a profile file; the name 'calibrated' is the shipped profile.

    Raises InputError naming the file and the field on a malformed profile.
    """
    path = shipped_profile_path() if str(source) == CALIBRATED_PROFILE_NAME else Path(source)
    if not path.is_file():
        raise InputError("rider profile not found (a file or the name 'calibrated')", path=path)
    text = path.read_text(encoding="utf-8")
    try:
        if path.suffix.lower() in (".yaml", ".yml"):
            import yaml

            raw = yaml.safe_load(text)
        else:
            raw = json.loads(text)
    except Exception as exc:  # noqa: BLE001 - json / yaml parse errors
        raise InputError(f"cannot parse the rider profile: {exc}", path=path) from None
    validate_profile(raw, str(path))
    return raw


def validate_profile(raw: Any, where: str) -> None:
    """Check a profile's structure; InputError names the file and field."""
    if not isinstance(raw, Mapping):
        raise InputError("a rider profile must be a mapping", path=where)
    if raw.get("format") != PROFILE_FORMAT:
        raise InputError(
            f"expected format {PROFILE_FORMAT!r}, got {raw.get('format')!r}",
            path=where,
            field="format",
        )
    for key in ("model", "vehicle_repulsion", "populations", "tracks"):
        if key not in raw:
            raise InputError("missing key", path=where, field=key)
    pops = raw["populations"]
    if not isinstance(pops, Mapping) or "all" not in pops:
        raise InputError("needs a population 'all'", path=where, field="populations")
    k = len(POP_PARAMETERS)
    for name, pop in pops.items():
        f = f"populations.{name}"
        if not isinstance(pop, Mapping):
            raise InputError("expected a mapping", path=where, field=f)
        if list(pop.get("parameters", [])) != list(POP_PARAMETERS):
            raise InputError(
                f"parameters must be {list(POP_PARAMETERS)}", path=where, field=f"{f}.parameters"
            )
        mean = np.asarray(pop.get("log_mean", []), dtype=np.float64)
        cov = np.asarray(pop.get("log_cov", []), dtype=np.float64)
        if mean.shape != (k,) or not np.all(np.isfinite(mean)):
            raise InputError(f"expected {k} finite numbers", path=where, field=f"{f}.log_mean")
        if cov.shape != (k, k) or not np.all(np.isfinite(cov)) or not np.allclose(cov, cov.T):
            raise InputError(
                f"expected a symmetric {k}x{k} matrix", path=where, field=f"{f}.log_cov"
            )
        if np.linalg.eigvalsh(cov).min() < -1e-9:
            raise InputError(
                "covariance is not positive semi-definite", path=where, field=f"{f}.log_cov"
            )
    rep = raw["vehicle_repulsion"]
    for key in ("a_veh_n", "b_veh_per_m"):
        v = rep.get(key) if isinstance(rep, Mapping) else None
        if not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
            raise InputError("expected a number >= 0", path=where, field=f"vehicle_repulsion.{key}")


def _population(profile: Mapping[str, Any], category: str) -> Mapping[str, Any]:
    pops = profile["populations"]
    return pops[category] if category in pops else pops["all"]


def sample_population(
    profile: Mapping[str, Any], n: int, *, category: str = "escooter", seed: int = 0
) -> dict[str, FloatArray]:
    """Draw n riders from a profile's population (log-normal, clipped to SAMPLE_BOUNDS).

    Args:
        profile: a loaded profile. n: number of riders (>= 1).
        category: 'escooter', 'cyclist' or 'all' (a category the profile lacks uses 'all').
        seed: numpy Generator seed; the same seed gives the same riders.
    Returns:
        VariantParams-ready arrays [n]: v0_mps, k_des_nspm, mass_kg, sigma_m, lookahead_m,
        max_speed_mps, max_accel_mps2, a_veh_n, b_veh_per_m; and tau_s.
    """
    if n < 1:
        raise InputError(f"sample must be >= 1, got {n}", field="sample")
    pop = _population(profile, category)
    mean = np.asarray(pop["log_mean"], dtype=np.float64)
    cov = np.asarray(pop["log_cov"], dtype=np.float64)
    rng = np.random.default_rng(seed)
    z = rng.multivariate_normal(mean, cov, size=n, method="eigh")
    vals = {
        name: np.clip(np.exp(z[:, i]), *SAMPLE_BOUNDS[name])
        for i, name in enumerate(POP_PARAMETERS)
    }
    return _to_params(profile, vals, n)


def _to_params(
    profile: Mapping[str, Any], vals: Mapping[str, FloatArray], n: int
) -> dict[str, FloatArray]:
    mass = float(profile["model"].get("mass_kg", MASS_KG))
    rep = profile["vehicle_repulsion"]
    return {
        "v0_mps": np.asarray(vals["v0_mps"], dtype=np.float64),
        "tau_s": np.asarray(vals["tau_s"], dtype=np.float64),
        "k_des_nspm": mass / np.asarray(vals["tau_s"], dtype=np.float64),
        "mass_kg": np.full(n, mass),
        "sigma_m": np.full(n, float(profile["model"].get("sigma_m", SIGMA_M))),
        "lookahead_m": np.asarray(vals["lookahead_m"], dtype=np.float64),
        "max_speed_mps": np.asarray(vals["max_speed_mps"], dtype=np.float64),
        "max_accel_mps2": np.asarray(vals["max_accel_mps2"], dtype=np.float64),
        "a_veh_n": np.full(n, float(rep["a_veh_n"])),
        "b_veh_per_m": np.full(n, float(rep["b_veh_per_m"])),
    }


def population_params(
    profile: Mapping[str, Any], vals: Mapping[str, FloatArray], n: int
) -> dict[str, FloatArray]:
    """VariantParams-ready arrays [n] of n riders given their population parameters.

    Args:
        profile: a loaded profile. vals: {POP_PARAMETERS name: [n] values} (already in
            SAMPLE_BOUNDS). n: number of riders.
    Returns:
        As :func:`sample_population` (k_des_nspm = mass / tau; A, b, mass, sigma the
        profile's).
    """
    return _to_params(profile, vals, n)


def cruise_v0_mps(
    cruise_speed_mps: npt.ArrayLike, lookahead_m: npt.ArrayLike, sigma_m: float
) -> FloatArray:
    """v0 whose normalised desired speed at the look-ahead distance equals the cruise speed."""
    la = np.asarray(lookahead_m, dtype=np.float64)
    return np.asarray(cruise_speed_mps, dtype=np.float64) * np.sqrt(la * la + sigma_m**2) / la


def params_for_recorded_rider(
    profile: Mapping[str, Any],
    category: str,
    median_moving_speed_mps: float,
    speed_p99_mps: float,
) -> dict[str, float]:
    """SFM parameters for one recorded rider (the rule of the module docstring).

    Args:
        profile: a loaded profile. category: the rider's category.
        median_moving_speed_mps: its recorded median speed while moving [m/s].
        speed_p99_mps: the 99th percentile of its recorded speed [m/s].
    Returns:
        Scalars: v0_mps, k_des_nspm, mass_kg, sigma_m, lookahead_m, max_speed_mps,
        max_accel_mps2, a_veh_n, b_veh_per_m, tau_s.
    """
    med = _population(profile, category)["median"]
    vals = {n: np.array([float(med[n])]) for n in POP_PARAMETERS}
    sigma = float(profile["model"].get("sigma_m", SIGMA_M))
    vals["v0_mps"] = cruise_v0_mps(
        np.array([max(median_moving_speed_mps, 0.2)]), vals["lookahead_m"], sigma
    )
    vals["max_speed_mps"] = np.array([max(speed_p99_mps, median_moving_speed_mps, 0.5)])
    return {k: float(v[0]) for k, v in _to_params(profile, vals, 1).items()}
