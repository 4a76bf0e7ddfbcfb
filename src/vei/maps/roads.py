"""Road geometry in the plane, read straight from OpenDRIVE: lane polygons, lane lines, drawing.

vei samples the OpenDRIVE description itself (pure numpy + shapely, no simulator needed):
each road's reference line (``line``, ``arc``, ``spiral``, ``poly3``, ``paramPoly3``) is
sampled every ``step_m`` metres and at every lane-section boundary; the lane offset and the
lane widths (cubic polynomials) are evaluated there and each lane becomes a polygon between
its inner and outer border. Lanes given by ``<border>`` records instead of ``<width>`` are
not supported (neither netconvert nor CARLA writes them): such lanes are skipped and counted.

Because the .xodr written by :func:`vei.maps.build.build_opendrive` has the scenario's plane
as its geoReference, the polygons are in the scenario frame (x east, y north, metres) and
trajectories can be checked against them directly (:func:`drivable_share`). The sampler is
checked in the tests against CARLA's own waypoints and against netconvert's SUMO lanes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.errors import InputError
from vei.maps import safexml

FloatArray = npt.NDArray[np.float64]

#: OpenDRIVE lane types a car may drive on.
DRIVABLE_LANE_TYPES: frozenset[str] = frozenset(
    {"driving", "entry", "exit", "onRamp", "offRamp", "connectingRamp", "bidirectional"}
)
#: Default sampling step along the reference line [m].
DEFAULT_STEP_M = 1.0
#: Drawing colours: drivable area, other lanes (sidewalks, bike lanes), lane lines.
ROAD_FACE = "#b8b8b8"
OTHER_FACE = "#dcdcdc"
LINE_COLOR = "#ffffff"
#: Lane types whose edge towards the carriageway is a kerb (drawn as a dark line).
KERB_LANE_TYPES: frozenset[str] = frozenset({"sidewalk", "curb"})
#: Kerb line colour, and the note drawn where a scenario has no map.
KERB_COLOR = "#555555"
NO_MAP_NOTE = "no road map (the scenario has no map.xodr)"


@dataclass(frozen=True)
class Lane:
    """One lane of one lane section, as a polygon in the plane.

    Attributes:
        road_id, section_index, lane_id: OpenDRIVE ids (lane_id < 0: right, > 0: left).
        lane_type: OpenDRIVE lane type ('driving', 'sidewalk', 'biking', ...).
        junction: the road's junction id ('-1' when not in a junction).
        inner: [N, 2] inner border (towards the reference line) x, y [m], along s.
        outer: [N, 2] outer border [m], along s.
    """

    road_id: str
    section_index: int
    lane_id: int
    lane_type: str
    junction: str
    inner: FloatArray = field(repr=False)
    outer: FloatArray = field(repr=False)

    @property
    def drivable(self) -> bool:
        """True for lane types a car drives on (:data:`DRIVABLE_LANE_TYPES`)."""
        return self.lane_type in DRIVABLE_LANE_TYPES

    @property
    def outline(self) -> FloatArray:
        """[N*2+1, 2] closed ring: inner border forward, outer border backward."""
        ring = np.vstack([self.inner, self.outer[::-1], self.inner[:1]])
        return ring


@dataclass(frozen=True)
class RoadGeometry:
    """Lanes and reference lines of an OpenDRIVE map in its plane.

    Attributes:
        lanes: every lane with a width (all types).
        reference_lines: per road, [N, 2] sampled reference line x, y [m].
        proj_string: the map's geoReference, or None.
        skipped_lanes: lanes without ``<width>`` records (not drawn, not drivable).
        source: the file read.
        areas: [K, 2] drivable-area rings that are no lane (maps converted from lane
            polylines, e.g. Argoverse 2: :mod:`vei.maps.lanes_xodr`); drivable, drawn.
    """

    lanes: tuple[Lane, ...]
    reference_lines: tuple[FloatArray, ...] = field(repr=False)
    proj_string: str | None
    skipped_lanes: int = 0
    source: Path | None = None
    areas: tuple[FloatArray, ...] = field(default=(), repr=False)

    @property
    def drivable_lanes(self) -> tuple[Lane, ...]:
        """Lanes of drivable types."""
        return tuple(lane for lane in self.lanes if lane.drivable)

    @property
    def drivable_polygons(self) -> list[Any]:
        """One valid shapely polygon per drivable lane and drivable area (plane metres);
        degenerate ones dropped."""
        return _polygons([lane.outline for lane in self.drivable_lanes] + list(self.areas))

    @property
    def drivable_area(self) -> Any:
        """Union of the drivable lanes' polygons (shapely geometry, plane metres)."""
        import shapely
        from shapely.geometry import Polygon

        polys = self.drivable_polygons
        return shapely.union_all(polys) if polys else Polygon()

    @property
    def kerbs(self) -> tuple[FloatArray, ...]:
        """[N, 2] kerb lines [m]: the inner border (towards the road's reference line) of
        every sidewalk / curb lane, i.e. its edge towards the carriageway."""
        return tuple(lane.inner for lane in self.lanes if lane.lane_type in KERB_LANE_TYPES)

    @property
    def lane_borders(self) -> tuple[FloatArray, ...]:
        """[N, 2] borders of the drivable lanes [m]: each one's outer and inner border (the
        innermost lanes' inner borders are the centre line)."""
        return tuple(b for lane in self.lanes if lane.drivable for b in (lane.outer, lane.inner))

    @property
    def bounds_xy(self) -> tuple[float, float, float, float]:
        """(min_x, min_y, max_x, max_y) of all lanes [m]."""
        pts = np.vstack(
            [np.vstack([lane.inner, lane.outer]) for lane in self.lanes] + list(self.areas)
        )
        return (
            float(pts[:, 0].min()),
            float(pts[:, 1].min()),
            float(pts[:, 0].max()),
            float(pts[:, 1].max()),
        )


def _polygons(rings: list[FloatArray]) -> list[Any]:
    import shapely
    from shapely.geometry import Polygon

    polys = []
    for ring in rings:
        if len(ring) < 4:
            continue
        poly = Polygon(ring)
        if not poly.is_valid:
            poly = shapely.make_valid(poly)
        if not poly.is_empty and poly.area > 0:
            polys.append(poly)
    return polys


# ------------------------------------------------------------------ reference line geometry


def _f(elem, name: str, default: float | None = None, *, path: Path | None = None) -> float:
    raw = elem.get(name)
    if raw is None:
        if default is None:
            raise InputError(f"<{elem.tag}> lacks attribute '{name}'", path=path, field=name)
        return default
    try:
        return float(raw)
    except ValueError as exc:
        raise InputError(
            f"<{elem.tag}> attribute '{name}'={raw!r} is not a number", path=path, field=name
        ) from exc


def _local_geometry(
    geom, ds: FloatArray, length: float, path: Path | None
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(u, v, heading) in the geometry's local frame at distances ``ds`` along it."""
    kind = None
    for child in geom:
        kind = child
        break
    if kind is None or kind.tag == "line":
        return ds, np.zeros_like(ds), np.zeros_like(ds)
    if kind.tag == "arc":
        k = _f(kind, "curvature", path=path)
        if abs(k) < 1e-12:
            return ds, np.zeros_like(ds), np.zeros_like(ds)
        return np.sin(k * ds) / k, (1.0 - np.cos(k * ds)) / k, k * ds
    # Dense sampling for the numerical curves: 0.25 m chords (chord-length error ~ k^2 h^3 / 24).
    n = min(max(int(math.ceil(length / 0.25)), 50), 20_000)
    if kind.tag == "spiral":
        c0 = _f(kind, "curvStart", path=path)
        c1 = _f(kind, "curvEnd", path=path)
        s_f = np.linspace(0.0, length, n + 1)
        th = c0 * s_f + (c1 - c0) * s_f**2 / (2.0 * length if length > 0 else 1.0)
        cu = np.concatenate(
            [[0.0], np.cumsum(0.5 * (np.cos(th[1:]) + np.cos(th[:-1])) * np.diff(s_f))]
        )
        cv = np.concatenate(
            [[0.0], np.cumsum(0.5 * (np.sin(th[1:]) + np.sin(th[:-1])) * np.diff(s_f))]
        )
        return np.interp(ds, s_f, cu), np.interp(ds, s_f, cv), np.interp(ds, s_f, th)
    if kind.tag == "poly3":
        a, b, c, d = (_f(kind, x, 0.0, path=path) for x in "abcd")
        uu = np.linspace(0.0, max(length, 1e-9), n + 1)  # u <= arc length
        vv = a + b * uu + c * uu**2 + d * uu**3
        s_f = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(uu), np.diff(vv)))])
        slope = np.interp(ds, s_f, b + 2 * c * uu + 3 * d * uu**2)
        return np.interp(ds, s_f, uu), np.interp(ds, s_f, vv), np.arctan(slope)
    if kind.tag == "paramPoly3":
        cu_ = [_f(kind, f"{x}U", 0.0, path=path) for x in "abcd"]
        cv_ = [_f(kind, f"{x}V", 0.0, path=path) for x in "abcd"]
        p_max = 1.0 if kind.get("pRange", "normalized") == "normalized" else length
        p = np.linspace(0.0, p_max, n + 1)
        uu = cu_[0] + cu_[1] * p + cu_[2] * p**2 + cu_[3] * p**3
        vv = cv_[0] + cv_[1] * p + cv_[2] * p**2 + cv_[3] * p**3
        du = cu_[1] + 2 * cu_[2] * p + 3 * cu_[3] * p**2
        dv = cv_[1] + 2 * cv_[2] * p + 3 * cv_[3] * p**2
        s_f = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(uu), np.diff(vv)))])
        if s_f[-1] > 0:
            s_f = s_f * (length / s_f[-1])  # the file's length is authoritative
        th = np.arctan2(np.interp(ds, s_f, dv), np.interp(ds, s_f, du))
        return np.interp(ds, s_f, uu), np.interp(ds, s_f, vv), th
    raise InputError(f"unsupported OpenDRIVE geometry <{kind.tag}>", path=path)


def _plan_view(road, path: Path | None) -> list[tuple[float, float, float, float, float, Any]]:
    pv = road.find("planView")
    if pv is None:
        raise InputError(f"road {road.get('id')} has no <planView>", path=path, field="planView")
    out = []
    for g in pv.findall("geometry"):
        out.append((_f(g, "s", path=path), _f(g, "x", path=path), _f(g, "y", path=path),
                    _f(g, "hdg", path=path), _f(g, "length", path=path), g))  # fmt: skip
    out.sort(key=lambda t: t[0])
    if not out:
        raise InputError(f"road {road.get('id')} has no <geometry>", path=path, field="planView")
    return out


def _eval_plan_view(
    geoms, s: FloatArray, path: Path | None
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Reference line x, y, heading [m, m, rad] at road coordinates ``s`` [m]."""
    x = np.empty_like(s)
    y = np.empty_like(s)
    h = np.empty_like(s)
    starts = np.array([g[0] for g in geoms])
    idx = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(geoms) - 1)
    for i, (s0, x0, y0, h0, length, elem) in enumerate(geoms):
        m = idx == i
        if not m.any():
            continue
        ds = np.clip(s[m] - s0, 0.0, length)
        u, v, th = _local_geometry(elem, ds, length, path)
        c, sn = math.cos(h0), math.sin(h0)
        x[m] = x0 + c * u - sn * v
        y[m] = y0 + sn * u + c * v
        h[m] = h0 + th
    return x, y, h


def _cubic_records(
    records: list[tuple[float, float, float, float, float]], s: FloatArray
) -> FloatArray:
    """Piecewise cubic a + b ds + c ds^2 + d ds^3 (records sorted by start), evaluated at s."""
    if not records:
        return np.zeros_like(s)
    starts = np.array([r[0] for r in records])
    idx = np.clip(np.searchsorted(starts, s, side="right") - 1, 0, len(records) - 1)
    rec = np.array(records)[idx]
    ds = s - rec[:, 0]
    return rec[:, 1] + rec[:, 2] * ds + rec[:, 3] * ds**2 + rec[:, 4] * ds**3


def _sample_s(geoms, s0: float, s1: float, step_m: float) -> FloatArray:
    """Road coordinates from s0 to s1 every <= step_m, plus every geometry start inside."""
    n = max(int(math.ceil((s1 - s0) / step_m)), 1)
    inner = [g[0] for g in geoms if s0 < g[0] < s1]
    return np.unique(np.concatenate([np.linspace(s0, s1, n + 1), np.array(inner)]))


def load_roads(xodr_path: str | Path, *, step_m: float = DEFAULT_STEP_M) -> RoadGeometry:
    """Read an OpenDRIVE file into lane polygons and reference lines in its plane.

    Args:
        xodr_path: the .xodr (parsed without entity expansion).
        step_m: sampling step along each road [m] (> 0).
    Returns:
        A :class:`RoadGeometry` (coordinates in metres in the file's own x/y plane).
    Raises:
        InputError: unsafe/malformed XML, not OpenDRIVE, missing attributes, or a geometry
            type outside OpenDRIVE 1.4-1.7.
    """
    if not step_m > 0:
        raise InputError(f"step_m must be > 0, got {step_m}")
    p = Path(xodr_path)
    root = safexml.parse_file(p)
    if root.tag != "OpenDRIVE":
        raise InputError(
            f"expected an OpenDRIVE file (root <OpenDRIVE>), found <{root.tag}>", path=p
        )
    geo = root.find("header/geoReference")
    proj = None if geo is None or not (geo.text or "").strip() else " ".join(geo.text.split())
    lanes: list[Lane] = []
    refs: list[FloatArray] = []
    skipped = 0
    for road in root.findall("road"):
        rid = road.get("id", "?")
        junction = road.get("junction", "-1")
        length = _f(road, "length", path=p)
        geoms = _plan_view(road, p)
        lanes_el = road.find("lanes")
        sections = [] if lanes_el is None else lanes_el.findall("laneSection")
        starts = [_f(sec, "s", 0.0, path=p) for sec in sections]
        cuts = [st for st in starts if 0.0 < st < length]
        s_all = np.unique(np.concatenate([_sample_s(geoms, 0.0, length, step_m), np.array(cuts)]))
        x_all, y_all, h_all = _eval_plan_view(geoms, s_all, p)
        refs.append(np.column_stack([x_all, y_all]))
        if lanes_el is None:
            continue
        offsets = sorted(
            (_f(o, "s", 0.0, path=p), _f(o, "a", 0.0, path=p), _f(o, "b", 0.0, path=p),
             _f(o, "c", 0.0, path=p), _f(o, "d", 0.0, path=p))
            for o in lanes_el.findall("laneOffset")
        )  # fmt: skip
        for k, sec in enumerate(sections):
            s0 = starts[k]
            s1 = starts[k + 1] if k + 1 < len(sections) else length
            if s1 - s0 <= 1e-9:
                continue
            m = (s_all >= s0 - 1e-9) & (s_all <= s1 + 1e-9)
            s, x, y, h = s_all[m], x_all[m], y_all[m], h_all[m]
            if len(s) < 2:
                continue
            nx, ny = -np.sin(h), np.cos(h)
            t_ref = _cubic_records(offsets, s)
            for side, sign in (("right", -1.0), ("left", 1.0)):
                side_el = sec.find(side)
                if side_el is None:
                    continue
                side_lanes = sorted(
                    side_el.findall("lane"), key=lambda ln: abs(int(ln.get("id", "0")))
                )
                t_in = t_ref.copy()
                for ln in side_lanes:
                    widths = sorted(
                        (s0 + _f(w, "sOffset", 0.0, path=p), _f(w, "a", 0.0, path=p), _f(w, "b", 0.0, path=p),
                         _f(w, "c", 0.0, path=p), _f(w, "d", 0.0, path=p))
                        for w in ln.findall("width")
                    )  # fmt: skip
                    if not widths:
                        skipped += 1
                        continue
                    w = np.maximum(_cubic_records(widths, s), 0.0)
                    t_out = t_in + sign * w
                    inner = np.column_stack([x + t_in * nx, y + t_in * ny])
                    outer = np.column_stack([x + t_out * nx, y + t_out * ny])
                    lanes.append(
                        Lane(
                            rid,
                            k,
                            int(ln.get("id", "0")),
                            ln.get("type", "none"),
                            junction,
                            inner,
                            outer,
                        )
                    )
                    t_in = t_out
    if not refs:
        raise InputError("OpenDRIVE file has no road", path=p)
    from vei.maps.lanes_xodr import read_drivable_areas

    return RoadGeometry(tuple(lanes), tuple(refs), proj, skipped, p, read_drivable_areas(root))


def drivable_share(
    roads: RoadGeometry, x_m: npt.ArrayLike, y_m: npt.ArrayLike, *, tolerance_m: float = 0.0
) -> float:
    """Share of points (x, y) [m] (any equal shapes; NaN ignored) that lie on a drivable lane.

    Args:
        tolerance_m: grow the drivable area by this much first (>= 0) [m].
    Returns:
        A share in [0, 1]; NaN when no finite point is given.
    """
    import shapely

    x = np.asarray(x_m, dtype=np.float64).ravel()
    y = np.asarray(y_m, dtype=np.float64).ravel()
    if x.shape != y.shape:
        raise InputError(f"x_m and y_m differ in size: {x.size} vs {y.size}")
    if tolerance_m < 0:
        raise InputError(f"tolerance_m must be >= 0, got {tolerance_m}")
    ok = np.isfinite(x) & np.isfinite(y)
    if not ok.any():
        return float("nan")
    polys = roads.drivable_polygons
    if not polys:
        return 0.0
    xs, ys = x[ok], y[ok]
    points = shapely.STRtree(shapely.points(xs, ys))
    inside = np.zeros(xs.shape[0], dtype=bool)
    for poly in polys:
        area = poly.buffer(tolerance_m) if tolerance_m > 0 else poly
        cand = points.query(area)  # bounding-box candidates
        cand = cand[~inside[cand]]
        if cand.size:
            shapely.prepare(area)
            inside[cand] = shapely.intersects_xy(area, xs[cand], ys[cand])
    return float(np.mean(inside))


def draw_roads(
    ax, roads: RoadGeometry, *, zorder: float = -10.0, lane_lines: bool = True
) -> list[Any]:
    """Draw the map under everything else on a matplotlib Axes (plane metres, equal aspect not forced).

    Drivable lanes and drivable areas are filled grey, other lanes (sidewalks, bike lanes, ...) light grey,
    lane borders drawn as thin white lines and kerbs (:attr:`RoadGeometry.kerbs`, where the
    map has sidewalks) as dark grey lines; all at ``zorder`` (below the default 1-3 of
    lines and markers) so trajectories stay on top. The axis limits are not changed
    (``autolim=False``), so the figure keeps framing the trajectories.

    Returns:
        The artists added: [PolyCollection drivable (label 'drivable lanes'),
        PolyCollection other, LineCollection lane lines, LineCollection kerbs ('_kerbs')]
        (the last two when drawn).
    """
    from matplotlib.collections import LineCollection, PolyCollection

    drivable = list(roads.areas) + [lane.outline for lane in roads.lanes if lane.drivable]
    other = [lane.outline for lane in roads.lanes if not lane.drivable]
    artists: list[Any] = []
    pc_other = PolyCollection(
        other, facecolors=OTHER_FACE, edgecolors="none", zorder=zorder, label="_sidewalks"
    )
    pc_drive = PolyCollection(drivable, facecolors=ROAD_FACE, edgecolors=ROAD_FACE, linewidths=0.3,
                              zorder=zorder + 0.1, label="drivable lanes")  # fmt: skip
    ax.add_collection(pc_other, autolim=False)
    ax.add_collection(pc_drive, autolim=False)
    artists += [pc_drive, pc_other]
    if lane_lines:
        segs = list(roads.lane_borders)
        lc = LineCollection(
            segs, colors=LINE_COLOR, linewidths=0.5, zorder=zorder + 0.2, label="_lane lines"
        )
        ax.add_collection(lc, autolim=False)
        artists.append(lc)
    kerbs = list(roads.kerbs)
    if kerbs:
        kc = LineCollection(
            kerbs, colors=KERB_COLOR, linewidths=0.9, zorder=zorder + 0.3, label="_kerbs"
        )
        ax.add_collection(kc, autolim=False)
        artists.append(kc)
    return artists


def draw_no_map_note(ax, text: str = NO_MAP_NOTE) -> Any:
    """Say on a bird's-eye Axes that no road network is drawn (the scenario has no map);
    returns the Text artist (label '_no road map')."""
    return ax.text(
        0.01, 0.01, text, transform=ax.transAxes, fontsize=7, color="#666666", ha="left",
        va="bottom", zorder=20, label="_no road map",
    )  # fmt: skip
