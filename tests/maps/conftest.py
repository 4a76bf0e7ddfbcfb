"""Shared map fixtures: netconvert runs once per session on small real inputs."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import require_data
from vei.geo import Bounds

#: The trafficmonitoring intersection in Ingolstadt (UTM 32N 678200 E, 5405300 N) [deg].
INGOLSTADT_ORIGIN = (48.775163205487885, 11.425535264419755)


@pytest.fixture(scope="session")
def west_oakland_osm() -> Path:
    return require_data("osm", "west_oakland.osm")


@pytest.fixture(scope="session")
def helsinki_pbf() -> Path:
    return require_data("osm", "helsinki.osm.pbf")


@pytest.fixture(scope="session")
def ingolstadt_net() -> Path:
    return require_data("maps", "ingolstadt_research_intersection.net.xml.gz")


@pytest.fixture(scope="session")
def west_oakland_map(tmp_path_factory, west_oakland_osm):
    """netconvert build of west_oakland.osm centred on (37.8076, -122.3004)."""
    from vei.maps.build import build_opendrive

    out = tmp_path_factory.mktemp("wo") / "map.xodr"
    return build_opendrive(west_oakland_osm, out, origin=(37.8076, -122.3004))


@pytest.fixture(scope="session")
def ingolstadt_map(tmp_path_factory, ingolstadt_net):
    """The Ingolstadt SUMO net re-projected into a tmerc plane on the intersection (300 m clip)."""
    from vei.maps.build import build_opendrive

    out = tmp_path_factory.mktemp("ing") / "map.xodr"
    clip = Bounds.around(INGOLSTADT_ORIGIN[0], INGOLSTADT_ORIGIN[1], margin_m=300.0)
    return build_opendrive(ingolstadt_net, out, origin=INGOLSTADT_ORIGIN, clip=clip)


@pytest.fixture(scope="session")
def ingolstadt_roads(ingolstadt_map):
    from vei.maps.roads import load_roads

    return load_roads(ingolstadt_map.opendrive)
