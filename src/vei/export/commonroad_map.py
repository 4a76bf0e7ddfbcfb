"""OpenDRIVE lanes to a CommonRoad lanelet network (vei's documented fallback converter).

CommonRoad's own converter (commonroad-scenario-designer) needs Qt, SUMO bindings and
pins of its own (a separate install of hundreds of MB; see docs/commonroad.md). vei
already samples the OpenDRIVE lanes it builds (:func:`vei.maps.roads.load_roads`: each
lane's inner and outer border every ``step_m`` along its road, the same geometry that is
drawn under every picture and checked against CARLA's waypoints); this module turns each
lane of a lane section into one lanelet:

- bounds in the lane's driving direction: a right lane (OpenDRIVE id < 0) runs along the
  road's s, a left lane (id > 0) against it (its borders reversed); either way its left
  bound is the inner border (towards the reference line) and its right bound the outer
  one. The centre line is the mean of the two bounds.
- type: driving lanes URBAN (on a road of type 'town' or untyped; the maps vei builds are
  urban), sidewalk SIDEWALK, biking BICYCLE_LANE, parking PARKING, shoulder SHOULDER,
  border BORDER, others UNKNOWN; lanes of a junction's connecting roads also INTERSECTION.
- neighbours within one lane section: ``adjacent_left`` / ``adjacent_right`` (same
  direction or not); successors across lane sections and roads are not linked (the
  collision and drivability checks vei runs need the geometry, not the topology).
- ids: ``first_id`` upwards in the order of :attr:`RoadGeometry.lanes`.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from vei.maps.roads import Lane, RoadGeometry, load_roads

#: OpenDRIVE lane type -> CommonRoad LaneletType name (others: UNKNOWN).
LANE_TYPES: dict[str, str] = {
    "driving": "URBAN", "entry": "URBAN", "exit": "URBAN", "onRamp": "ACCESS_RAMP",
    "offRamp": "EXIT_RAMP", "connectingRamp": "URBAN", "bidirectional": "URBAN",
    "sidewalk": "SIDEWALK", "biking": "BICYCLE_LANE", "parking": "PARKING",
    "shoulder": "SHOULDER", "border": "BORDER", "restricted": "RESTRICTED",
}  # fmt: skip
#: Sampling step of the lane borders [m].
STEP_M = 1.0


def _bounds(lane: Lane) -> tuple[np.ndarray, np.ndarray]:
    """(left, right) bounds [N, 2] in the lane's driving direction."""
    if lane.lane_id < 0:
        return lane.inner, lane.outer
    return lane.inner[::-1], lane.outer[::-1]


def lanelet_network(roads: RoadGeometry, *, first_id: int = 1000, decimals: int = 6) -> Any:
    """The CommonRoad LaneletNetwork of ``roads`` (see the module docstring).

    Args:
        roads: the map's lanes (vei.maps.roads). first_id: the first lanelet id.
        decimals: coordinates are rounded to this many decimals [m] (the precision the
            file is written with, so that it reads back equal).
    Returns:
        (LaneletNetwork, {(road_id, section, lane_id): lanelet id}).
    """
    from commonroad.scenario.lanelet import Lanelet, LaneletNetwork, LaneletType

    lanelets = []
    ids: dict[tuple[str, int, int], int] = {}
    usable = [ln for ln in roads.lanes if len(ln.inner) >= 2 and ln.inner.shape == ln.outer.shape]
    for k, lane in enumerate(usable):
        ids[(lane.road_id, lane.section_index, lane.lane_id)] = first_id + k
    for lane in usable:
        left, right = (np.round(np.asarray(b, dtype=np.float64), decimals) for b in _bounds(lane))
        centre = np.round(0.5 * (left + right), decimals)
        types = {LaneletType[LANE_TYPES.get(lane.lane_type, "UNKNOWN")]}
        if lane.junction not in ("-1", ""):
            types.add(LaneletType.INTERSECTION)
        key = (lane.road_id, lane.section_index)
        # neighbours in the same section: in the lane's own direction its left is towards
        # the reference line (the next lane inwards, across the centre for the innermost),
        # its right the next lane outwards
        left_n, right_n = (
            _neighbour(ids, key, lane.lane_id, -1),
            _neighbour(ids, key, lane.lane_id, +1),
        )
        lanelets.append(
            Lanelet(
                left_vertices=left, center_vertices=centre, right_vertices=right,
                lanelet_id=ids[(lane.road_id, lane.section_index, lane.lane_id)],
                adjacent_left=left_n[0], adjacent_left_same_direction=left_n[1],
                adjacent_right=right_n[0], adjacent_right_same_direction=right_n[1],
                lanelet_type=types,
            )
        )  # fmt: skip
    return LaneletNetwork.create_from_lanelet_list(lanelets, cleanup_ids=False), ids


def _neighbour(
    ids: dict[tuple[str, int, int], int], key: tuple[str, int], lane_id: int, step: int
) -> tuple[int | None, bool | None]:
    """(id, same direction) of the lane ``step`` further out (+1) or in (-1) than lane_id."""
    sign = 1 if lane_id > 0 else -1
    target = lane_id + sign * step
    if target == 0:  # across the centre line: the innermost lane of the other side
        target = -sign
    got = ids.get((*key, target))
    if got is None:
        return None, None
    return got, (target > 0) == (lane_id > 0)


def load_lanelet_network(xodr: str | Path, **kwargs: Any) -> Any:
    """:func:`lanelet_network` of an OpenDRIVE file (sampled every STEP_M)."""
    return lanelet_network(load_roads(xodr, step_m=STEP_M), **kwargs)


__all__ = ["LANE_TYPES", "lanelet_network", "load_lanelet_network"]
