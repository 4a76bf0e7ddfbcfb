"""Encounter finding: which riders of a reconstructed recording meet the car.

A recording (one reconstructed scenario) holds the ego car and every annotated rider
(e-scooter, cyclist). Each rider is scored against the ego's recorded motion:

- ``path_distance_m``: the smallest distance from any sample of the rider's path to the
  ego's path (any time): how close the two *routes* come;
- ``pet_s``: at the rider sample closest to the ego path, ``|t_rider - t_ego|`` where
  ``t_ego`` is when the ego passed the nearest point of its path: the post-encroachment
  time at the routes' closest point (small = they were there at nearly the same time);
- ``min_gap_m`` and ``t_closest_s``: the smallest centre-to-centre distance while both are
  present, and when (inf / NaN if they never coexist);
- ``crossing_angle_deg``: angle in [0, 180] between the rider's and the ego's direction
  of motion at the routes' closest point (0 = same direction, 90 = crossing, 180 = head-on).

**Rule** (:class:`EncounterRule`, documented in docs/catalogue.md): a rider is an
encounter when its route comes within ``path_distance_max_m`` (5 m) of the ego's route and
``pet_s <= pet_max_s`` (30 s), or when it comes within ``gap_max_m`` (10 m) of the car at
the same time. The first clause catches riders whose route a time shift turns into a
collision course; the second riders passing the car closely on a parallel route. Riders
further away are context (drawn in the report, never simulated).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
from scipy.spatial import cKDTree

from vei.errors import ConfigError
from vei.types import EGO_ID, Scenario

#: Categories that can be the rider of an encounter.
RIDER_CATEGORIES: tuple[str, ...] = ("escooter", "cyclist")


@dataclass(frozen=True)
class EncounterRule:
    """When a rider counts as an encounter with the car (see the module docstring).

    Attributes:
        path_distance_max_m: routes within this distance [m] ...
        pet_max_s: ... and post-encroachment time at the routes' closest point at most this [s];
        gap_max_m: or a same-time centre distance at most this [m].
        categories: rider categories considered.
    """

    path_distance_max_m: float = 5.0
    pet_max_s: float = 30.0
    gap_max_m: float = 10.0
    categories: tuple[str, ...] = RIDER_CATEGORIES

    def __post_init__(self) -> None:
        cats = self.categories
        if isinstance(cats, str):  # a lone name is a one-element tuple, not its characters
            object.__setattr__(self, "categories", (cats,))
        elif isinstance(cats, list | tuple):
            object.__setattr__(self, "categories", tuple(cats))
        else:
            raise ConfigError(f"encounter rule: categories must be a list of names, got {cats!r}")
        for name in ("path_distance_max_m", "pet_max_s", "gap_max_m"):
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, int | float)
                or not math.isfinite(v)
                or v < 0
            ):
                raise ConfigError(f"encounter rule: {name} must be a finite number >= 0, got {v!r}")
        if not self.categories or any(c not in RIDER_CATEGORIES for c in self.categories):
            raise ConfigError(
                f"encounter rule: categories must be a non-empty subset of {RIDER_CATEGORIES}, "
                f"got {self.categories!r}"
            )

    def matches(self, enc: Encounter) -> bool:
        """Whether the figures of ``enc`` make it an encounter under this rule."""
        route = enc.path_distance_m <= self.path_distance_max_m and enc.pet_s <= self.pet_max_s
        return bool(route or enc.min_gap_m <= self.gap_max_m)


@dataclass(frozen=True)
class Encounter:
    """One car-rider encounter of a recording (figures of the recorded motion).

    Attributes:
        encounter_id: '<recording>__<rider_id>' (unique within a dataset).
        recording: recording (scenario) id. rider_id: the rider's agent id. category: its category.
        path_distance_m, pet_s, min_gap_m, t_closest_s, crossing_angle_deg: see the module docstring.
        ego_speed_mps: ego speed when the ego passes the routes' closest point [m/s].
        rider_speed_mps: rider's median speed over its track [m/s].
        rider_t_start_s, rider_t_end_s: when the rider is seen [s since the recording start].
    """

    encounter_id: str
    recording: str
    rider_id: str
    category: str
    path_distance_m: float
    pet_s: float
    min_gap_m: float
    t_closest_s: float
    crossing_angle_deg: float
    ego_speed_mps: float
    rider_speed_mps: float
    rider_t_start_s: float
    rider_t_end_s: float

    def as_dict(self) -> dict:
        """Plain dict (JSON-safe: inf/NaN -> None)."""
        out = {}
        for k, v in asdict(self).items():
            out[k] = None if isinstance(v, float) and not math.isfinite(v) else v
        return out

    @classmethod
    def from_dict(cls, d: dict) -> Encounter:
        """Inverse of :meth:`as_dict` (None -> inf for distances/times, NaN for the rest)."""
        vals = dict(d)
        for k in ("path_distance_m", "pet_s", "min_gap_m"):
            vals[k] = math.inf if vals.get(k) is None else float(vals[k])
        for k in (
            "t_closest_s",
            "crossing_angle_deg",
            "ego_speed_mps",
            "rider_speed_mps",
            "rider_t_start_s",
            "rider_t_end_s",
        ):
            vals[k] = math.nan if vals.get(k) is None else float(vals[k])
        return cls(**vals)


def rider_figures(scenario: Scenario, rider_id: str) -> Encounter:
    """Encounter figures of one rider of ``scenario`` against its ego (recorded motion).

    Uses the scenario's trajectories (t_s on the simulation grid; x_m, y_m in the plane;
    yaw_rad; speed_mps): ego [M samples], rider [N samples].
    """
    ego = scenario.track(EGO_ID)
    rider = scenario.track(rider_id)
    category = scenario.agent(rider_id).category
    e_xy = ego[["x_m", "y_m"]].to_numpy(np.float64)
    r_xy = rider[["x_m", "y_m"]].to_numpy(np.float64)
    e_t = ego["t_s"].to_numpy(np.float64)
    r_t = rider["t_s"].to_numpy(np.float64)
    nan = math.nan
    if len(e_xy) == 0 or len(r_xy) == 0:
        return Encounter(
            f"{scenario.id}__{rider_id}", scenario.id, rider_id, category,
            math.inf, math.inf, math.inf, nan, nan, nan, nan, nan, nan,
        )  # fmt: skip
    dist, idx = cKDTree(e_xy).query(r_xy)
    k = int(np.argmin(dist))
    path_d = float(dist[k])
    ek = int(idx[k])
    pet = float(abs(r_t[k] - e_t[ek]))
    d_yaw = float(rider["yaw_rad"].iloc[k] - ego["yaw_rad"].iloc[ek])
    angle = abs(math.degrees(math.atan2(math.sin(d_yaw), math.cos(d_yaw))))
    common, ri, ei = np.intersect1d(np.round(r_t, 6), np.round(e_t, 6), return_indices=True)
    if common.size:
        gap = np.hypot(*(r_xy[ri] - e_xy[ei]).T)
        j = int(np.argmin(gap))
        min_gap, t_close = float(gap[j]), float(common[j])
    else:
        min_gap, t_close = math.inf, nan
    return Encounter(
        encounter_id=f"{scenario.id}__{rider_id}",
        recording=scenario.id,
        rider_id=rider_id,
        category=category,
        path_distance_m=path_d,
        pet_s=pet,
        min_gap_m=min_gap,
        t_closest_s=t_close,
        crossing_angle_deg=angle,
        ego_speed_mps=float(ego["speed_mps"].iloc[ek]),
        rider_speed_mps=float(np.median(rider["speed_mps"].to_numpy())),
        rider_t_start_s=float(r_t[0]),
        rider_t_end_s=float(r_t[-1]),
    )


def find_encounters(
    scenario: Scenario, rule: EncounterRule | None = None
) -> tuple[list[Encounter], list[Encounter]]:
    """Every rider of ``scenario`` scored; returns (encounters, others), each sorted by
    (pet_s, min_gap_m, rider_id) resp. (path_distance_m, rider_id)."""
    rule = rule or EncounterRule()
    found, others = [], []
    for agent in scenario.agents:
        if agent.category not in rule.categories:
            continue
        enc = rider_figures(scenario, agent.agent_id)
        (found if rule.matches(enc) else others).append(enc)
    found.sort(key=lambda e: (e.pet_s, e.min_gap_m, e.rider_id))
    others.sort(key=lambda e: (e.path_distance_m, e.rider_id))
    return found, others
