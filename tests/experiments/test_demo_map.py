"""The demo's synthetic street map: valid OpenDRIVE in the scenario's plane, the demo's
ego and rider on its drivable lanes, the street where the spec puts it."""

from __future__ import annotations

import numpy as np
import pytest

from vei.experiments.demo_data import DemoSpec
from vei.experiments.demo_map import LANE_WIDTH_M, SIDEWALK_WIDTH_M, write_demo_scenario


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    return write_demo_scenario(tmp_path_factory.mktemp("dm") / "demo")


def test_map_is_valid_and_under_the_tracks(folder):
    from vei.geo import LocalFrame
    from vei.io.scenario import read_scenario
    from vei.maps import drivable_share, load_roads
    from vei.maps.validate import validate_opendrive

    assert validate_opendrive(folder / "map.xodr").issues == ()
    scen = read_scenario(folder)
    assert scen.maps == {"opendrive": "map.xodr"}
    roads = load_roads(folder / "map.xodr")
    assert roads.proj_string == scen.projection
    for aid in ("ego", scen.primary_threat):
        tr = scen.track(aid)
        assert drivable_share(roads, tr["x_m"], tr["y_m"]) == 1.0
    # the street's centre line at the spec's y = 0, in the scenario's plane
    spec = DemoSpec()
    src = LocalFrame(spec.origin_lat_deg, spec.origin_lon_deg)
    dst = LocalFrame.from_proj_string(scen.projection)
    lat, lon = src.to_latlon(np.array([0.0]), np.array([0.0]))
    cx, cy = dst.to_xy(lat, lon)
    main_right = next(ln for ln in roads.lanes if ln.road_id == "1" and ln.lane_id == -1)
    i = int(np.argmin(np.abs(main_right.inner[:, 0] - cx[0])))
    assert main_right.inner[i, 1] == pytest.approx(cy[0], abs=0.01)
    assert main_right.outer[i, 1] == pytest.approx(cy[0] - LANE_WIDTH_M, abs=0.01)
    kerbs = roads.kerbs
    assert len(kerbs) == 4  # two sidewalks on each of the two roads
    walk = next(ln for ln in roads.lanes if ln.road_id == "1" and ln.lane_id == -2)
    assert walk.outer[i, 1] == pytest.approx(cy[0] - LANE_WIDTH_M - SIDEWALK_WIDTH_M, abs=0.01)
