"""Building outlines of a scenario's OpenStreetMap source, in the scenario's plane.

OpenDRIVE maps built by netconvert carry no buildings, but a scenario whose map was built
from OpenStreetMap keeps the OSM file (``scenario.maps['osm']``): its closed ways tagged
``building=*`` (and multipolygon relations' outer ways) are the outlines a continuation
must not cross. Read with the project's safe XML parser (:mod:`vei.maps.safexml`);
``.osm`` and ``.osm.gz`` / ``.osm.bz2`` files. A ``.osm.pbf`` needs osmium (extra
``maps``) and is read with it when installed.
"""

from __future__ import annotations

from functools import lru_cache
from pathlib import Path
from typing import Any

import numpy as np

from vei.geo.frame import LocalFrame


def _outlines_xml(path: Path) -> list[list[tuple[float, float]]]:
    """[(lat, lon), ...] rings of the buildings of an OSM XML file."""
    from vei.maps.safexml import parse_file

    root = parse_file(path)
    nodes = {
        n.get("id"): (float(n.get("lat", "nan")), float(n.get("lon", "nan")))
        for n in root.iter("node")
    }
    ways: dict[str, list[str]] = {}
    rings = []
    for w in root.iter("way"):
        refs = [nd.get("ref") for nd in w.iter("nd")]
        ways[w.get("id", "")] = refs
        if any(t.get("k") == "building" for t in w.iter("tag")):
            rings.append(refs)
    for r in root.iter("relation"):
        tags = {t.get("k"): t.get("v") for t in r.iter("tag")}
        if "building" not in tags:
            continue
        for m in r.iter("member"):
            if m.get("type") == "way" and m.get("role", "outer") == "outer":
                rings.append(ways.get(m.get("ref", ""), []))
    out = []
    for refs in rings:
        pts = [nodes[r] for r in refs if r in nodes]
        if len(pts) >= 4 and refs[0] == refs[-1]:
            out.append(pts)
    return out


def _outlines_pbf(path: Path) -> list[list[tuple[float, float]]]:
    import osmium

    out: list[list[tuple[float, float]]] = []
    for obj in osmium.FileProcessor(str(path)).with_locations():
        if obj.is_way() and "building" in obj.tags and obj.is_closed():
            pts = [(n.lat, n.lon) for n in obj.nodes if n.location.valid()]
            if len(pts) >= 4:
                out.append(pts)
    return out


@lru_cache(maxsize=8)
def _load(path: str, mtime_ns: int, projection: str) -> Any:
    import shapely
    from shapely.geometry import Polygon

    p = Path(path)
    rings = _outlines_pbf(p) if p.name.endswith(".pbf") else _outlines_xml(p)
    frame = LocalFrame.from_proj_string(projection)
    polys = []
    for ring in rings:
        lat = np.array([q[0] for q in ring])
        lon = np.array([q[1] for q in ring])
        if not (np.isfinite(lat).all() and np.isfinite(lon).all()):
            continue
        x, y = frame.to_xy(lat, lon)
        poly = Polygon(np.column_stack([x, y]))
        if not poly.is_valid:
            poly = poly.buffer(0)
        if not poly.is_empty:
            polys.append(poly)
    return shapely.union_all(polys) if polys else None


def load_buildings(osm_path: str | Path, projection: str) -> Any:
    """The union of the building outlines (shapely geometry in the plane of
    ``projection``, metres), or None when the file has none. Cached per file."""
    p = Path(osm_path)
    return _load(str(p), p.stat().st_mtime_ns, projection)
