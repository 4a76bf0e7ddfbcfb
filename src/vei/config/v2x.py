"""Configuration of V2X (vei.policy.v2x): riders that announce themselves, a car that listens.

:class:`V2XConfig` lives on the config layer so that :class:`vei.config.CaseConfig` holds
and checks it; the model is :mod:`vei.policy.v2x`. Every default names its source in
docs/v2x.md; the ones that are this project's own calculation or assumption say so there.

Imports nothing of vei but errors (a configuration module: see DESIGN.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from vei.errors import ConfigError

Technology = Literal["its-g5", "c-v2x-pc5"]
LatencyDistribution = Literal["exponential", "uniform"]
Environment = Literal["urban", "highway"]
TECHNOLOGIES: tuple[str, ...] = ("its-g5", "c-v2x-pc5")
LATENCY_DISTRIBUTIONS: tuple[str, ...] = ("exponential", "uniform")
#: Road-user categories that may carry a V2X device (send VAMs).
SENDER_CATEGORIES: tuple[str, ...] = ("escooter", "cyclist", "pedestrian")

#: Link environments of 3GPP TR 37.885 Table 6.2.1-1 (the LOS path-loss law of V2V links).
ENVIRONMENTS: tuple[str, ...] = ("urban", "highway")
#: Default latency of each technology: (fixed part [s], random part [s], distribution).
#: ITS-G5: 1 ms on air and through the receive path plus an exponential channel-access
#: wait of mean 2 ms (mean 3 ms). LTE-V2X PC5: 1 ms plus a uniform wait for its resource of
#: up to 44 ms (mean 23 ms: ITS-G5's 3 ms plus the 20 ms by which Cimoli et al. 2022
#: measured PC5 slower in the field); docs/v2x.md.
DEFAULT_LATENCY: dict[str, tuple[float, float, str]] = {
    "its-g5": (0.001, 0.002, "exponential"),
    "c-v2x-pc5": (0.001, 0.044, "uniform"),
}


def _num(name: str, value: Any, *, lo: float | None = None, lo_open: bool = False,
         hi: float | None = None) -> float:  # fmt: skip
    if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
        raise ConfigError(f"v2x.{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f"v2x.{name} must be finite, got {value!r}")
    if lo is not None and (value <= lo if lo_open else value < lo):
        raise ConfigError(f"v2x.{name} must be {'>' if lo_open else '>='} {lo:g}, got {value!r}")
    if hi is not None and value > hi:
        raise ConfigError(f"v2x.{name} must be <= {hi:g}, got {value!r}")
    return value


def _table(name: str, value: Any) -> tuple[float, ...]:
    if isinstance(value, str) or not isinstance(value, list | tuple | np.ndarray):
        raise ConfigError(f"v2x.{name} must be a list of numbers, got {value!r}")
    out = tuple(_num(f"{name}[{i}]", v) for i, v in enumerate(value))
    if not out:
        raise ConfigError(f"v2x.{name} must not be empty")
    return out


def check_pdr_table(distance_m: Any, pdr: Any) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """Validate a packet-delivery table: PDR(distance) non-increasing, values in [0, 1].

    Args:
        distance_m: distances [m], >= 0, strictly increasing. pdr: delivery ratios there.
    Returns:
        (distance_m, pdr) as tuples of floats.
    Raises:
        ConfigError: naming ``v2x.pdr_distance_m`` / ``v2x.pdr`` and the offending entry.
    """
    d = _table("pdr_distance_m", distance_m)
    p = _table("pdr", pdr)
    if len(d) != len(p):
        raise ConfigError(
            f"v2x.pdr has {len(p)} values but v2x.pdr_distance_m has {len(d)}: give one "
            "delivery ratio per distance"
        )
    for i, v in enumerate(d):
        if v < 0:
            raise ConfigError(f"v2x.pdr_distance_m[{i}] must be >= 0, got {v!r}")
        if i and v <= d[i - 1]:
            raise ConfigError(
                f"v2x.pdr_distance_m must increase strictly: {v:g} m at [{i}] after {d[i - 1]:g} m"
            )
    for i, v in enumerate(p):
        if not 0.0 <= v <= 1.0:
            raise ConfigError(f"v2x.pdr[{i}] must be in [0, 1], got {v!r}")
        if i and v > p[i - 1]:
            raise ConfigError(
                f"v2x.pdr must not increase with distance: {v:g} at {d[i]:g} m after "
                f"{p[i - 1]:g} at {d[i - 1]:g} m (v2x.pdr[{i}])"
            )
    return d, p


@dataclass(frozen=True)
class V2XConfig:
    """V2X: VRU awareness messages (VAM) from equipped riders to the car (frozen, validated).

    ``enabled=False`` (default): no V2X, the car perceives with its own sensor only. The
    numbers marked *sweepable* are also per-variant engine settings
    (:data:`vei.config.settings.SETTINGS`, ``v2x.<name>``).

    Attributes:
        enabled: riders send VAMs and the car fuses them with its perception.
        technology: 'its-g5' (ETSI ITS-G5 / DSRC, IEEE 802.11p) or 'c-v2x-pc5' (LTE-V2X
            sidelink mode 4): picks the link budget and the default latency.
        seed: seed of every V2X draw (equipped riders, GNSS error, delivery, latency,
            blockage loss), with the variant's key.
        penetration_rate: share of riders equipped, [0, 1], drawn per rider and variant
            (sweepable). Default 1.
        sender_categories: the categories that may carry a device. Default e-scooters and
            cyclists.
        t_gen_vam_min_s, t_gen_vam_max_s: T_GenVamMin / T_GenVamMax [s] (ETSI TS 103 300-3
            clause 6.2, Table 16: 0.1 / 5.0).
        t_check_vam_gen_s: T_CheckVamGen [s], the period of the generation checks,
            <= T_GenVamMin (clause 6.2). Default 0.1.
        position_threshold_m, speed_threshold_mps, heading_threshold_deg: the position,
            ground-speed and heading change that trigger a VAM (clause 6.4.1, Table 17:
            4 m, 0.5 m/s, 4 deg).
        position_error_std_m: GNSS error of the rider's device, per axis (1 sigma) [m]
            (sweepable). Default 3.23 (a dual-frequency smartphone: docs/v2x.md).
        position_error_tau_s: correlation time of that error (first-order Gauss-Markov)
            [s], > 0. Default 60.
        clock_offset_s: the device clock minus true time [s] (sweepable): a message's time
            stamp is its generation time plus this. Default 0.
        environment: 'urban' (default) or 'highway': the LOS path-loss law of V2V links
            (3GPP TR 37.885 Table 6.2.1-1); NLOSv adds the vehicle blockage to it, NLOS
            (buildings) is urban's.
        rider_antenna_height_m, car_antenna_height_m: antenna heights [m] (> 0): they
            pick the blockage case of TR 37.885 clause 6.2.1 against the blocker's height.
            Defaults 1.5 (TR 37.885 Table 6.1.4-1, a pedestrian UE) and 1.6 (clause 6.1.2,
            vehicle type 2, roof antenna).
        truck_min_length_m: a blocking vehicle box longer than this [m] is a truck, bus or
            van (blocker height 3 m, TR 37.885 vehicle type 3), a shorter one a passenger
            vehicle (1.6 m). Default 5.5 (the TR's passenger vehicle is 5 m long).
        pdr_distance_m, pdr: a measured delivery table of line-of-sight links (delivery
            ratio against the rider-car distance, linear in between, held beyond the ends)
            in place of the link budget; a blocked link is read at ``d 10^(L /
            pdr_slope_db_per_decade)`` (L its extra loss over LOS). None (default): the
            link budget of TR 37.885's path loss (vei.policy.v2x.channel). Given, both
            together: distances strictly increasing, ratios in [0, 1] and non-increasing.
        pdr_factor: multiplies every delivery ratio, [0, 1] (sweepable): the share of
            packets that survive channel load (interference, congestion), which the link
            budget leaves out. Default 1.
        nlos: links blocked by a vehicle's box (not the sender's) take the vehicle
            blockage loss (NLOSv). Default True.
        buildings: links blocked by a building of the scenario's map (OpenStreetMap
            outlines, where it has them) take the NLOS path loss. Default True.
        nlos_loss_db, nlos_loss_std_db: a fixed blockage loss L ~ max(0, N(mean, std))
            [dB] for every NLOSv link instead of TR 37.885's by case (antenna and blocker
            heights); None (default): the TR's. Given, both together.
        pdr_slope_db_per_decade: the slope that turns an extra loss into distance on a
            given delivery table [dB per decade of distance]; None (default): the LOS
            law's (16.7 urban, 20 highway).
        latency_s: fixed part of the latency [s] (sweepable); None = the technology's.
        latency_jitter_s: scale of its random part [s] (the exponential's mean or the
            uniform's width) (sweepable); None = the technology's.
        latency_distribution: 'exponential' or 'uniform'; None = the technology's.
        max_track_age_s: the car drops a V2X track whose last message is older than this
            [s] (> 0). Default 10.2: 2 x (T_GenVamMax + T_CheckVamGen), one lost VAM of a
            standing rider (it sends every 5.1 s) is bridged.
        policies_use_v2x: the built-in policies (none, paper-cap, aeb, idm) act on V2X
            objects; False = they see only their sensor's (V2X still in the observation
            of user policies). Default True.
    """

    enabled: bool = False
    technology: Technology = "its-g5"
    seed: int = 0
    penetration_rate: float = 1.0
    sender_categories: tuple[str, ...] = ("escooter", "cyclist")
    t_gen_vam_min_s: float = 0.1
    t_gen_vam_max_s: float = 5.0
    t_check_vam_gen_s: float = 0.1
    position_threshold_m: float = 4.0
    speed_threshold_mps: float = 0.5
    heading_threshold_deg: float = 4.0
    position_error_std_m: float = 3.23
    position_error_tau_s: float = 60.0
    clock_offset_s: float = 0.0
    environment: Environment = "urban"
    rider_antenna_height_m: float = 1.5
    car_antenna_height_m: float = 1.6
    truck_min_length_m: float = 5.5
    pdr_distance_m: tuple[float, ...] | None = None
    pdr: tuple[float, ...] | None = None
    pdr_factor: float = 1.0
    nlos: bool = True
    buildings: bool = True
    nlos_loss_db: float | None = None
    nlos_loss_std_db: float | None = None
    pdr_slope_db_per_decade: float | None = None
    latency_s: float | None = None
    latency_jitter_s: float | None = None
    latency_distribution: LatencyDistribution | None = None
    max_track_age_s: float = 10.2
    policies_use_v2x: bool = True

    def __post_init__(self) -> None:
        for name in ("enabled", "nlos", "buildings", "policies_use_v2x"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"v2x.{name} must be true or false, got {getattr(self, name)!r}")
        if self.technology not in TECHNOLOGIES:
            raise ConfigError(
                f"v2x.technology must be one of {', '.join(TECHNOLOGIES)}, got {self.technology!r}"
            )
        seed = self.seed
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
            raise ConfigError(f"v2x.seed must be an integer, got {seed!r}")
        object.__setattr__(self, "seed", int(seed))
        cats = self.sender_categories
        if isinstance(cats, str) or not isinstance(cats, list | tuple):
            raise ConfigError(f"v2x.sender_categories must be a list, got {cats!r}")
        bad = [c for c in cats if c not in SENDER_CATEGORIES]
        if bad:
            raise ConfigError(
                f"v2x.sender_categories: unknown {', '.join(map(repr, bad))}; expected some "
                f"of {', '.join(SENDER_CATEGORIES)}"
            )
        object.__setattr__(self, "sender_categories", tuple(cats))
        unit = {"lo": 0.0, "hi": 1.0}
        pos = {"lo": 0.0, "lo_open": True}
        checked: dict[str, dict[str, Any]] = {
            "penetration_rate": unit,
            "t_gen_vam_min_s": pos,
            "t_gen_vam_max_s": pos,
            "t_check_vam_gen_s": pos,
            "position_threshold_m": {"lo": 0.0},
            "speed_threshold_mps": {"lo": 0.0},
            "heading_threshold_deg": {"lo": 0.0, "hi": 180.0},
            "position_error_std_m": {"lo": 0.0},
            "position_error_tau_s": pos,
            "clock_offset_s": {},
            "pdr_factor": unit,
            "rider_antenna_height_m": pos,
            "car_antenna_height_m": pos,
            "truck_min_length_m": pos,
            "max_track_age_s": pos,
        }
        for name, bounds in checked.items():
            object.__setattr__(self, name, _num(name, getattr(self, name), **bounds))
        for name in ("latency_s", "latency_jitter_s", "nlos_loss_db", "nlos_loss_std_db"):
            if getattr(self, name) is not None:
                object.__setattr__(self, name, _num(name, getattr(self, name), lo=0.0))
        if self.pdr_slope_db_per_decade is not None:
            object.__setattr__(self, "pdr_slope_db_per_decade",
                               _num("pdr_slope_db_per_decade", self.pdr_slope_db_per_decade,
                                    lo=0.0, lo_open=True))  # fmt: skip
        if (self.nlos_loss_db is None) != (self.nlos_loss_std_db is None):
            raise ConfigError(
                "v2x.nlos_loss_db and v2x.nlos_loss_std_db go together: give both (a fixed "
                "blockage loss) or neither (3GPP TR 37.885's by antenna and blocker heights)"
            )
        if self.environment not in ENVIRONMENTS:
            raise ConfigError(
                f"v2x.environment must be one of {', '.join(ENVIRONMENTS)}, got {self.environment!r}"
            )
        if self.latency_distribution is not None and (
            self.latency_distribution not in LATENCY_DISTRIBUTIONS
        ):
            raise ConfigError(
                f"v2x.latency_distribution must be one of {', '.join(LATENCY_DISTRIBUTIONS)} "
                f"(or null for the technology's), got {self.latency_distribution!r}"
            )
        if self.t_gen_vam_max_s < self.t_gen_vam_min_s:
            raise ConfigError(
                f"v2x.t_gen_vam_max_s ({self.t_gen_vam_max_s:g}) must be >= v2x.t_gen_vam_min_s "
                f"({self.t_gen_vam_min_s:g})"
            )
        if self.t_check_vam_gen_s > self.t_gen_vam_min_s + 1e-12:
            raise ConfigError(
                f"v2x.t_check_vam_gen_s ({self.t_check_vam_gen_s:g}) must be <= "
                f"v2x.t_gen_vam_min_s ({self.t_gen_vam_min_s:g}) (TS 103 300-3 clause 6.2)"
            )
        if (self.pdr_distance_m is None) != (self.pdr is None):
            raise ConfigError(
                "v2x.pdr_distance_m and v2x.pdr go together: give both (a measured table) or "
                "neither (the link budget of 3GPP TR 37.885)"
            )
        if self.pdr is not None:
            d, p = check_pdr_table(self.pdr_distance_m, self.pdr)
            object.__setattr__(self, "pdr_distance_m", d)
            object.__setattr__(self, "pdr", p)

    @property
    def pdr_table(self) -> tuple[tuple[float, ...], tuple[float, ...]] | None:
        """(distances [m], delivery ratios) of a given delivery table, or None (the link
        budget)."""
        if self.pdr is not None and self.pdr_distance_m is not None:
            return self.pdr_distance_m, self.pdr
        return None

    def default_for(self, name: str) -> float:
        """The value a None field stands for: ``latency_s`` / ``latency_jitter_s`` of the
        technology (vei.config.settings conversion 'none_is_default')."""
        fixed, jitter, _ = self.latency
        values = {"latency_s": fixed, "latency_jitter_s": jitter}
        if name not in values:
            raise ConfigError(f"v2x.{name} has no technology default")
        return values[name]

    @property
    def latency(self) -> tuple[float, float, str]:
        """(fixed part [s], random part's scale [s], distribution) in use."""
        fixed, jitter, dist = DEFAULT_LATENCY[self.technology]
        return (
            fixed if self.latency_s is None else float(self.latency_s),
            jitter if self.latency_jitter_s is None else float(self.latency_jitter_s),
            dist if self.latency_distribution is None else str(self.latency_distribution),
        )


__all__ = [
    "DEFAULT_LATENCY",
    "ENVIRONMENTS",
    "LATENCY_DISTRIBUTIONS",
    "SENDER_CATEGORIES",
    "TECHNOLOGIES",
    "V2XConfig",
    "check_pdr_table",
]
