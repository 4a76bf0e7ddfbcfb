"""OpenDRIVE checks: XSD validation (xmlschema) and CARLA's own parser (offline).

* :func:`validate_opendrive` validates a .xodr against the official OpenDRIVE XML schema of
  the revision its header declares (``revMajor``/``revMinor``); the schemas ship in
  ``vei/maps/schemas`` (from asam-qc-opendrive, see the README there). SUMO netconvert
  writes OpenDRIVE 1.4, validated against ``OpenDRIVE_1.4H.xsd``.
* :func:`carla_check` loads the map with ``carla.Map(name, xodr_text)`` from the ``carla``
  client package -- the parser a CARLA server uses for ``generate_opendrive_world`` -- and
  generates waypoints on its driving lanes.
"""

from __future__ import annotations

import functools
import math
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

from vei.errors import ConfigError, DependencyError, InputError
from vei.maps import safexml

SCHEMA_DIR = Path(__file__).resolve().parent / "schemas"
#: OpenDRIVE minor revision -> schema entry file (relative to SCHEMA_DIR).
SCHEMA_FILES: dict[int, str] = {
    4: "OpenDRIVE_1.4H.xsd",
    5: "OpenDRIVE_1.5M.xsd",
    6: "1.6/opendrive_16_core.xsd",
    7: "1.7/opendrive_17_core.xsd",
}


@dataclass(frozen=True)
class SchemaIssue:
    """One XSD violation: the element path (XPath-like) and the validator's reason."""

    path: str
    reason: str


@dataclass(frozen=True)
class ValidationReport:
    """Result of validating an OpenDRIVE file against the XSD.

    Attributes:
        path: the file checked.
        rev_major, rev_minor: OpenDRIVE revision declared in the header.
        schema: schema file used (relative to ``vei/maps/schemas``).
        issues: every violation found (empty when valid).
        note: remark on the schema choice (e.g. a newer revision checked with 1.7), or "".
        validator: 'lxml' or 'xmlschema'.
    """

    path: Path
    rev_major: int
    rev_minor: int
    schema: str
    issues: tuple[SchemaIssue, ...]
    note: str = ""
    validator: str = "xmlschema"

    @property
    def valid(self) -> bool:
        """True when the file has no schema violation."""
        return not self.issues

    @property
    def version(self) -> str:
        """'MAJOR.MINOR' as declared in the header."""
        return f"{self.rev_major}.{self.rev_minor}"

    def summary(self) -> dict[str, int]:
        """Violation counts by (element tag, reason) -> {'<tag>: <reason>': count}."""
        counts: Counter[str] = Counter()
        for issue in self.issues:
            tag = issue.path.rstrip("/").rsplit("/", 1)[-1].split("[")[0] if issue.path else "?"
            counts[f"{tag}: {issue.reason}"] += 1
        return dict(counts.most_common())


def _xmlschema():
    try:
        import xmlschema
    except ImportError as exc:
        raise DependencyError(
            "OpenDRIVE validation needs xmlschema: pip install 'vei[maps]'"
        ) from exc
    return xmlschema


@functools.lru_cache(maxsize=8)
def _schema(rel: str):
    return _xmlschema().XMLSchema(str(SCHEMA_DIR / rel))


def read_header(root_or_path) -> tuple[int, int, str | None]:
    """(revMajor, revMinor, geoReference text or None) of an OpenDRIVE root element or file."""
    root = (
        safexml.parse_file(root_or_path) if isinstance(root_or_path, (str, Path)) else root_or_path
    )
    where = root_or_path if isinstance(root_or_path, (str, Path)) else None
    if root.tag != "OpenDRIVE":
        raise InputError(
            f"expected an OpenDRIVE file (root <OpenDRIVE>), found <{root.tag}>", path=where
        )
    header = root.find("header")
    if header is None:
        raise InputError("OpenDRIVE file has no <header>", path=where, field="header")
    try:
        major = int(header.get("revMajor", "1"))
        minor = int(header.get("revMinor", "4"))
    except ValueError as exc:
        raise InputError(f"bad revMajor/revMinor: {exc}", path=where, field="header") from exc
    geo = header.find("geoReference")
    text = None if geo is None or geo.text is None else " ".join(geo.text.split())
    return major, minor, text or None


@functools.lru_cache(maxsize=8)
def _lxml_schema(rel: str):
    from lxml import etree

    parser = etree.XMLParser(resolve_entities=False, no_network=True, load_dtd=False)
    return etree.XMLSchema(etree.parse(str(SCHEMA_DIR / rel), parser))


def _lxml_available() -> bool:
    try:
        import lxml.etree  # noqa: F401
    except ImportError:
        return False
    return True


VALIDATORS = ("auto", "lxml", "xmlschema")


def validate_opendrive(path: str | Path, *, validator: str = "auto") -> ValidationReport:
    """Validate an OpenDRIVE file against the XSD of the revision its header declares.

    Revisions 1.4-1.7 use their own schema; a newer 1.x is checked against 1.7 (noted).
    The file is first parsed with entity expansion disabled (see :mod:`vei.maps.safexml`).

    Args:
        validator: 'xmlschema' (pure Python; lists every violation, slow on large maps:
            ~20 s for a 6 MB city net), 'lxml' (libxml2; ~50x faster, but reports only the
            first violation inside a content model it rejects), or 'auto' (lxml when
            installed, else xmlschema).
    Raises:
        InputError: unsafe/malformed XML, not OpenDRIVE, or a revision below 1.4.
        DependencyError: xmlschema (or lxml when asked for) missing.
    """
    if validator not in VALIDATORS:
        raise ConfigError(f"validator must be one of {VALIDATORS}, got {validator!r}")
    if validator == "auto":
        validator = "lxml" if _lxml_available() else "xmlschema"
    p = Path(path)
    root = safexml.parse_file(p)
    major, minor, _geo = read_header(root) if root.tag == "OpenDRIVE" else read_header(p)
    note = ""
    if major != 1 or minor < 4:
        raise InputError(
            f"OpenDRIVE {major}.{minor} is not supported (vei validates 1.4-1.7)", path=p
        )
    rel = SCHEMA_FILES.get(minor)
    if rel is None:
        rel = SCHEMA_FILES[7]
        note = f"no schema for OpenDRIVE 1.{minor} shipped; checked against 1.7"
    if validator == "lxml":
        if not _lxml_available():
            raise DependencyError("validator 'lxml' needs lxml: pip install lxml")
        from lxml import etree

        parser = etree.XMLParser(
            resolve_entities=False, no_network=True, load_dtd=False, huge_tree=False
        )
        doc = etree.parse(str(p), parser)  # entity-free: checked by safexml above
        schema = _lxml_schema(rel)
        schema.validate(doc)
        issues = tuple(
            SchemaIssue(path=str(err.path or ""), reason=str(err.message))
            for err in schema.error_log
        )
    else:
        schema = _schema(rel)
        issues = tuple(
            SchemaIssue(path=str(err.path or ""), reason=str(err.reason or err.message))
            for err in schema.iter_errors(root)
        )
    return ValidationReport(p, major, minor, rel, issues, note, validator)


def carla_check(xodr_path: str | Path, *, distance_m: float = 2.0) -> dict[str, float | int]:
    """Load an OpenDRIVE map in CARLA's own parser offline and generate waypoints on it.

    Args:
        xodr_path: the .xodr file (checked for unsafe XML first).
        distance_m: waypoint spacing [m] for ``Map.generate_waypoints``.
    Returns:
        {'waypoints': n, 'roads': distinct road ids with waypoints, 'lanes': distinct
        (road, section, lane) ids, 'topology_segments': len(get_topology()),
        'spawn_points': n, 'mean_lane_width_m': mean width at the waypoints,
        'origin_lat_deg', 'origin_lon_deg': CARLA's geolocation of location (0, 0, 0)}.
    Raises:
        DependencyError: the ``carla`` package is missing.
        InputError: CARLA cannot build a map from the file, or it has no waypoint.
    """
    try:
        import carla
    except ImportError as exc:
        raise DependencyError(
            "the CARLA check needs the carla client package: pip install 'vei[carla]'"
        ) from exc
    p = Path(xodr_path)
    safexml.check_file(p)
    text = p.read_text(encoding="utf-8")
    try:
        cmap = carla.Map(p.stem or "vei_map", text)
        waypoints = cmap.generate_waypoints(float(distance_m))
    except RuntimeError as exc:
        raise InputError(f"CARLA could not load the OpenDRIVE map: {exc}", path=p) from exc
    if not waypoints:
        raise InputError("CARLA generated no waypoint on this map (no driving lane?)", path=p)
    widths = [w.lane_width for w in waypoints]
    for w in waypoints:
        loc = w.transform.location
        if not (math.isfinite(loc.x) and math.isfinite(loc.y)):
            raise InputError(f"CARLA produced a non-finite waypoint on road {w.road_id}", path=p)
    geo = cmap.transform_to_geolocation(carla.Location(0.0, 0.0, 0.0))
    return {
        "waypoints": len(waypoints),
        "roads": len({w.road_id for w in waypoints}),
        "lanes": len({(w.road_id, w.section_id, w.lane_id) for w in waypoints}),
        "topology_segments": len(cmap.get_topology()),
        "spawn_points": len(cmap.get_spawn_points()),
        "mean_lane_width_m": float(sum(widths) / len(widths)),
        "origin_lat_deg": float(geo.latitude),
        "origin_lon_deg": float(geo.longitude),
    }
