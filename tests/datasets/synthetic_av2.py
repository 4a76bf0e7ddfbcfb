"""A SYNTHETIC Argoverse 2 motion-forecasting scenario, written with the av2 package's own
dataclasses and writer (the PyPI av2 wheel ships no test scenario), and a synthetic map
archive in av2's JSON schema: a four-way intersection in Pittsburgh's city frame.

Nothing here is real Argoverse data: the geometry is made up, the schema is av2's.
``python -m tests.datasets.synthetic_av2 --figure docs/figures/av2_map_conversion.png``
draws the map conversion under the tracks (the figure docs/datasets.md shows).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

SCENARIO_ID = "synthetic-0000-av2"
CITY = "PIT"
#: Where the synthetic intersection lies in PIT's city frame [m].
CENTRE = np.array([2000.0, 1500.0])
LANE_W = 3.5
NUM_STEPS = 110
DT_S = 0.1


def _pts(xy: np.ndarray) -> list[dict]:
    return [{"x": float(x), "y": float(y), "z": 0.0} for x, y in xy]


def _line(a, b, n: int = 12) -> np.ndarray:
    return np.linspace(np.asarray(a, float), np.asarray(b, float), n)


def map_archive() -> dict:
    """Lane segments (two lanes per direction on an east-west road, one per direction on a
    north-south road, a bike lane, two turning lanes through the intersection) and drivable
    areas (the intersection square, the corners' shoulders), in av2's JSON schema."""
    c = CENTRE
    segs = {}

    def add(seg_id: int, left: np.ndarray, right: np.ndarray, lane_type="VEHICLE", inter=False):
        segs[str(seg_id)] = {
            "id": seg_id,
            "is_intersection": inter,
            "lane_type": lane_type,
            "left_lane_boundary": _pts(left),
            "right_lane_boundary": _pts(right),
            "left_lane_mark_type": "SOLID_YELLOW",
            "right_lane_mark_type": "DASHED_WHITE",
            "right_neighbor_id": None,
            "left_neighbor_id": None,
            "predecessors": [],
            "successors": [],
        }

    h = 2 * LANE_W  # half width of the carriageway
    sid = 100
    for sign in (-1, 1):  # west (-1) and east (+1) arms
        x0, x1 = c[0] + sign * h, c[0] + sign * 70.0
        for k in range(2):  # eastbound lanes below the centre line, westbound above
            yl, yr = c[1] - k * LANE_W, c[1] - (k + 1) * LANE_W
            a, b = (x1, x0) if sign < 0 else (x0, x1)
            add(sid, _line((a, yl), (b, yl)), _line((a, yr), (b, yr)))
            sid += 1
            yl, yr = c[1] + k * LANE_W, c[1] + (k + 1) * LANE_W
            add(sid, _line((b, yl), (a, yl)), _line((b, yr), (a, yr)))
            sid += 1
        yb = c[1] - h - 1.5
        a, b = (x1, x0) if sign < 0 else (x0, x1)
        add(sid, _line((a, c[1] - h), (b, c[1] - h)), _line((a, yb), (b, yb)), "BIKE")
        sid += 1
    for sign in (-1, 1):  # south and north arms, one lane per direction
        y0, y1 = c[1] + sign * h, c[1] + sign * 60.0
        a, b = (y1, y0) if sign < 0 else (y0, y1)
        add(sid, _line((c[0], a), (c[0], b)), _line((c[0] + LANE_W, a), (c[0] + LANE_W, b)))
        sid += 1
        add(sid, _line((c[0], b), (c[0], a)), _line((c[0] - LANE_W, b), (c[0] - LANE_W, a)))
        sid += 1
    # through lanes and a right turn inside the intersection
    add(
        sid,
        _line((c[0] - h, c[1]), (c[0] + h, c[1])),
        _line((c[0] - h, c[1] - LANE_W), (c[0] + h, c[1] - LANE_W)),
        inter=True,
    )
    sid += 1
    ang = np.linspace(math.pi / 2, 0.0, 16)
    r_in, r_out = h - LANE_W, h
    corner = np.array([c[0] - h, c[1] - h])
    add(sid, corner + r_out * np.column_stack([np.cos(ang), np.sin(ang)]) * [1, 1] + [0, 0],
        corner + r_in * np.column_stack([np.cos(ang), np.sin(ang)]), inter=True)  # fmt: skip
    areas = {
        "1": {"id": 1, "area_boundary": _pts(np.array([c + (-h, -h), c + (h, -h), c + (h, h), c + (-h, h)]))},
        "2": {"id": 2, "area_boundary": _pts(np.array([c + (h, h), c + (70, h), c + (70, h + 2.5), c + (h, h + 2.5)]))},
    }  # fmt: skip
    return {"pedestrian_crossings": {}, "lane_segments": segs, "drivable_areas": areas}


def _track(track_id, object_type, xy, heading, v, category=2, steps=None):
    from av2.datasets.motion_forecasting.data_schema import (
        ObjectState,
        ObjectType,
        Track,
        TrackCategory,
    )

    steps = range(len(xy)) if steps is None else steps
    states = [
        ObjectState(observed=int(k) < 50, timestep=int(k), position=(float(p[0]), float(p[1])),
                    heading=float(hd), velocity=(float(vv[0]), float(vv[1])))
        for k, p, hd, vv in zip(steps, xy, heading, v, strict=True)
    ]  # fmt: skip
    return Track(track_id, states, ObjectType(object_type), TrackCategory(category))


def _straight(start, velocity, n=NUM_STEPS):
    t = np.arange(n) * DT_S
    xy = np.asarray(start, float) + t[:, None] * np.asarray(velocity, float)
    h = np.full(n, math.atan2(velocity[1], velocity[0]))
    return xy, h, np.tile(velocity, (n, 1))


def scenario():
    """The synthetic scenario as av2's ArgoverseScenario: the AV eastbound at 8 m/s in the
    inner lane, a cyclist northbound crossing in front of it, a second vehicle westbound, a
    motorcyclist eastbound in the bike lane's neighbour lane, a pedestrian, a riderless
    bicycle (not imported) and a parked vehicle (never an ego)."""
    from av2.datasets.motion_forecasting.data_schema import ArgoverseScenario

    c = CENTRE
    tracks = [
        _track("AV", "vehicle", *_straight(c + (-50.0, -LANE_W / 2), (8.0, 0.0)), category=3),
        _track("1001", "cyclist", *_straight(c + (LANE_W / 2, -45.0), (0.0, 4.5))),
        _track("1002", "vehicle", *_straight(c + (55.0, LANE_W / 2), (-7.0, 0.0))),
        _track("1003", "motorcyclist", *_straight(c + (-60.0, -1.5 * LANE_W), (9.0, 0.0))),
        _track("1004", "pedestrian", *_straight(c + (-12.0, 12.0), (0.0, -1.2))),
        _track("1005", "riderless_bicycle", *_straight(c + (-20.0, -10.0), (0.0, 0.0))),
        _track("1006", "vehicle", *_straight(c + (30.0, 9.5), (0.0, 0.0)), category=1),
    ]
    ts = (1_700_000_000_000_000_000 + np.arange(NUM_STEPS) * int(DT_S * 1e9)).astype(np.int64)
    return ArgoverseScenario(SCENARIO_ID, ts, tracks, "AV", CITY, None, None)


def write(folder: Path) -> Path:
    """Write the scenario folder (scenario_<id>.parquet with av2's writer, the map archive);
    returns the folder."""
    from av2.datasets.motion_forecasting.scenario_serialization import (
        serialize_argoverse_scenario_parquet,
    )

    folder = Path(folder) / SCENARIO_ID
    folder.mkdir(parents=True, exist_ok=True)
    serialize_argoverse_scenario_parquet(folder / f"scenario_{SCENARIO_ID}.parquet", scenario())
    (folder / f"log_map_archive_{SCENARIO_ID}.json").write_text(
        json.dumps(map_archive()), encoding="utf-8"
    )
    return folder


def draw_figure(out_png: Path, work: Path) -> Path:
    """Import the synthetic scenario (ego AV), reconstruct it with its converted map and
    draw the bird's-eye figure (map under the tracks) to ``out_png``."""
    import matplotlib

    matplotlib.use("Agg")
    from vei.datasets.av2 import read_recording
    from vei.datasets.world_import import import_tracks
    from vei.io.interaction import read_interaction
    from vei.maps import draw_roads
    from vei.maps.scenario_map import add_map
    from vei.recon.pipeline import reconstruct
    from vei.report.birdseye import plot_birdseye, save_figure

    root = write(work / "av2")
    rec = read_recording(root, SCENARIO_ID)
    (written,) = import_tracks(rec, work / "inter", ego="AV", road_users="all")
    scen = reconstruct(read_interaction(written.folder))
    scen, _files, roads = add_map(scen, work / "map", source=written.folder / "map.xodr")
    fig = plot_birdseye(
        scen,
        title="SYNTHETIC Argoverse 2 scenario: map archive -> OpenDRIVE, under the tracks",
        roads=lambda ax: draw_roads(ax, roads),
    )
    save_figure(fig, out_png)
    return out_png


if __name__ == "__main__":
    import argparse
    import tempfile

    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--figure", type=Path, required=True)
    args = p.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        print(draw_figure(args.figure, Path(tmp)))
