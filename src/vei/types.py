"""Core data types shared across vei. Imports nothing of vei but errors.

Tables are pandas DataFrames with documented columns (units in the names); frames that
the engine uses become NumPy arrays with a leading batch axis inside ``vei.sim``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import Literal

import pandas as pd

#: Road-user categories of the interaction format (annotations and ground truth).
CATEGORIES: tuple[str, ...] = ("escooter", "cyclist", "pedestrian", "vehicle")
#: Categories that get the rider (social-force) models and can be the primary threat.
RIDER_CATEGORIES: tuple[str, ...] = ("escooter", "cyclist")
#: Category of the ego vehicle in scenario trajectories.
EGO_CATEGORY = "ego"
#: agent_id of the ego vehicle in scenario trajectories.
EGO_ID = "ego"

YAxis = Literal["left", "right"]
#: Frames of an interaction's annotations: 'ego' (ego-relative offsets, the paper's data) or
#: 'world' (each road user's own latitude/longitude, as drone and infrastructure datasets
#: record them; docs/interaction-format.md).
AnnotationFrame = Literal["ego", "world"]

#: Default footprints per category [m] (length, width): sedan, e-scooter with rider, ...
DEFAULT_DIMENSIONS_M: dict[str, tuple[float, float]] = {
    EGO_CATEGORY: (4.7, 1.85),
    "vehicle": (4.7, 1.85),
    "escooter": (1.2, 0.6),
    "cyclist": (1.8, 0.6),
    "pedestrian": (0.5, 0.5),
}


@dataclass(frozen=True)
class InteractionMeta:
    """Contents of ``interaction.json`` (format ``vei.interaction/1``).

    Attributes:
        id: identifier of the interaction.
        source: where it comes from (dataset, recording).
        start_time_utc: absolute time of t_s = 0 (timezone-aware, UTC).
        y_axis: which way the annotations' lateral axis points ('left' = ISO 8855).
        annotation_rate_hz: nominal annotation rate [Hz], if declared.
        notes: free text.
        frame: 'ego' (annotations are ego-relative x_m / y_m) or 'world' (annotations are
            lat_deg / lon_deg world positions; y_axis then plays no part).
        origin_lat_deg, origin_lon_deg: 'world' only, optional: origin [deg] of the local
            plane the reconstruction must use (so that a map written for that plane by an
            importer is used unchanged); None = the centre of the data's bounds.
    """

    id: str
    source: str
    start_time_utc: datetime
    y_axis: YAxis = "left"
    annotation_rate_hz: float | None = None
    notes: str = ""
    frame: AnnotationFrame = "ego"
    origin_lat_deg: float | None = None
    origin_lon_deg: float | None = None


@dataclass(frozen=True)
class Interaction:
    """One recorded vehicle-e-scooter interaction, as read from the interaction format.

    Attributes:
        meta: interaction.json.
        ego: ego GPS track, one row per fix, sorted by t_s. Columns: t_s [s], lat_deg,
            lon_deg, heading_deg [deg clockwise from true north, NaN if absent],
            speed_mps [m/s, NaN if absent].
        annotations: detections, sorted by (track_id, t_s). meta.frame 'ego': columns t_s,
            track_id (str), category, x_m (forward), y_m (lateral per meta.y_axis),
            yaw_deg (relative to the ego heading, positive towards +y; NaN if absent),
            length_m, width_m (NaN if absent). meta.frame 'world': columns t_s, track_id,
            category, lat_deg, lon_deg, heading_deg (the road user's true heading, deg
            clockwise from north; NaN if absent), length_m, width_m.
        ground_truth: optional world tracks at full rate. Columns: t_s, track_id (str),
            category, lat_deg, lon_deg.
        root: folder it was read from, if any.
    """

    meta: InteractionMeta
    ego: pd.DataFrame
    annotations: pd.DataFrame
    ground_truth: pd.DataFrame | None = None
    root: Path | None = None


@dataclass(frozen=True)
class AgentInfo:
    """One agent of a scenario.

    Attributes:
        agent_id: unique id within the scenario ('ego' for the ego vehicle).
        category: 'ego' or one of CATEGORIES.
        length_m, width_m: footprint [m].
        source_track_id: track id in the interaction's annotations (None for the ego).
    """

    agent_id: str
    category: str
    length_m: float
    width_m: float
    source_track_id: str | None = None


#: Columns of Scenario.trajectories, in order.
TRAJECTORY_COLUMNS: tuple[str, ...] = (
    "t_s",
    "agent_id",
    "source_track_id",
    "category",
    "x_m",
    "y_m",
    "yaw_rad",
    "speed_mps",
)

#: Optional bool column of Scenario.trajectories and of run time series: the row is a
#: continuation sample (a run-in before the recording or a run-out after it, added by
#: vei.continuation), not a recorded one. Absent = every row is recorded.
CONTINUATION_COLUMN = "continuation"


@dataclass(frozen=True)
class Scenario:
    """A reconstructed scenario: world-frame trajectories at the simulation rate + metadata.

    Stored as a folder with ``scenario.json`` and ``trajectories.parquet`` (and
    ``keyframes.parquet``, the sparse world-frame keyframes of each tracked road user).

    Attributes:
        id: scenario identifier.
        projection: PROJ string of the local tmerc plane (x east, y north [m]).
        origin_lat_deg, origin_lon_deg: origin of the plane [deg].
        start_time_utc: absolute time of t_s = 0.
        rate_hz: simulation rate of ``trajectories`` [Hz].
        bounds: geographic bounds {'south_deg','west_deg','north_deg','east_deg'}.
        agents: every agent, ego first.
        primary_threat: agent_id of the primary threat (None if no rider is present).
        trajectories: columns TRAJECTORY_COLUMNS; one row per agent per sample where the
            agent is present; t_s on the grid k / rate_hz; yaw_rad CCW from +x.
        keyframes: columns t_s, agent_id, x_m, y_m, yaw_rad (sparse keyframes), or None.
        maps: map files relative to the scenario folder, e.g. {'opendrive': 'map.xodr'}.
        extra: everything else of scenario.json (reconstruction errors, settings, ...).
        root: the folder it was read from, if any.
    """

    id: str
    projection: str
    origin_lat_deg: float
    origin_lon_deg: float
    start_time_utc: datetime
    rate_hz: float
    bounds: dict[str, float]
    agents: tuple[AgentInfo, ...]
    primary_threat: str | None
    trajectories: pd.DataFrame
    keyframes: pd.DataFrame | None = None
    maps: dict[str, str] = field(default_factory=dict)
    extra: dict = field(default_factory=dict)
    root: Path | None = None

    def agent(self, agent_id: str) -> AgentInfo:
        """The AgentInfo with this id (KeyError if absent)."""
        for a in self.agents:
            if a.agent_id == agent_id:
                return a
        raise KeyError(agent_id)

    def track(self, agent_id: str) -> pd.DataFrame:
        """Trajectory rows of one agent, sorted by t_s."""
        df = self.trajectories
        return df[df["agent_id"] == agent_id].sort_values("t_s").reset_index(drop=True)


#: Columns of a run's long-format time series (what every backend produces, one row per
#: agent per step): see Trace for the array form metrics consume.
TIMESERIES_COLUMNS: tuple[str, ...] = (
    "config",  # str: configuration name (e.g. 'normal-cap')
    "variant",  # int: variant index within the batch (0 for single runs)
    "t_s",  # float [s]
    "agent_id",  # str
    "category",  # 'ego' or one of CATEGORIES
    "x_m",  # float [m], plane x east
    "y_m",  # float [m], plane y north
    "yaw_rad",  # float [rad], CCW from +x
    "speed_mps",  # float [m/s], >= 0
    "accel_mps2",  # float [m/s^2], longitudinal (ego) or along-velocity (others)
    "active",  # bool: agent present in the scene at this step
    "collided",  # bool: this agent has collided with the ego at or before this step
    "cap_state",  # str: ego CAP state ('CRUISE', 'BRAKE', 'RECOVER'; '' if no CAP / not ego)
)


@dataclass(frozen=True)
class Trace:
    """Ego and one other road user over time, for B runs: the input every metric takes.

    All arrays share T time steps (uniform, ``dt_s`` apart). Positions in the plane [m].

    Attributes:
        t_s: [T] time [s].
        ego_xy_m: [B, T, 2]; ego_yaw_rad: [B, T]; ego_speed_mps: [B, T]; ego_accel_mps2: [B, T].
        other_xy_m: [B, T, 2]; other_yaw_rad: [B, T]; other_speed_mps: [B, T];
        other_vel_mps: [B, T, 2] velocity vector of the other road user [m/s].
        other_active: [B, T] bool, the other road user is present (the "interaction" span).
        collided: [B, T] bool, ego and other have collided at or before this step.
        ego_length_m, ego_width_m, other_length_m, other_width_m: footprints [m].
        secondary: the run's secondary collisions (every contact but ego / this road
            user: vei.metrics.secondary.secondary_record, a mapping of [B] arrays), or
            None where the source reports none.
        where: where the runs' contacts happened (vei.continuation.where.run_where:
            {'contact': [B], 'secondary': [B]} labels 'recorded', 'run-in', 'run-out',
            ''), or None where the source reports none.
    """

    t_s: object
    ego_xy_m: object
    ego_yaw_rad: object
    ego_speed_mps: object
    ego_accel_mps2: object
    other_xy_m: object
    other_yaw_rad: object
    other_speed_mps: object
    other_vel_mps: object
    other_active: object
    collided: object
    ego_length_m: float
    ego_width_m: float
    other_length_m: float
    other_width_m: float
    secondary: object = None
    where: object = None

    @property
    def dt_s(self) -> float:
        """Time step [s] (uniform grid)."""
        import numpy as np

        t = np.asarray(self.t_s)
        return float(t[1] - t[0]) if t.size > 1 else 0.0
