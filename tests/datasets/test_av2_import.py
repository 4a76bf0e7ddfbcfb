"""Argoverse 2 import on a SYNTHETIC scenario written by the av2 package's own writer (the
PyPI wheel ships no test scenario: checked below) and a synthetic map archive in av2's
schema (tests/datasets/synthetic_av2.py)."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from tests.datasets import synthetic_av2 as syn
from vei.datasets import av2
from vei.datasets.world_import import import_tracks
from vei.errors import InputError
from vei.io.interaction import read_interaction
from vei.maps.roads import drivable_share, load_roads
from vei.maps.validate import validate_opendrive
from vei.recon.pipeline import reconstruct

pytest.importorskip("av2.datasets.motion_forecasting.scenario_serialization")


def test_the_av2_wheel_ships_no_scenario():
    """Why the scenario is regenerated: the installed package holds no parquet test data."""
    root = Path(importlib.util.find_spec("av2").origin).parent
    assert not list(root.rglob("*.parquet"))


@pytest.fixture(scope="module")
def scenario_dir(tmp_path_factory):
    return syn.write(tmp_path_factory.mktemp("synthetic_av2"))


def test_classes_units_and_city_frame(scenario_dir):
    from av2.geometry.utm import CityName, convert_city_coords_to_wgs84

    rec = av2.read_recording(scenario_dir.parent, syn.SCENARIO_ID)
    cats = rec.category_of()
    assert cats["1001"] == "cyclist" and cats["1003"] == "cyclist"  # cyclist, motorcyclist
    assert cats["1005"] == ""  # a riderless bicycle is not imported
    assert rec.rate_hz == pytest.approx(10.0)
    av = rec.track("AV")
    assert av["t_s"].iloc[-1] == pytest.approx(10.9)
    assert av["speed_mps"].iloc[0] == pytest.approx(8.0)
    # the same WGS84 point as av2's own conversion
    start = syn.CENTRE + (-50.0, -syn.LANE_W / 2)
    (lat, lon), = convert_city_coords_to_wgs84(np.array([start]), CityName.PIT)  # fmt: skip
    assert av["lat_deg"].iloc[0] == pytest.approx(lat, abs=1e-9)
    assert av["lon_deg"].iloc[0] == pytest.approx(lon, abs=1e-9)


def test_av_as_ego_with_its_converted_map(scenario_dir, tmp_path):
    rec = av2.read_recording(scenario_dir.parent, syn.SCENARIO_ID)
    (w,) = import_tracks(rec, tmp_path / "out", ego=av2.AV_TRACK_ID)
    inter = read_interaction(w.folder)
    assert inter.meta.frame == "world" and inter.meta.origin_lat_deg is not None
    xodr = w.folder / "map.xodr"
    report = validate_opendrive(xodr)
    assert report.valid, report.issues[:3]
    roads = load_roads(xodr)
    archive = syn.map_archive()
    assert len(roads.lanes) == len(archive["lane_segments"])
    assert len(roads.areas) == len(archive["drivable_areas"])
    scen = reconstruct(inter)
    assert scen.projection == roads.proj_string  # one plane: the map is used unchanged
    ego = scen.track("ego")
    assert drivable_share(roads, ego["x_m"], ego["y_m"]) > 0.99
    # a lane's converted left border lies on the archive's boundary (through the geodesy)
    from vei.geo.frame import LocalFrame

    grid = av2.city_grid(syn.CITY)
    plane = LocalFrame.from_proj_string(roads.proj_string)
    seg = archive["lane_segments"]["100"]
    pts = np.array([[p["x"], p["y"]] for p in seg["left_lane_boundary"]])
    lat, lon = grid.to_latlon(pts[:, 0], pts[:, 1])
    x, y = plane.to_xy(lat, lon)
    from shapely.geometry import LineString, Point

    lane = next(ln for ln in roads.lanes if ln.road_id == "1")
    border = LineString(lane.inner)
    assert max(border.distance(Point(px, py)) for px, py in zip(x, y, strict=True)) < 0.01


def test_every_vehicle_in_reach_becomes_an_ego(scenario_dir, tmp_path):
    rec = av2.read_recording(scenario_dir.parent, syn.SCENARIO_ID)
    written = import_tracks(rec, tmp_path / "all")
    assert {w.ego_id for w in written} == {"AV", "1002"}  # 1006 is parked


def test_bad_parquet_names_row_and_column(scenario_dir, tmp_path):
    path = next(scenario_dir.glob("scenario_*.parquet"))
    df = pd.read_parquet(path)
    df.loc[17, "object_type"] = "hovercraft"
    bad = tmp_path / "bad" / syn.SCENARIO_ID
    bad.mkdir(parents=True)
    df.to_parquet(bad / path.name)
    with pytest.raises(InputError) as exc:
        av2.read_recording(bad.parent, syn.SCENARIO_ID)
    assert exc.value.row == 18 and exc.value.field == "object_type"
    df = pd.read_parquet(path).drop(columns=["heading"])
    df.to_parquet(bad / path.name)
    with pytest.raises(InputError, match="missing column") as exc:
        av2.read_recording(bad.parent, syn.SCENARIO_ID)
    assert exc.value.field == "heading"
