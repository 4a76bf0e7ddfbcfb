"""The run-in and run-out of one track (:func:`continue_track`).

Candidates for each end, in order: along the lane the end lies on (where the map has
lanes and the blended path keeps the curvature bounds), the free continuation, straight
on. Where the map has building outlines, the first candidate that crosses none is taken
(buildings that hold the end point itself are ignored: a recording noisy enough to put a
rider inside a wall says nothing about where it came from); where every candidate
crosses one, the first is cut 0.5 m before the building: the road user appears there, as
from a passage or a doorway, and the end's report says ``blocked_by_building``.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.config.continuation import ContinuationConfig
from vei.continuation import lanes as lane_mod
from vei.continuation.path import (
    EndState,
    Motion,
    end_curvature,
    end_state,
    free_path,
    motion,
    near_turn,
    path_arc,
    reverse_samples,
    run_in,
    sample,
)

FloatArray = npt.NDArray[np.float64]

#: A cut continuation ends this far before the building it would cross [m].
BUILDING_MARGIN_M = 0.5
#: Extra path length beyond the travelled distance [m] (interpolation headroom).
_HEADROOM_M = 1.0


@dataclass(frozen=True)
class EndReport:
    """How one end was continued.

    Attributes:
        kind: 'lane' (along the map's lane), 'free', 'straight' or 'standing'.
        duration_s: its length in time [s]. length_m: the distance covered [m].
        speed_mps, course_rad, curvature_per_m: the end's motion (curvature as used,
            after the bounds). yaw_step_rad, speed_step_mps: the recording's noise there.
        blocked_by_building: cut short before a building.
    """

    kind: str
    duration_s: float
    length_m: float
    speed_mps: float
    course_rad: float
    curvature_per_m: float
    yaw_step_rad: float
    speed_step_mps: float
    blocked_by_building: bool = False

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready fields."""
        return {k: (bool(v) if isinstance(v, bool) else v) for k, v in self.__dict__.items()}


def _crossing(path: FloatArray, length_m: float, buildings: Any, end: EndState) -> float | None:
    """Arc length [m] at which the path first enters a building (None: it never does);
    buildings that contain the end point are ignored."""
    import shapely
    from shapely.geometry import LineString, Point

    if buildings is None:
        return None
    arc = path_arc(path)
    keep = arc <= length_m + 1e-9
    pts = path[keep, :2]
    if pts.shape[0] < 2:
        return None
    start = Point(end.x_m, end.y_m)
    parts = getattr(buildings, "geoms", [buildings])
    blocking = [g for g in parts if not g.covers(start)]
    if not blocking:
        return None
    line = LineString(pts)
    hit = shapely.union_all(blocking).intersection(line)
    if hit.is_empty:
        return None
    return float(
        min(line.project(Point(c)) for g in getattr(hit, "geoms", [hit]) for c in g.coords)
    )


def _candidates(
    end: EndState, length_m: float, cfg: ContinuationConfig, lanes: Any
) -> list[tuple[str, FloatArray]]:
    k0 = end_curvature(
        end,
        decay_m=cfg.curvature_decay_m,
        max_turn_rad=cfg.max_turn_rad,
        max_lat_accel_mps2=cfg.max_lat_accel_mps2,
    )
    free = free_path(end, length_m + _HEADROOM_M, k0, cfg.curvature_decay_m)
    out: list[tuple[str, FloatArray]] = []
    if lanes is not None and cfg.follow_roads:
        lp = lane_mod.lane_path(lanes, end, length_m + _HEADROOM_M, cfg.road_heading_tol_rad)
        if lp is not None and lp.shape[0] >= 2:
            bl = lane_mod.blend(free, lp, cfg.road_blend_m)
            v2 = end.speed_mps * end.speed_mps
            if (
                path_arc(bl)[-1] >= length_m
                and v2 * lane_mod.max_curvature(bl) <= cfg.max_lat_accel_mps2
            ):
                out.append(("lane", bl))
    out.append(("free", free))
    if k0 != 0.0:
        out.append(("straight", free_path(end, length_m + _HEADROOM_M, 0.0, cfg.curvature_decay_m)))
    return out


def continue_end(
    t_s: FloatArray,
    x_m: FloatArray,
    y_m: FloatArray,
    yaw_rad: FloatArray,
    speed_mps: FloatArray,
    *,
    reach_m: float,
    cfg: ContinuationConfig,
    lanes: Any = None,
    buildings: Any = None,
) -> tuple[dict[str, FloatArray], EndReport]:
    """The run-out of a track (its samples after the last one) and how it was made.

    Args:
        t_s, x_m, y_m, yaw_rad, speed_mps: [N] the track. reach_m: its length [m]
            (:meth:`ContinuationConfig.reach_m`). cfg: the settings.
        lanes: a :class:`vei.continuation.lanes.LaneSet` or None. buildings: a shapely
            geometry of building outlines or None.
    Returns:
        ({'t_s', 'x_m', 'y_m', 'yaw_rad', 'speed_mps'} [K] samples, EndReport).
    """
    end = end_state(t_s, x_m, y_m, yaw_rad, speed_mps)
    mov = motion(
        end, reach_m, standing_speed_mps=cfg.standing_speed_mps, stop_decel_mps2=cfg.stop_decel_mps2
    )
    length = float(mov.s_m[-1])
    blocked = False
    if mov.standing:
        kind, path = "standing", free_path(end, length + _HEADROOM_M, 0.0, cfg.curvature_decay_m)
    else:
        cands = _candidates(end, length, cfg, lanes)
        kind, path = cands[0]
        if buildings is not None and cfg.avoid_buildings:
            cut = None
            for name, cand in cands:
                c = _crossing(cand, length, buildings, end)
                if c is None:
                    kind, path = name, cand
                    break
                if cut is None:
                    cut = c
            else:
                blocked = True
                keep = mov.s_m <= max(float(cut) - BUILDING_MARGIN_M, 0.0)
                if not keep.any():
                    keep[0] = True
                mov = Motion(False, mov.t_rel_s[keep], mov.s_m[keep], mov.speed_mps[keep])
                length = float(mov.s_m[-1])
    samples = sample(end, mov, path, cfg.curvature_decay_m)
    k_used = end_curvature(
        end,
        decay_m=cfg.curvature_decay_m,
        max_turn_rad=cfg.max_turn_rad,
        max_lat_accel_mps2=cfg.max_lat_accel_mps2,
    )
    report = EndReport(
        kind=kind,
        duration_s=float(mov.t_rel_s[-1]),
        length_m=length,
        speed_mps=end.speed_mps,
        course_rad=end.course_rad,
        curvature_per_m=0.0 if kind in ("standing", "straight") else k_used,
        yaw_step_rad=end.yaw_step_rad,
        speed_step_mps=end.speed_step_mps,
        blocked_by_building=blocked,
    )
    return samples, report


def continue_track(
    t_s: FloatArray,
    x_m: FloatArray,
    y_m: FloatArray,
    yaw_rad: FloatArray,
    speed_mps: FloatArray,
    *,
    reach_m: float,
    cfg: ContinuationConfig,
    lanes: Any = None,
    buildings: Any = None,
) -> tuple[dict[str, FloatArray], dict[str, FloatArray], dict[str, EndReport]]:
    """Run-in and run-out of one track: (run-in samples in time order, run-out samples,
    {'run_in': EndReport, 'run_out': EndReport}). See :func:`continue_end`."""
    kw: dict[str, Any] = {"reach_m": reach_m, "cfg": cfg, "lanes": lanes, "buildings": buildings}
    rev, rep_in = continue_end(*run_in(t_s, x_m, y_m, yaw_rad, speed_mps), **kw)
    out, rep_out = continue_end(t_s, x_m, y_m, yaw_rad, speed_mps, **kw)
    before = reverse_samples(rev)
    yaw0 = float(np.asarray(yaw_rad, dtype=np.float64)[0])
    before["yaw_rad"] = near_turn(before["yaw_rad"], yaw0)  # the recording's own turns
    return before, out, {"run_in": rep_in, "run_out": rep_out}
