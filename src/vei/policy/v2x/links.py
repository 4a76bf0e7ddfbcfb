"""Which V2X links are blocked, and by what: vehicle boxes (NLOSv) and buildings (NLOS).

- :func:`tallest_blocker_m`: the tallest vehicle box that the straight line between the
  two antennas crosses (vei's occlusion test,
  :func:`vei.policy.perception_geometry.segments_blocked`: grazing an edge does not count;
  a box holding either end is ignored); its height picks the blockage case of TR 37.885
  clause 6.2.1 (:func:`vei.policy.v2x.channel.blockage_stats_db`).
- :func:`blocker_heights_m`: a vehicle box's height by TR 37.885 clause 6.1.2's vehicle
  types from its length (passenger vehicles 5 m long and 1.6 m high; trucks and buses 13
  m and 3 m): up to ``truck_min_length_m`` a passenger vehicle, longer a truck, bus or
  van.
- :class:`Buildings`: building outlines near the scene (OpenStreetMap, where the scenario's
  map has them: :mod:`vei.continuation.buildings`); :meth:`Buildings.blocks` says which
  links cross one (an outline holding either end is ignored, like a box).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from vei.policy import perception_geometry as geom
from vei.policy.v2x.channel import PASSENGER_HEIGHT_M, TRUCK_HEIGHT_M

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Margin [m] around the scene's tracks within which building outlines are kept.
SCENE_MARGIN_M = 150.0


def blocker_heights_m(length_m: npt.ArrayLike, truck_min_length_m: float) -> FloatArray:
    """[...] blocker heights [m] of vehicle boxes of these lengths [m]: passenger
    vehicles (TR 37.885 types 1 and 2, 1.6 m) up to ``truck_min_length_m``, trucks, buses
    and vans (type 3, 3 m) beyond."""
    ln = np.asarray(length_m, dtype=np.float64)
    return np.where(ln > truck_min_length_m, TRUCK_HEIGHT_M, PASSENGER_HEIGHT_M)


def _contains(px: FloatArray, py: FloatArray, x: FloatArray, y: FloatArray, yaw: FloatArray,
              length: FloatArray, width: FloatArray) -> BoolArray:  # fmt: skip
    c, s = np.cos(yaw), np.sin(yaw)
    dx, dy = px - x, py - y
    return (np.abs(dx * c + dy * s) < 0.5 * length) & (np.abs(-dx * s + dy * c) < 0.5 * width)


def tallest_blocker_m(
    sx_m: FloatArray,
    sy_m: FloatArray,
    rx_m: FloatArray,
    ry_m: FloatArray,
    box_x_m: FloatArray,
    box_y_m: FloatArray,
    box_yaw_rad: FloatArray,
    box_length_m: FloatArray,
    box_width_m: FloatArray,
    box_height_m: FloatArray,
    blockers: BoolArray,
) -> FloatArray:
    """Height [m] of the tallest box each link's straight segment crosses (0: none).

    Args:
        sx_m, sy_m: [Q] sender (rider) positions [m]. rx_m, ry_m: [Q] receiver (car)
            positions [m].
        box_*: [Q, M] the candidate blockers' boxes [m, rad] and heights [m].
        blockers: [Q, M] which of them may block this link (present vehicles other than
            the sender).
    Returns:
        [Q] heights [m]; 0 where the line is clear. A box holding either end is ignored;
        grazing an edge does not block
        (:data:`vei.policy.perception_geometry.BLOCK_TOL_M`).
    """
    q, m = box_x_m.shape
    out = np.zeros(q)
    if q == 0 or m == 0:
        return out
    ends_inside = _contains(sx_m[:, None], sy_m[:, None], box_x_m, box_y_m, box_yaw_rad,
                            box_length_m, box_width_m) | _contains(
        rx_m[:, None], ry_m[:, None], box_x_m, box_y_m, box_yaw_rad, box_length_m, box_width_m
    )  # fmt: skip
    use = blockers & ~ends_inside
    qi, mi = np.nonzero(use)
    if qi.size == 0:
        return out
    hit = geom.segments_blocked(
        sx_m[qi], sy_m[qi], rx_m[qi][:, None], ry_m[qi][:, None], box_x_m[qi, mi],
        box_y_m[qi, mi], box_yaw_rad[qi, mi], box_length_m[qi, mi], box_width_m[qi, mi],
    )[:, 0]  # fmt: skip
    np.maximum.at(out, qi[hit], box_height_m[qi[hit], mi[hit]])
    return out


def links_blocked(
    sx_m: FloatArray,
    sy_m: FloatArray,
    rx_m: FloatArray,
    ry_m: FloatArray,
    box_x_m: FloatArray,
    box_y_m: FloatArray,
    box_yaw_rad: FloatArray,
    box_length_m: FloatArray,
    box_width_m: FloatArray,
    blockers: BoolArray,
) -> BoolArray:
    """Whether each link's straight segment crosses a blocker's box ([Q] bool; the
    arguments of :func:`tallest_blocker_m` without heights)."""
    ones = np.ones_like(np.asarray(box_x_m, dtype=np.float64))
    return (
        tallest_blocker_m(sx_m, sy_m, rx_m, ry_m, box_x_m, box_y_m, box_yaw_rad, box_length_m,
                          box_width_m, ones, blockers) > 0.0
    )  # fmt: skip


class Buildings:
    """Building outlines (shapely polygons in the scenario's plane, metres) that block
    V2X links (NLOS). Picklable (the spatial index is rebuilt after unpickling).

    Attributes:
        polygons: [K] object array of shapely Polygons.
    """

    def __init__(self, polygons: Any) -> None:
        self.polygons = np.asarray(list(polygons), dtype=object)
        self._tree: Any = None

    def __len__(self) -> int:
        return int(self.polygons.size)

    def __getstate__(self) -> dict[str, Any]:
        return {"polygons": self.polygons}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.polygons = state["polygons"]
        self._tree = None

    def _index(self) -> Any:
        if self._tree is None:
            import shapely

            self._tree = shapely.STRtree(self.polygons)
        return self._tree

    def blocks(
        self, sx_m: FloatArray, sy_m: FloatArray, rx_m: FloatArray, ry_m: FloatArray
    ) -> BoolArray:
        """[Q] whether the segment from (sx, sy) to (rx, ry) [m] crosses a building that
        holds neither end (a rider recorded inside an outline, under an arcade or in a
        passage, keeps its line of sight through that one)."""
        import shapely

        q = int(np.asarray(sx_m).size)
        out = np.zeros(q, dtype=bool)
        if q == 0 or not len(self):
            return out
        tree = self._index()
        a = np.column_stack([sx_m, sy_m])
        b = np.column_stack([rx_m, ry_m])
        lines = shapely.linestrings(np.stack([a, b], axis=1))
        li, pi = tree.query(lines, predicate="intersects")
        if li.size == 0:
            return out
        ends = shapely.points(np.concatenate([a, b]))
        ei, ep = tree.query(ends, predicate="within")
        holds = set(zip((ei % q).tolist(), ep.tolist(), strict=True))
        keep = np.array([(i, p) not in holds for i, p in zip(li.tolist(), pi.tolist(), strict=True)],
                        dtype=bool)  # fmt: skip
        out[li[keep]] = True
        return out


def scene_buildings(scenario: Any, margin_m: float = SCENE_MARGIN_M) -> Buildings | None:
    """The building outlines of a scenario's OpenStreetMap source (``maps['osm']``) within
    ``margin_m`` of its tracks, or None (no OSM source, no building near the scene, or an
    unreadable file: V2X links are then never NLOS)."""
    from vei.errors import InputError

    osm = getattr(scenario, "maps", {}).get("osm")
    root = getattr(scenario, "root", None)
    if not osm or root is None or not (root / osm).is_file():
        return None
    import shapely

    from vei.continuation.buildings import load_buildings

    try:
        geom_all = load_buildings(root / osm, scenario.projection)
    except InputError:
        return None
    if geom_all is None:
        return None
    traj = scenario.trajectories
    x, y = traj["x_m"].to_numpy(dtype=np.float64), traj["y_m"].to_numpy(dtype=np.float64)
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return None
    x, y = x[ok], y[ok]
    box = (x.min() - margin_m, y.min() - margin_m, x.max() + margin_m, y.max() + margin_m)
    near = shapely.clip_by_rect(geom_all, *box)
    parts = [p for p in shapely.get_parts(near) if p.geom_type == "Polygon" and not p.is_empty]
    return Buildings(parts) if parts else None


__all__ = [
    "SCENE_MARGIN_M",
    "Buildings",
    "blocker_heights_m",
    "links_blocked",
    "scene_buildings",
    "tallest_blocker_m",
]
