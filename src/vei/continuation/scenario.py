"""A scenario with continuations: :func:`with_continuations` (Scenario -> Scenario).

The one place where continuations are made. The engine's
:func:`vei.sim.state.prepare_scenario` (every backend), the time shift's search, the
OpenSCENARIO export, the figures and the reports all take the scenario through it, so
they all see the same run-ins and run-outs.

Every road user but the ego gets a run-in before its first recorded sample and a
run-out after its last (:func:`vei.continuation.tracks.continue_track`), each covering
the reach distance ``D = v t_r + v^2 / (2 a)`` (:class:`vei.config.ContinuationConfig`)
at the ego's speed v. The recorded rows are kept exactly as they are (same values, same
dtypes) with ``continuation = False``; the added rows have ``continuation = True``, lie
on the track's own time grid (run-ins at negative times where the recording starts
early) and carry the agent's category and source track id. ``scenario.extra
['continuation']`` records the settings, v, D and per agent how each end was made.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
import pandas as pd

from vei.config.continuation import ContinuationConfig
from vei.continuation.tracks import continue_track
from vei.errors import InputError
from vei.types import CONTINUATION_COLUMN, EGO_ID, Scenario

#: Key of Scenario.extra holding the continuation report.
EXTRA_KEY = "continuation"
#: A recorded ego sample counts as moving above this speed [m/s] (as the cruise speed's
#: median-moving rule, EgoConfig.moving_threshold_mps).
_MOVING_MPS = 0.5


def is_continued(scenario: Scenario) -> bool:
    """The scenario's trajectories carry the ``continuation`` column."""
    return CONTINUATION_COLUMN in scenario.trajectories.columns


def recorded_rows(traj: pd.DataFrame) -> pd.DataFrame:
    """The recorded rows of a trajectories table (all rows when it has no column)."""
    if CONTINUATION_COLUMN not in traj.columns:
        return traj
    return traj[~traj[CONTINUATION_COLUMN].to_numpy(dtype=bool)]


def strip_continuations(scenario: Scenario) -> Scenario:
    """The scenario as recorded: continuation rows, the column and the report removed."""
    if not is_continued(scenario):
        return scenario
    traj = recorded_rows(scenario.trajectories).drop(columns=CONTINUATION_COLUMN)
    extra = {k: v for k, v in scenario.extra.items() if k != EXTRA_KEY}
    return dataclasses.replace(scenario, trajectories=traj.reset_index(drop=True), extra=extra)


def recorded_ego_speed_mps(scenario: Scenario) -> float:
    """The recorded ego's median speed over its moving samples [m/s] (NaN if it never
    moves; the speed from the positions where the column has none)."""
    ego = recorded_rows(scenario.trajectories)
    ego = ego[ego["agent_id"] == EGO_ID].sort_values("t_s")
    sp = ego["speed_mps"].to_numpy(dtype=np.float64)
    if sp.size and not np.isfinite(sp).all():
        t = ego["t_s"].to_numpy(dtype=np.float64)
        x, y = ego["x_m"].to_numpy(dtype=np.float64), ego["y_m"].to_numpy(dtype=np.float64)
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
        sp = np.gradient(arc, t) if t.size > 1 else np.zeros_like(arc)
    moving = sp[sp > _MOVING_MPS]
    return float(np.median(moving)) if moving.size else float("nan")


def reach_speed_mps(
    scenario: Scenario, cfg: ContinuationConfig, ego_speed_mps: float | None = None
) -> float:
    """v of the reach distance [m/s]: ``cfg.ego_speed_mps``, else ``ego_speed_mps`` (the
    caller's cruise speed), else the recorded ego's median moving speed, else
    ``cfg.min_ego_speed_mps``."""
    for v in (cfg.ego_speed_mps, ego_speed_mps):
        if v is not None and math.isfinite(v) and v > 0:
            return float(v)
    med = recorded_ego_speed_mps(scenario)
    return med if math.isfinite(med) else float(cfg.min_ego_speed_mps)


def _settings(cfg: ContinuationConfig, v: float) -> dict[str, Any]:
    return {**dataclasses.asdict(cfg), "ego_speed_mps": v}


def map_features(scenario: Scenario, cfg: ContinuationConfig) -> tuple[Any, Any]:
    """(lanes, buildings) of the scenario's map files (None where it has none or the
    settings turn them off): :func:`vei.continuation.lanes.load_lanes` of
    ``maps['opendrive']``, :func:`vei.continuation.buildings.load_buildings` of
    ``maps['osm']``, both relative to ``scenario.root``."""
    lanes = buildings = None
    if scenario.root is None:
        return None, None
    xodr = scenario.maps.get("opendrive")
    if cfg.follow_roads and xodr and (scenario.root / xodr).is_file():
        from vei.continuation.lanes import load_lanes

        try:
            lanes = load_lanes(scenario.root / xodr)
        except InputError as exc:  # a broken map: the free continuation; the error is kept
            lanes = _Unusable(str(exc))
    osm = scenario.maps.get("osm")
    if cfg.avoid_buildings and osm and (scenario.root / osm).is_file():
        from vei.continuation.buildings import load_buildings

        try:
            buildings = load_buildings(scenario.root / osm, scenario.projection)
        except InputError as exc:
            buildings = _Unusable(str(exc))
    return lanes, buildings


class _Unusable:
    """A map file the continuations could not read (its error, for the report)."""

    def __init__(self, error: str) -> None:
        self.error = error


def with_continuations(
    scenario: Scenario,
    cfg: ContinuationConfig | None = None,
    *,
    ego_speed_mps: float | None = None,
) -> Scenario:
    """The scenario with a run-in and a run-out for every road user but the ego.

    Idempotent: a scenario continued with the same settings and speed comes back as it
    is; one continued otherwise is continued again from its recorded rows. With
    ``cfg.enabled`` False the recorded scenario (continuations stripped).

    Args:
        scenario: any scenario (its map files are read from ``scenario.root``).
        cfg: the settings (default ContinuationConfig()).
        ego_speed_mps: the cruise speed the reach distance is for [m/s] (used when
            ``cfg.ego_speed_mps`` is None; None = the recorded ego's median moving speed).
    Returns:
        The continued scenario (see the module docstring).
    """
    cfg = ContinuationConfig() if cfg is None else cfg
    if not cfg.enabled:
        return strip_continuations(scenario)
    v = reach_speed_mps(scenario, cfg, ego_speed_mps)
    settings = _settings(cfg, v)
    if is_continued(scenario):
        if scenario.extra.get(EXTRA_KEY, {}).get("settings") == settings:
            return scenario
        scenario = strip_continuations(scenario)
    reach = cfg.reach_m(v)
    lanes, buildings = map_features(scenario, cfg)
    map_report: dict[str, Any] = {"lanes": lanes is not None, "buildings": buildings is not None}
    for key, feat in (("lanes", lanes), ("buildings", buildings)):
        if isinstance(feat, _Unusable):
            map_report[key] = False
            map_report[f"{key}_error"] = feat.error
    lanes = None if isinstance(lanes, _Unusable) else lanes
    buildings = None if isinstance(buildings, _Unusable) else buildings
    traj = scenario.trajectories
    rec = traj.assign(**{CONTINUATION_COLUMN: False})
    added = []
    report: dict[str, Any] = {}
    for agent in scenario.agents:
        if agent.agent_id == EGO_ID:
            continue
        tr = scenario.track(agent.agent_id)
        if tr.empty:
            continue
        cols = [tr[c].to_numpy(dtype=np.float64) for c in ("t_s", "x_m", "y_m", "yaw_rad")]
        sp = tr["speed_mps"].to_numpy(dtype=np.float64)
        before, after, ends = continue_track(
            *cols, sp, reach_m=reach, cfg=cfg, lanes=lanes, buildings=buildings
        )
        first, last = tr.iloc[0], tr.iloc[-1]
        for part, row in ((before, first), (after, last)):
            k = part["t_s"].size
            added.append(
                pd.DataFrame(
                    {
                        "t_s": part["t_s"],
                        "agent_id": np.full(k, agent.agent_id, dtype=object),
                        "source_track_id": np.full(k, row["source_track_id"], dtype=object),
                        "category": np.full(k, row["category"], dtype=object),
                        "x_m": part["x_m"],
                        "y_m": part["y_m"],
                        "yaw_rad": part["yaw_rad"],
                        "speed_mps": part["speed_mps"],
                        CONTINUATION_COLUMN: np.ones(k, dtype=bool),
                    }
                )
            )
        report[agent.agent_id] = {
            "recorded_span_s": [float(cols[0][0]), float(cols[0][-1])],
            "continued_span_s": [
                float(before["t_s"][0]) if before["t_s"].size else float(cols[0][0]),
                float(after["t_s"][-1]) if after["t_s"].size else float(cols[0][-1]),
            ],
            **{name: rep.as_dict() for name, rep in ends.items()},
        }
    out = pd.concat([rec, *added], ignore_index=True) if added else rec
    order = {a.agent_id: i for i, a in enumerate(scenario.agents)}
    out = out.assign(_o=out["agent_id"].map(order).fillna(len(order)))
    out = out.sort_values(["_o", "t_s"], kind="stable").drop(columns="_o").reset_index(drop=True)
    for c in traj.columns:  # the recorded columns keep their dtypes
        if out[c].dtype != traj[c].dtype:
            out[c] = out[c].astype(traj[c].dtype)
    extra = dict(scenario.extra)
    extra[EXTRA_KEY] = {
        "settings": settings,
        "reach_m": reach,
        "map": map_report,
        "agents": report,
    }
    return dataclasses.replace(scenario, trajectories=out, extra=extra)


def recorded_span_s(scenario: Scenario, agent_id: str) -> tuple[float, float]:
    """(first, last) recorded time of an agent [s] (continuations left out)."""
    rec = recorded_rows(scenario.trajectories)
    t = rec.loc[rec["agent_id"] == agent_id, "t_s"].to_numpy(dtype=np.float64)
    return (float(t.min()), float(t.max())) if t.size else (math.nan, math.nan)
