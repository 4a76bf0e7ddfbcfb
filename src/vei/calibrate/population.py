"""Rider populations in runs and sweeps: N riders sampled from a rider profile.

``rider: {profile: FILE | calibrated, sample: N, category: escooter, seed: 0}``
(:class:`vei.config.RiderPopulationConfig`) turns one social-force configuration into N
riders: each gets its own v0, k_des (= mass / tau), look-ahead, speed and acceleration
limits drawn from the profile population (:func:`vei.calibrate.profile.sample_population`);
A and b are the profile's. A rider's vehicle force switch and k_des factor stay the case's
(so an Aggressive configuration keeps f_veh off and its k_des amplification). Where the
case's riders decide (``decision.enabled``) each gets its own critical gap, drawn from the
gap-acceptance fit's logistic (:func:`sample_critical_gaps`): some riders hardly ever yield.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace
from typing import Any

import numpy as np
import numpy.typing as npt
import pandas as pd

# The column names live in a light module (no scipy): every sweep worker imports them.
from vei.calibrate.columns import POPULATION_FIELDS as POPULATION_FIELDS
from vei.calibrate.columns import POPULATION_SET as POPULATION_SET
from vei.calibrate.columns import RIDER_COLUMN as RIDER_COLUMN
from vei.calibrate.columns import RIDER_PARAM_COLUMNS as RIDER_PARAM_COLUMNS
from vei.config import CaseConfig, RiderPopulationConfig, load_config
from vei.errors import ConfigError

FloatArray = npt.NDArray[np.float64]


def parse_population(raw: Any, where: str, default_seed: Any = 0) -> RiderPopulationConfig | None:
    """``rider: {profile, sample[, category, seed]}`` of a file -> the population (or None).

    Args:
        raw: the mapping (None: no population). where: file name for messages.
        default_seed: the seed when the mapping has none (a sweep spec's own seed).
    Raises:
        ConfigError naming the file and the key.
    """
    if raw is None:
        return None
    if not isinstance(raw, Mapping):
        raise ConfigError(
            f"{where}: 'rider' must be a mapping like {{profile: calibrated, sample: 50}}"
        )
    raw = dict(raw)
    if "sample" not in raw:
        raise ConfigError(f"{where}: rider: missing 'sample' (number of riders)")
    if "seed" not in raw and isinstance(default_seed, int) and not isinstance(default_seed, bool):
        raw["seed"] = default_seed
    try:
        return load_config(raw, RiderPopulationConfig)
    except ConfigError as exc:
        raise ConfigError(f"{where}: rider: {exc}".replace("config: ", "")) from None


def with_population(points: pd.DataFrame, pop: RiderPopulationConfig) -> pd.DataFrame:
    """Every row of a design repeated for the N riders (RIDER_COLUMN, RIDER_PARAM_COLUMNS).

    Args:
        points: [P rows] design points. pop: the population.
    Returns:
        [P * N rows]: row p * N + i is point p with rider i (the same N riders for every
        point, seeded).
    """
    n = pop.sample
    riders = sample_riders(pop)
    out = points.loc[points.index.repeat(n)].reset_index(drop=True)
    reps = len(out) // n
    out[RIDER_COLUMN] = np.tile(np.arange(n, dtype=np.int64), reps)
    for col, fname in RIDER_PARAM_COLUMNS.items():
        out[col] = np.tile(riders[fname].astype(np.float64), reps)
    return out


def sample_riders(pop: RiderPopulationConfig) -> dict[str, FloatArray]:
    """The population's N riders as arrays [N] (POPULATION_FIELDS and tau_s), seeded."""
    # profile -> fit -> scipy: imported when a population is sampled, not by every sweep
    from vei.calibrate.profile import load_profile, sample_population

    profile = load_profile(pop.profile)
    return sample_population(profile, pop.sample, category=pop.category, seed=pop.seed)


def population_cases(case: CaseConfig, pop: RiderPopulationConfig) -> list[CaseConfig]:
    """N copies of a social-force configuration, one per sampled rider.

    Names are ``<case.name>#<i>`` (i = 0 .. N-1); each SFMConfig holds the rider's own
    parameters (speed_from_recording off: the sampled v0 is the rider's).
    """
    if case.rider != "sfm":
        raise ConfigError(f"configuration {case.name!r}: a rider population needs rider 'sfm'")
    s = sample_riders(pop)
    gaps = sample_critical_gaps(case.decision, pop.sample, pop.seed)  # decisions: their spread
    out = []
    for i in range(pop.sample):
        sfm = replace(
            case.sfm,
            v0_mps=float(s["v0_mps"][i]),
            k_des_nspm=float(s["k_des_nspm"][i]),
            mass_kg=float(s["mass_kg"][i]),
            sigma_m=float(s["sigma_m"][i]),
            lookahead_m=float(s["lookahead_m"][i]),
            max_speed_mps=float(s["max_speed_mps"][i]),
            max_accel_mps2=float(s["max_accel_mps2"][i]),
            a_veh_n=float(s["a_veh_n"][i]),
            b_veh_per_m=float(s["b_veh_per_m"][i]),
            speed_from_recording=False,
        )
        dec = (
            replace(case.decision, critical_gap_s=float(gaps[i]))
            if gaps is not None
            else case.decision
        )
        out.append(replace(case, name=f"{case.name}#{i}", sfm=sfm, decision=dec))
    return out


def sample_critical_gaps(decision: Any, n: int, seed: int) -> FloatArray | None:
    """[N] critical gaps [s] of a rider population that decides (``decision.enabled``):
    logistic with location ``decision.critical_gap_s`` and scale ``decision.gap_scale_s``
    (the gap-acceptance fit's spread: ``P(t_c < DTA)`` is the population's go
    probability), within the setting's bounds [-30, 30] s; seeded apart from the SFM
    draws. None where the riders do not decide."""
    if not decision.enabled:
        return None
    u = np.random.default_rng([seed, 24]).uniform(1e-9, 1.0 - 1e-9, n)
    t_c = decision.critical_gap_s + decision.gap_scale_s * np.log(u / (1.0 - u))
    return np.clip(t_c, -30.0, 30.0)
