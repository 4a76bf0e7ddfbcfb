"""attach_map: bounds -> configured OSM source -> OpenDRIVE in the scenario frame."""

from __future__ import annotations

import pytest

from tests.maps.conftest import INGOLSTADT_ORIGIN
from tests.maps.test_fetch import WO_BOX, overpass_server
from vei.errors import ConfigError, InputError
from vei.geo import Bounds, LocalFrame
from vei.maps.attach import ENV_OSM_SOURCE, ENV_OVERPASS_URL, MapConfig, attach_map, resolve_source
from vei.maps.validate import read_header


def test_resolve_source_reads_the_environment(monkeypatch, west_oakland_osm):
    monkeypatch.delenv(ENV_OSM_SOURCE, raising=False)
    assert resolve_source("auto") == "overpass"
    monkeypatch.setenv(ENV_OSM_SOURCE, str(west_oakland_osm))
    assert resolve_source("auto") == str(west_oakland_osm)
    assert resolve_source("overpass") == "overpass"
    monkeypatch.setenv(ENV_OSM_SOURCE, "/data/roads.shp")
    with pytest.raises(InputError, match="map source must be"):
        resolve_source("auto")


def test_map_config_validation():
    with pytest.raises(ConfigError):
        MapConfig(retries=-1)
    with pytest.raises(ConfigError):
        MapConfig(timeout_s=0.0)
    with pytest.raises(ConfigError):
        MapConfig(converter="osm2xodr")
    with pytest.raises(ConfigError):
        MapConfig(source="")


def test_attach_from_a_local_extract_via_the_environment(monkeypatch, west_oakland_osm, tmp_path):
    monkeypatch.setenv(ENV_OSM_SOURCE, str(west_oakland_osm))
    frame = LocalFrame(*WO_BOX.center)
    info = attach_map(WO_BOX, frame, tmp_path / "scn")
    assert (
        info["opendrive"] == "map.xodr"
        and info["osm"] == "map.osm"
        and info["sumo_net"] == "map.net.xml"
    )
    for key in ("opendrive", "osm", "sumo_net"):
        assert (tmp_path / "scn" / info[key]).is_file()
    assert info["projection"] == frame.proj_string == read_header(tmp_path / "scn" / "map.xodr")[2]
    assert (
        info["schema_valid"] and info["schema_issues"] == 0 and info["opendrive_version"] == "1.4"
    )
    assert info["source"] == str(west_oakland_osm)


def test_attach_through_overpass_on_loopback(monkeypatch, west_oakland_osm, tmp_path):
    monkeypatch.delenv(ENV_OSM_SOURCE, raising=False)
    with overpass_server(west_oakland_osm, ["ok"]) as (url, queries):
        monkeypatch.setenv(ENV_OVERPASS_URL, url)
        info = attach_map(WO_BOX, LocalFrame(*WO_BOX.center), tmp_path / "scn")
    assert len(queries) == 1
    assert info["source"] == "overpass" and info["schema_valid"]


def test_attach_a_sumo_net_is_clipped_to_the_bounds(ingolstadt_net, tmp_path):
    from vei.maps.roads import load_roads

    bounds = Bounds.around(INGOLSTADT_ORIGIN[0], INGOLSTADT_ORIGIN[1], margin_m=60.0)
    frame = LocalFrame(*INGOLSTADT_ORIGIN)
    info = attach_map(bounds, frame, tmp_path / "scn", source=str(ingolstadt_net),
                      config=MapConfig(clip_margin_m=40.0))  # fmt: skip
    assert info["osm"] is None and info["schema_valid"]
    x0, y0, x1, y1 = load_roads(tmp_path / "scn" / "map.xodr").bounds_xy
    # Edges crossing the 100 m box are kept whole, so the map reaches a bit beyond it, but
    # nothing of the 2 km network far away.
    assert -400 < x0 < -60 and 60 < x1 < 400 and -400 < y0 < -60 and 60 < y1 < 400
