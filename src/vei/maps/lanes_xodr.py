"""OpenDRIVE 1.4 from lane boundary polylines (maps that come as lanes, e.g. Argoverse 2).

Each lane (a left and a right boundary polyline in a plane, both along the direction of
travel) becomes one road: its reference line is the left boundary, resampled to at most
``step_m`` between points and written as straight ``<line>`` geometries; it has one right
lane (id -1, so right-hand traffic drives along the reference line) whose width records
(linear per geometry) put the lane's outer border on the right boundary resampled at the
same arc-length fractions. Drivable areas (polygons that are no lane: intersection
interiors, shoulders) go into the header as ``<userData code="vei:drivableAreas">``
(schema-valid: userData holds any content) and :func:`vei.maps.roads.load_roads` reads
them back; other tools see only the lanes. Lane topology (successors, neighbours) is not
written: each lane is a road without links.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np
import numpy.typing as npt

from vei.errors import InputError

FloatArray = npt.NDArray[np.float64]

#: userData code of the drivable-area polygons in the header.
DRIVABLE_AREAS_CODE = "vei:drivableAreas"
#: Default largest step between reference-line points [m].
DEFAULT_STEP_M = 2.0


@dataclass(frozen=True)
class LanePolylines:
    """One lane in a plane.

    Attributes:
        lane_id: the source's id (written as the road's name).
        left, right: [N, 2] / [M, 2] boundaries x, y [m] along the direction of travel.
        lane_type: OpenDRIVE lane type ('driving', 'biking', ...).
    """

    lane_id: str
    left: FloatArray = field(repr=False)
    right: FloatArray = field(repr=False)
    lane_type: str = "driving"


def _resample(line: FloatArray, fractions: FloatArray) -> FloatArray:
    """Points at the given fractions [K] of a polyline's arc length."""
    seg = np.hypot(*np.diff(line, axis=0).T)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    if s[-1] <= 0:
        return np.repeat(line[:1], len(fractions), axis=0)
    target = fractions * s[-1]
    return np.column_stack([np.interp(target, s, line[:, 0]), np.interp(target, s, line[:, 1])])


def _road_xml(road_id: int, lane: LanePolylines, step_m: float) -> str | None:
    left = np.asarray(lane.left, dtype=np.float64)
    right = np.asarray(lane.right, dtype=np.float64)
    length = float(np.sum(np.hypot(*np.diff(left, axis=0).T))) if len(left) > 1 else 0.0
    if len(left) < 2 or len(right) < 2 or length < 1e-3:
        return None
    k = max(len(left), len(right), math.ceil(length / step_m) + 1)
    f = np.linspace(0.0, 1.0, k)
    ref, outer = _resample(left, f), _resample(right, f)
    d = np.diff(ref, axis=0)
    seg = np.hypot(d[:, 0], d[:, 1])
    keep = seg > 1e-6
    geoms, widths, s = [], [], 0.0
    for i in np.flatnonzero(keep):
        h = math.atan2(d[i, 1], d[i, 0])
        rn = np.array([math.sin(h), -math.cos(h)])  # right normal
        wa = float(np.dot(outer[i] - ref[i], rn))
        wb = float(np.dot(outer[i + 1] - ref[i + 1], rn))
        geoms.append(
            f'<geometry s="{s:.6f}" x="{ref[i, 0]:.6f}" y="{ref[i, 1]:.6f}" hdg="{h:.9f}" '
            f'length="{seg[i]:.6f}"><line/></geometry>'
        )
        widths.append(
            f'<width sOffset="{s:.6f}" a="{max(wa, 0.0):.6f}" b="{(max(wb, 0.0) - max(wa, 0.0)) / seg[i]:.9f}" c="0" d="0"/>'
        )
        s += float(seg[i])
    name = escape(str(lane.lane_id), {'"': "&quot;"})
    return (
        f'<road name="lane {name}" length="{s:.6f}" id="{road_id}" junction="-1">'
        f"<planView>{''.join(geoms)}</planView>"
        '<lanes><laneSection s="0"><center><lane id="0" type="none" level="false"/></center>'
        f'<right><lane id="-1" type="{lane.lane_type}" level="false">{"".join(widths)}'
        '<roadMark sOffset="0" type="solid" weight="standard" color="standard" width="0.13"/>'
        "</lane></right></laneSection></lanes></road>"
    )


def write_lanes_opendrive(
    path: str | Path,
    lanes: list[LanePolylines],
    *,
    proj_string: str,
    areas: list[FloatArray] | None = None,
    name: str = "vei lanes",
    step_m: float = DEFAULT_STEP_M,
) -> Path:
    """Write lanes (and drivable-area polygons [K, 2] in the same plane) as an OpenDRIVE 1.4
    file whose geoReference is ``proj_string`` (atomically); returns the path.

    Raises:
        InputError: no lane with two points and a length.
    """
    from vei.io.atomic import write_text

    roads = [x for i, lane in enumerate(lanes) if (x := _road_xml(i + 1, lane, step_m)) is not None]
    if not roads:
        raise InputError("no lane with a length to write", path=path)
    pts = np.vstack([np.asarray(p, dtype=np.float64) for ln in lanes for p in (ln.left, ln.right)])
    area_xml = ""
    if areas:
        rings = []
        for k, ring in enumerate(areas):
            r = np.asarray(ring, dtype=np.float64)
            coords = " ".join(f"{x:.6f},{y:.6f}" for x, y in r)
            rings.append(f'<area id="{k}">{coords}</area>')
            pts = np.vstack([pts, r])
        area_xml = f'<userData code="{DRIVABLE_AREAS_CODE}">{"".join(rings)}</userData>'
    header = (
        f'<header revMajor="1" revMinor="4" name="{escape(name)}" version="1.00" '
        f'north="{pts[:, 1].max():.6f}" south="{pts[:, 1].min():.6f}" '
        f'east="{pts[:, 0].max():.6f}" west="{pts[:, 0].min():.6f}" vendor="vei">'
        f"<geoReference><![CDATA[{proj_string}]]></geoReference>{area_xml}</header>"
    )
    text = (
        '<?xml version="1.0" encoding="UTF-8"?>\n<OpenDRIVE>'
        + header
        + "\n".join(roads)
        + "</OpenDRIVE>\n"
    )
    return write_text(path, text)


def read_drivable_areas(root) -> tuple[FloatArray, ...]:
    """The drivable-area rings [K, 2] of a parsed OpenDRIVE root element (empty if none)."""
    out = []
    for ud in root.findall("header/userData"):
        if ud.get("code") != DRIVABLE_AREAS_CODE:
            continue
        for area in ud.findall("area"):
            pairs = [p.split(",") for p in (area.text or "").split()]
            try:
                ring = np.array([[float(a), float(b)] for a, b in pairs], dtype=np.float64)
            except ValueError:
                continue
            if len(ring) >= 3:
                out.append(ring)
    return tuple(out)
