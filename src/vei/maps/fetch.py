"""OSM acquisition: crop a local extract (osmium) or query the Overpass API.

Both paths write an OSM XML file (``.osm``) for the region ``bounds``:

* **local extract** (``source`` = a ``.osm``, ``.osm.gz``, ``.osm.bz2`` or ``.osm.pbf`` file):
  the crop keeps *complete ways* -- every way with at least one node inside the box is kept
  with all its nodes, also those outside the box, so no road is cut mid-way and netconvert
  sees whole junctions. Nodes inside the box are kept; relations are kept when they
  reference a kept node or way (turn restrictions!), with their member lists unchanged
  (the strategy ``osmium extract --strategy complete_ways`` uses).
* **Overpass** (``source="overpass"``): a query built from the bounds (all ``highway`` ways
  in the box, the turn-restriction relations on them, and every node of those ways),
  POSTed with urllib; timeouts, retries with exponential backoff on HTTP 429/5xx and
  network errors, and clear errors for Overpass ``remark`` answers (query timeout, out of
  memory), HTTP errors and empty results.
"""

from __future__ import annotations

import bz2
import re
import time
import urllib.error
import urllib.parse
import urllib.request
from pathlib import Path

from vei.errors import DependencyError, InputError
from vei.geo import Bounds
from vei.io.atomic import atomic_path, write_bytes
from vei.maps import safexml

#: Public Overpass endpoint (any Overpass API instance works; see docs/maps.md).
DEFAULT_OVERPASS_URL = "https://overpass-api.de/api/interpreter"
#: HTTP statuses worth retrying: rate limit and transient server / gateway failures.
RETRY_STATUSES = frozenset({429, 500, 502, 503, 504})
#: Longest wait honoured from a ``Retry-After`` header [s].
MAX_RETRY_AFTER_S = 60.0
OSM_SUFFIXES = (".osm", ".osm.gz", ".osm.bz2", ".osm.pbf", ".pbf", ".xml")


def _osmium():
    try:
        import osmium
    except ImportError as exc:
        raise DependencyError(
            "cropping an OSM extract needs pyosmium: pip install 'vei[maps]'"
        ) from exc
    return osmium


def is_osm_path(path: str | Path) -> bool:
    """True when the file name looks like an OSM extract (.osm, .osm.gz/.bz2, .osm.pbf, .pbf)."""
    name = Path(path).name.lower()
    return any(name.endswith(s) for s in OSM_SUFFIXES if s != ".xml")


def check_osm_xml(path: str | Path) -> None:
    """Reject unsafe or malformed OSM XML (entities, XXE) before any tool reads it.

    PBF files are binary and skipped. Raises InputError naming the file.
    """
    p = Path(path)
    name = p.name.lower()
    if name.endswith(".pbf"):
        return
    if name.endswith(".bz2"):
        import tempfile

        # Decompress to a temporary file and scan it (defusedxml reads plain / gzip files).
        with tempfile.TemporaryDirectory() as tmp:
            plain = Path(tmp) / p.name[:-4]
            try:
                with bz2.open(p, "rb") as src, open(plain, "wb") as dst:
                    while chunk := src.read(1 << 20):
                        dst.write(chunk)
            except OSError as exc:
                raise InputError(f"cannot decompress bz2: {exc}", path=p) from exc
            try:
                root = safexml.check_file(plain)
            except InputError as exc:
                raise InputError(exc.detail, path=p) from exc
    else:
        root = safexml.check_file(p)
    if root != "osm":
        raise InputError(f"expected an OSM XML file (root <osm>), found <{root}>", path=p)


def osm_data_bounds(path: str | Path) -> Bounds:
    """Geographic bounds of an OSM file: its header box if it has one, else the nodes' extent.

    Returns:
        Bounds in degrees.
    Raises:
        InputError: file without nodes; DependencyError: pyosmium missing.
    """
    osmium = _osmium()
    p = Path(path)
    check_osm_xml(p)
    try:
        reader = osmium.io.Reader(str(p), osmium.osm.osm_entity_bits.NOTHING)
        box = reader.header().box()
        reader.close()
    except RuntimeError as exc:
        raise InputError(f"cannot read OSM file: {exc}", path=p) from exc
    if box.valid():
        return Bounds(
            box.bottom_left.lat, box.bottom_left.lon, box.top_right.lat, box.top_right.lon
        )
    s = w = float("inf")
    n = e = float("-inf")
    for node in osmium.FileProcessor(str(p), osmium.osm.NODE):
        if node.location.valid():
            s, n = min(s, node.location.lat), max(n, node.location.lat)
            w, e = min(w, node.location.lon), max(e, node.location.lon)
    if s == float("inf"):
        raise InputError("OSM file has no node with a location", path=p)
    return Bounds(s, w, n, e)


def crop_osm(source: str | Path, bounds: Bounds, out: str | Path) -> dict[str, int]:
    """Crop an OSM extract to ``bounds`` keeping complete ways; write OSM XML to ``out``.

    Args:
        source: .osm / .osm.gz / .osm.bz2 / .osm.pbf extract.
        bounds: region [deg].
        out: output .osm file (written atomically).
    Returns:
        Counts {'nodes', 'ways', 'relations'} written.
    Raises:
        InputError: unreadable / unsafe source, or no way touches the box.
    """
    osmium = _osmium()
    src = Path(source)
    if not src.is_file():
        raise InputError("OSM extract not found", path=src)
    check_osm_xml(src)
    s, w, n, e = bounds.south_deg, bounds.west_deg, bounds.north_deg, bounds.east_deg

    inside: set[int] = set()
    keep_nodes: set[int] = set()
    keep_ways: set[int] = set()
    keep_rels: set[int] = set()
    try:
        # Pass 1: nodes in the box, ways touching them, relations referencing either.
        # (Files are sorted nodes -> ways -> relations, as OSM files are by convention.)
        for obj in osmium.FileProcessor(str(src)):
            if obj.is_node():
                loc = obj.location
                if loc.valid() and s <= loc.lat <= n and w <= loc.lon <= e:
                    inside.add(obj.id)
            elif obj.is_way():
                refs = [nd.ref for nd in obj.nodes]
                if any(r in inside for r in refs):
                    keep_ways.add(obj.id)
                    keep_nodes.update(refs)
            elif obj.is_relation():
                for m in obj.members:
                    if (m.type == "n" and m.ref in inside) or (
                        m.type == "w" and m.ref in keep_ways
                    ):
                        keep_rels.add(obj.id)
                        break
    except RuntimeError as exc:
        raise InputError(f"cannot read OSM extract: {exc}", path=src) from exc
    if not keep_ways:
        raise InputError(
            f"no OSM way touches the box S,W,N,E = {bounds.as_sw_ne()} (is the region inside the extract?)",
            path=src,
        )
    keep_nodes |= inside

    header = osmium.io.Header()
    header.add_box(osmium.osm.Box(osmium.osm.Location(w, s), osmium.osm.Location(e, n)))
    header.set("generator", "vei (osmium crop, complete ways)")
    counts = {"nodes": 0, "ways": 0, "relations": 0}
    with atomic_path(out) as tmp:
        writer = osmium.SimpleWriter(osmium.io.File(str(tmp), "osm"), header=header, overwrite=True)
        try:
            for obj in osmium.FileProcessor(str(src)):
                if obj.is_node() and obj.id in keep_nodes:
                    writer.add_node(obj)
                    counts["nodes"] += 1
                elif obj.is_way() and obj.id in keep_ways:
                    writer.add_way(obj)
                    counts["ways"] += 1
                elif obj.is_relation() and obj.id in keep_rels:
                    writer.add_relation(obj)
                    counts["relations"] += 1
        finally:
            writer.close()
    return counts


def overpass_query(bounds: Bounds, *, timeout_s: int = 60) -> str:
    """Overpass QL for the road network in ``bounds``.

    All ``highway`` ways in the box with their tags, the turn-restriction relations that use
    them, then every node of those ways (``>``) -- with tags (``out body``), because
    netconvert reads traffic-signal and crossing nodes.
    """
    bbox = f"({bounds.south_deg:.7f},{bounds.west_deg:.7f},{bounds.north_deg:.7f},{bounds.east_deg:.7f})"
    return (
        f"[out:xml][timeout:{int(timeout_s)}];\n"
        f'way["highway"]{bbox}->.roads;\n'
        'rel(bw.roads)["type"="restriction"]->.restrictions;\n'
        "(.roads; .restrictions;);\n"
        "out body;\n"
        ">;\n"
        "out body qt;\n"
    )


_REMARK = re.compile(rb"<remark>\s*(.*?)\s*</remark>", re.S)


def _check_overpass_answer(data: bytes, url: str) -> int:
    """Validate an Overpass XML answer; returns the number of ways."""
    m = _REMARK.search(data)
    if m and (b"error" in m.group(1).lower() or b"timed out" in m.group(1).lower()):
        raise InputError(
            f"{url}: Overpass reported an error: {m.group(1).decode('utf-8', 'replace')}"
        )
    root = safexml.parse_bytes(data, source=url)
    if root.tag != "osm":
        raise InputError(f"{url}: Overpass answer is not OSM XML (root <{root.tag}>)")
    ways = sum(1 for _ in root.iter("way"))
    if ways == 0:
        raise InputError(f"{url}: Overpass returned no road (no highway way in the box)")
    return ways


def fetch_overpass(
    bounds: Bounds,
    out: str | Path,
    *,
    overpass_url: str = DEFAULT_OVERPASS_URL,
    timeout_s: float = 90.0,
    retries: int = 3,
    backoff_s: float = 2.0,
) -> Path:
    """Download the road network in ``bounds`` from an Overpass API endpoint to ``out`` (.osm).

    Args:
        timeout_s: socket timeout per request [s]; also the server-side query timeout.
        retries: extra attempts after the first on HTTP 429/5xx or network errors.
        backoff_s: first wait between attempts [s], doubled each time (a ``Retry-After``
            header, if larger, is honoured up to 60 s).
    Raises:
        InputError: HTTP error that is not transient, an Overpass error remark, unsafe or
            malformed XML, or no road in the answer; all naming the URL. After the retries
            are spent, the last failure is reported with the number of attempts.
    """
    if retries < 0:
        raise InputError(f"retries must be >= 0, got {retries}")
    if timeout_s <= 0:
        raise InputError(f"timeout_s must be > 0, got {timeout_s}")
    body = urllib.parse.urlencode(
        {"data": overpass_query(bounds, timeout_s=int(timeout_s))}
    ).encode()
    last_error = "no attempt made"
    for attempt in range(retries + 1):
        wait = backoff_s * (2**attempt)
        req = urllib.request.Request(
            overpass_url,
            data=body,
            headers={
                "User-Agent": "vei (https://github.com/vei) map fetch",
                "Accept": "application/xml",
            },
        )
        try:
            with urllib.request.urlopen(req, timeout=timeout_s) as resp:
                data = resp.read()
        except urllib.error.HTTPError as exc:
            detail = exc.read()[:300].decode("utf-8", "replace").strip()
            last_error = f"HTTP {exc.code} {exc.reason}" + (f": {detail}" if detail else "")
            if exc.code not in RETRY_STATUSES:
                raise InputError(f"{overpass_url}: Overpass request failed: {last_error}") from exc
            retry_after = exc.headers.get("Retry-After") if exc.headers else None
            if retry_after and retry_after.strip().isdigit():
                wait = max(wait, min(float(retry_after), MAX_RETRY_AFTER_S))
        except (urllib.error.URLError, TimeoutError, ConnectionError, OSError) as exc:
            reason = getattr(exc, "reason", exc)
            last_error = f"network error: {reason}"
        else:
            m = _REMARK.search(data)
            if m and b"timed out" in m.group(1).lower():
                last_error = f"Overpass query timed out: {m.group(1).decode('utf-8', 'replace')}"
            else:
                _check_overpass_answer(data, overpass_url)
                write_bytes(out, data)
                return Path(out)
        if attempt < retries:
            time.sleep(wait)
    raise InputError(
        f"{overpass_url}: Overpass request failed after {retries + 1} attempt(s): {last_error}"
    )


def fetch_osm(
    bounds: Bounds,
    out: str | Path,
    *,
    source: str | Path = "overpass",
    overpass_url: str = DEFAULT_OVERPASS_URL,
    timeout_s: float = 90.0,
    retries: int = 3,
    backoff_s: float = 2.0,
) -> Path:
    """Get the OSM road network of ``bounds`` into ``out`` (OSM XML).

    Args:
        bounds: region [deg].
        out: target .osm file (written atomically).
        source: ``"overpass"`` or the path of a local extract (.osm, .osm.gz, .osm.bz2,
            .osm.pbf) to crop with complete ways.
        overpass_url, timeout_s, retries, backoff_s: see :func:`fetch_overpass`.
    Returns:
        ``Path(out)``.
    """
    if str(source) == "overpass":
        return fetch_overpass(
            bounds,
            out,
            overpass_url=overpass_url,
            timeout_s=timeout_s,
            retries=retries,
            backoff_s=backoff_s,
        )
    src = Path(source)
    if not is_osm_path(src):
        raise InputError(
            "OSM source must be 'overpass' or a .osm, .osm.gz, .osm.bz2 or .osm.pbf file", path=src
        )
    crop_osm(src, bounds, out)
    return Path(out)
