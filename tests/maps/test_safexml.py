"""Untrusted XML: entity expansion (billion laughs) and external entities (XXE) are refused."""

from __future__ import annotations

import gzip
from pathlib import Path

import pytest

from vei.errors import InputError
from vei.maps import safexml

BILLION_LAUGHS = """<?xml version="1.0"?>
<!DOCTYPE osm [
 <!ENTITY lol "lol">
 <!ENTITY lol1 "&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;&lol;">
 <!ENTITY lol2 "&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;&lol1;">
 <!ENTITY lol3 "&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;&lol2;">
 <!ENTITY lol9 "&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;&lol3;">
]>
<osm version="0.6"><node id="1" lat="0" lon="0"><tag k="name" v="&lol9;"/></node></osm>
"""

XXE = """<?xml version="1.0"?>
<!DOCTYPE osm [<!ENTITY secret SYSTEM "file:///etc/passwd">]>
<osm version="0.6"><node id="1" lat="0" lon="0"><tag k="name" v="&secret;"/></node></osm>
"""

SAFE = """<?xml version="1.0"?>
<osm version="0.6"><node id="1" lat="1.5" lon="2.5"/><way id="7"><nd ref="1"/></way></osm>
"""


@pytest.fixture(params=["billion_laughs", "xxe"])
def evil_osm(request, tmp_path) -> Path:
    path = tmp_path / f"{request.param}.osm"
    path.write_text(BILLION_LAUGHS if request.param == "billion_laughs" else XXE)
    return path


def test_check_file_refuses_entities_and_names_the_file(evil_osm):
    with pytest.raises(InputError, match="refusing unsafe XML") as exc:
        safexml.check_file(evil_osm)
    assert exc.value.path == evil_osm
    assert str(evil_osm) in str(exc.value)


def test_parse_file_and_iter_elements_refuse_entities(evil_osm):
    with pytest.raises(InputError, match="entity"):
        safexml.parse_file(evil_osm)
    with pytest.raises(InputError, match="unsafe"):
        list(safexml.iter_elements(evil_osm, {"node"}))


def test_parse_bytes_refuses_entities_and_names_the_source():
    with pytest.raises(InputError, match="http://example/overpass"):
        safexml.parse_bytes(XXE.encode(), source="http://example/overpass")


def test_map_build_refuses_a_malicious_osm_before_netconvert(evil_osm, tmp_path):
    from vei.maps.build import build_opendrive

    out = tmp_path / "out.xodr"
    with pytest.raises(InputError, match="refusing unsafe XML"):
        build_opendrive(evil_osm, out)
    assert not out.exists()


def test_malicious_opendrive_is_refused_by_the_readers(tmp_path):
    from vei.maps.roads import load_roads
    from vei.maps.validate import validate_opendrive

    path = tmp_path / "evil.xodr"
    path.write_text(XXE.replace("osm", "OpenDRIVE"))
    for reader in (validate_opendrive, load_roads):
        with pytest.raises(InputError, match="unsafe"):
            reader(path)


def test_safe_file_parses_plain_and_gzipped(tmp_path):
    plain = tmp_path / "a.osm"
    plain.write_text(SAFE)
    gz = tmp_path / "a.osm.gz"
    gz.write_bytes(gzip.compress(SAFE.encode()))
    for p in (plain, gz):
        assert safexml.check_file(p) == "osm"
        root = safexml.parse_file(p)
        assert root.find("node").get("lat") == "1.5"
        assert [e.get("id") for e in safexml.iter_elements(p, {"way"})] == ["7"]


def test_malformed_and_missing_files_are_input_errors(tmp_path):
    bad = tmp_path / "bad.osm"
    bad.write_text("<osm><node></osm>")
    with pytest.raises(InputError, match="malformed XML"):
        safexml.check_file(bad)
    with pytest.raises(InputError, match="cannot read"):
        safexml.parse_file(tmp_path / "missing.osm")
