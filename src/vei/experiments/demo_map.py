"""The built-in SYNTHETIC demo's road map: its street as OpenDRIVE, in the scenario's plane.

The demo scene (vei.experiments.demo_data) is drawn on a street that exists only as its
spec: an east-west two-lane street through the spec's origin (lanes ``2 x lane_width``,
the centre line at y = 0 of the spec's plane, eastbound traffic in the southern lane),
sidewalks beyond both kerbs, and a two-lane side street leaving it to the north where the
e-scooter turns in (its centre line ``lane_width / 2`` west of the rider's northbound
path, so the rider rides in the side street's right lane). This module writes that street
as an OpenDRIVE 1.4 map (roads of straight ``<line>`` geometry, driving and sidewalk
lanes) in the plane of a reconstructed demo scenario, whose origin differs from the
spec's (vei reconstruct centres the plane on the recording): every point goes through
geographic coordinates (DESIGN.md). The map is labelled synthetic in its header.

    scenario = demo_scenario()            # reconstructed demo + its map (in memory)
    write_demo_scenario(folder)           # the same as a scenario folder with map.xodr
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from pathlib import Path
from xml.sax.saxutils import escape

import numpy as np

from vei.experiments.demo_data import DemoSpec, _rider_truth, demo_interaction
from vei.geo.frame import LocalFrame
from vei.types import Scenario

#: Lane width of the demo street [m] (demo_data: lanes 3.5 m wide).
LANE_WIDTH_M = 3.5
#: Sidewalk width beyond each kerb [m] (a typical urban sidewalk; drawing only).
SIDEWALK_WIDTH_M = 2.5
#: The main street's extent east and west of the spec's origin [m] (covers the ego's run-up).
MAIN_HALF_LENGTH_M = 160.0
#: The side street's length north of the main street's kerb [m].
SIDE_LENGTH_M = 60.0
#: File name of the map in a scenario folder.
MAP_NAME = "map.xodr"


def side_street_x_m(spec: DemoSpec) -> float:
    """x [m] (spec plane) of the side street's centre line: the rider's northbound
    path (its position at the end of the recording) minus half a lane."""
    x, _, _ = _rider_truth(spec, np.array([0.0, spec.duration_s]))
    return float(x[-1]) - 0.5 * LANE_WIDTH_M


def _lane(lane_id: int, lane_type: str, width_m: float, mark: str) -> str:
    return (
        f'<lane id="{lane_id}" type="{lane_type}" level="false"><link/>'
        f'<width sOffset="0" a="{width_m:.3f}" b="0" c="0" d="0"/>'
        f'<roadMark sOffset="0" type="{mark}" weight="standard" color="standard" width="0.13"/>'
        "</lane>"
    )


def _road(road_id: int, name: str, x: float, y: float, hdg: float, length: float) -> str:
    w, sw = LANE_WIDTH_M, SIDEWALK_WIDTH_M
    left = _lane(2, "sidewalk", sw, "none") + _lane(1, "driving", w, "solid")
    right = _lane(-1, "driving", w, "solid") + _lane(-2, "sidewalk", sw, "none")
    centre = (
        '<lane id="0" type="none" level="false"><link/>'
        '<roadMark sOffset="0" type="broken" weight="standard" color="standard" width="0.13"/></lane>'
    )
    return (
        f'<road name="{escape(name)}" length="{length:.6f}" id="{road_id}" junction="-1"><link/>'
        f'<type s="0" type="town"/><planView><geometry s="0" x="{x:.6f}" y="{y:.6f}" '
        f'hdg="{hdg:.12f}" length="{length:.6f}"><line/></geometry></planView>'
        '<lanes><laneSection s="0">'
        f"<left>{left}</left><center>{centre}</center><right>{right}</right>"
        "</laneSection></lanes></road>"
    )


def demo_map_xodr(projection: str, spec: DemoSpec | None = None) -> str:
    """The demo street as OpenDRIVE 1.4 text in the plane ``projection`` (a scenario's
    tmerc PROJ string; the geoReference written into the header).

    Args:
        projection: the target plane (``Scenario.projection``).
        spec: the demo's spec (default DemoSpec()).
    Returns:
        The .xodr document (validates against the OpenDRIVE 1.4 schema).
    """
    spec = DemoSpec() if spec is None else spec
    src = LocalFrame(spec.origin_lat_deg, spec.origin_lon_deg)
    dst = LocalFrame.from_proj_string(projection)

    def seg(x0: float, y0: float, x1: float, y1: float) -> tuple[float, float, float, float]:
        lat, lon = src.to_latlon(np.array([x0, x1]), np.array([y0, y1]))
        px, py = dst.to_xy(lat, lon)
        dx, dy = float(px[1] - px[0]), float(py[1] - py[0])
        return float(px[0]), float(py[0]), math.atan2(dy, dx), math.hypot(dx, dy)

    L = MAIN_HALF_LENGTH_M
    xs = side_street_x_m(spec)
    main = seg(-L, 0.0, L, 0.0)
    side = seg(xs, LANE_WIDTH_M, xs, LANE_WIDTH_M + SIDE_LENGTH_M)
    pts = np.array([[-L, -LANE_WIDTH_M - SIDEWALK_WIDTH_M], [L, LANE_WIDTH_M + SIDE_LENGTH_M]])
    lat, lon = src.to_latlon(pts[:, 0], pts[:, 1])
    bx, by = dst.to_xy(lat, lon)
    return (
        '<?xml version="1.0" encoding="UTF-8"?>\n<OpenDRIVE>'
        f'<header revMajor="1" revMinor="4" name="vei demo street (SYNTHETIC)" version="1" '
        f'north="{by.max():.3f}" south="{by.min():.3f}" east="{bx.max():.3f}" west="{bx.min():.3f}" '
        'vendor="vei (synthetic map of the synthetic demo, not a survey)">'
        f"<geoReference><![CDATA[{dst.proj_string}]]></geoReference></header>"
        + _road(1, "demo main street", *main)
        + _road(2, "demo side street", *side)
        + "</OpenDRIVE>\n"
    )


def attach_demo_map(
    scenario: Scenario, spec: DemoSpec | None = None
) -> tuple[Scenario, dict[str, Callable[[Path], object]]]:
    """A reconstructed demo scenario naming its synthetic map, and the map's writer.

    Returns (scenario with ``maps`` = {'opendrive': 'map.xodr'} and ``extra['map']``
    saying synthetic, {'map.xodr': writer(path)}: :func:`vei.io.scenario.write_scenario`'s
    ``extra_files``).
    """
    text = demo_map_xodr(scenario.projection, spec)
    extra = dict(scenario.extra)
    extra["map"] = {"opendrive": MAP_NAME, "source": "synthetic (vei.experiments.demo_map)"}
    scen = dataclasses.replace(scenario, maps={"opendrive": MAP_NAME}, extra=extra)
    return scen, {MAP_NAME: lambda p: Path(p).write_text(text)}


def demo_scenario(spec: DemoSpec | None = None) -> Scenario:
    """The reconstructed demo scenario (vei reconstruct's defaults) naming its map (the
    map itself is written by :func:`write_demo_scenario`: a Scenario in memory has no
    folder)."""
    from vei.recon.pipeline import reconstruct

    return attach_demo_map(reconstruct(demo_interaction(spec)), spec)[0]


def write_demo_scenario(folder: str | Path, spec: DemoSpec | None = None) -> Path:
    """Write the reconstructed demo with its synthetic map as a scenario folder (atomic).

    Returns the folder (scenario.json, trajectories.parquet, keyframes.parquet, map.xodr).
    """
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    scen, files = attach_demo_map(reconstruct(demo_interaction(spec)), spec)
    return write_scenario(scen, folder, extra_files=files)


__all__ = [
    "LANE_WIDTH_M",
    "attach_demo_map",
    "MAP_NAME",
    "SIDEWALK_WIDTH_M",
    "demo_map_xodr",
    "demo_scenario",
    "side_street_x_m",
    "write_demo_scenario",
]
