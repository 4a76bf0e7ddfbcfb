"""Road maps: OSM acquisition (extract crop, Overpass), netconvert -> OpenDRIVE, road geometry.

Heavy dependencies (osmium, SUMO, carla, xmlschema/lxml, matplotlib) are imported inside the
functions that need them, so importing this package is cheap.
"""

from vei.maps.attach import MapConfig, attach_map, resolve_source
from vei.maps.build import MapBuildResult, build_opendrive
from vei.maps.fetch import crop_osm, fetch_osm, fetch_overpass, osm_data_bounds, overpass_query
from vei.maps.roads import (
    Lane,
    RoadGeometry,
    draw_no_map_note,
    draw_roads,
    drivable_share,
    load_roads,
)
from vei.maps.validate import ValidationReport, carla_check, validate_opendrive

__all__ = [
    "Lane",
    "MapBuildResult",
    "MapConfig",
    "RoadGeometry",
    "ValidationReport",
    "attach_map",
    "build_opendrive",
    "carla_check",
    "crop_osm",
    "draw_no_map_note",
    "draw_roads",
    "drivable_share",
    "fetch_osm",
    "fetch_overpass",
    "load_roads",
    "osm_data_bounds",
    "overpass_query",
    "resolve_source",
    "validate_opendrive",
]
