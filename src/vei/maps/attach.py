"""Attach a road map to a scenario: bounds -> configured OSM source -> OpenDRIVE in its frame.

The *configured OSM source* (what ``source="auto"`` means) is, in order:

1. the environment variable ``VEI_OSM_SOURCE``: a local extract (``.osm``, ``.osm.gz``,
   ``.osm.bz2``, ``.osm.pbf``), a ready map (``.net.xml(.gz)``, ``.xodr``), or ``overpass``;
2. otherwise ``overpass`` (endpoint from ``VEI_OVERPASS_URL``, default
   :data:`vei.maps.fetch.DEFAULT_OVERPASS_URL`).

An explicit ``source`` path or ``"overpass"`` overrides the environment.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from vei.errors import ConfigError
from vei.geo import Bounds, LocalFrame
from vei.maps.build import CONVERTERS, build_opendrive, source_kind
from vei.maps.fetch import DEFAULT_OVERPASS_URL, fetch_osm

ENV_OSM_SOURCE = "VEI_OSM_SOURCE"
ENV_OVERPASS_URL = "VEI_OVERPASS_URL"


@dataclass(frozen=True)
class MapConfig:
    """How :func:`attach_map` gets and builds the map.

    Attributes:
        source: 'auto' (see module doc), 'overpass', or a file path (OSM extract, SUMO
            net, OpenDRIVE).
        overpass_url: Overpass API endpoint.
        timeout_s: Overpass request timeout [s] (> 0).
        retries: Overpass retries after the first attempt (>= 0).
        converter: 'netconvert' or 'carla'.
        traffic_lights: build traffic lights from OSM signal nodes.
        clip_margin_m: for SUMO-network sources, keep edges within the scenario bounds grown by
            this margin [m] (>= 0); OSM sources are cropped to the bounds (complete ways).
    """

    source: str = "auto"
    overpass_url: str = DEFAULT_OVERPASS_URL
    timeout_s: float = 90.0
    retries: int = 3
    converter: str = "netconvert"
    traffic_lights: bool = False
    clip_margin_m: float = 100.0

    def __post_init__(self) -> None:
        if not self.source:
            raise ConfigError("map source must not be empty ('auto', 'overpass' or a file)")
        if not self.timeout_s > 0:
            raise ConfigError(f"timeout_s must be > 0, got {self.timeout_s}")
        if self.retries < 0:
            raise ConfigError(f"retries must be >= 0, got {self.retries}")
        if self.converter not in CONVERTERS:
            raise ConfigError(f"converter must be one of {CONVERTERS}, got {self.converter!r}")
        if self.clip_margin_m < 0:
            raise ConfigError(f"clip_margin_m must be >= 0, got {self.clip_margin_m}")

    @classmethod
    def from_env(cls, **overrides: Any) -> MapConfig:
        """Defaults, the overpass URL from ``VEI_OVERPASS_URL`` if set, then ``overrides``."""
        url = os.environ.get(ENV_OVERPASS_URL) or DEFAULT_OVERPASS_URL
        kwargs: dict[str, Any] = {"overpass_url": url}
        kwargs.update(overrides)
        return cls(**kwargs)


def resolve_source(source: str | Path = "auto") -> str:
    """The concrete source for ``source``: 'auto' -> $VEI_OSM_SOURCE or 'overpass'."""
    src = str(source)
    if src == "auto":
        src = os.environ.get(ENV_OSM_SOURCE, "").strip() or "overpass"
    if src != "overpass":
        p = Path(src).expanduser()
        source_kind(p)  # raises InputError on an unknown kind
        src = str(p)
    return src


def attach_map(
    bounds: Bounds,
    frame: LocalFrame,
    out_dir: str | Path,
    *,
    source: str | Path = "auto",
    config: MapConfig | None = None,
) -> dict[str, Any]:
    """Fetch and build the scenario's road map into ``out_dir``.

    Args:
        bounds: the scenario's geographic bounds [deg] (the region to fetch / keep).
        frame: the scenario's plane; the OpenDRIVE geoReference is ``frame.proj_string``.
        out_dir: folder to write into (created).
        source: 'auto', 'overpass' or a file; overrides ``config.source`` unless 'auto'.
        config: a :class:`MapConfig` (default: :meth:`MapConfig.from_env`).
    Returns:
        {'opendrive': 'map.xodr', 'osm': 'map.osm' or None, 'sumo_net': 'map.net.xml' or
        None (file names relative to out_dir), 'source': the resolved source,
        'converter', 'projection': proj string, 'opendrive_version': 'MAJOR.MINOR',
        'schema_valid': bool, 'schema_issues': int}.
    Raises:
        InputError / DependencyError / BackendError from fetching, building or validating.
    """
    from vei.maps.validate import validate_opendrive

    cfg = config if config is not None else MapConfig.from_env()
    chosen = str(source) if str(source) != "auto" else cfg.source
    resolved = resolve_source(chosen)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    origin = (frame.origin_lat_deg, frame.origin_lon_deg)
    osm_name: str | None = None
    if resolved == "overpass" or source_kind(resolved) == "osm":
        osm_path = out / "map.osm"
        fetch_osm(bounds, osm_path, source=resolved, overpass_url=cfg.overpass_url,
                  timeout_s=cfg.timeout_s, retries=cfg.retries)  # fmt: skip
        osm_name = osm_path.name
        result = build_opendrive(osm_path, out / "map.xodr", origin=origin, converter=cfg.converter,
                                 traffic_lights=cfg.traffic_lights)  # fmt: skip
    else:
        clip = None
        if source_kind(resolved) == "sumo-net":
            lat = [bounds.south_deg, bounds.north_deg]
            lon = [bounds.west_deg, bounds.east_deg]
            clip = Bounds.around(lat, lon, cfg.clip_margin_m)
        result = build_opendrive(resolved, out / "map.xodr", origin=origin, converter="netconvert",
                                 traffic_lights=cfg.traffic_lights, clip=clip)  # fmt: skip
    report = validate_opendrive(result.opendrive)
    return {
        "opendrive": result.opendrive.name,
        "osm": osm_name,
        "sumo_net": None if result.sumo_net is None else result.sumo_net.name,
        "source": resolved,
        "converter": result.converter,
        "projection": result.proj_string,
        "opendrive_version": report.version,
        "schema_valid": report.valid,
        "schema_issues": len(report.issues),
    }
