"""XSD validation of OpenDRIVE (schema chosen by the header revision)."""

from __future__ import annotations

import pytest

from tests.maps.odr_fixtures import HEADER, straight_road, write_odr
from vei.errors import ConfigError, InputError
from vei.maps.validate import SCHEMA_DIR, SCHEMA_FILES, read_header, validate_opendrive

VALIDATORS = ["lxml", "xmlschema"]


def test_shipped_schemas_exist():
    for rel in SCHEMA_FILES.values():
        assert (SCHEMA_DIR / rel).is_file()
    assert (SCHEMA_DIR / "README.md").is_file()


@pytest.mark.parametrize("validator", VALIDATORS)
def test_hand_written_14_file_is_valid(tmp_path, validator):
    path = write_odr(tmp_path / "ok.xodr", straight_road())
    report = validate_opendrive(path, validator=validator)
    assert report.valid, report.summary()
    assert (report.version, report.schema, report.validator) == (
        "1.4",
        "OpenDRIVE_1.4H.xsd",
        validator,
    )
    assert read_header(path)[2].startswith("+proj=tmerc +lat_0=48.0000000000")


@pytest.mark.parametrize("validator", VALIDATORS)
def test_bad_attribute_type_and_unknown_element_are_found(tmp_path, validator):
    bogus = straight_road().replace("<link/>", "<bogus/>", 1)
    north = straight_road().replace('id="1"', 'id="2"', 1).replace('hdg="0.0"', 'hdg="north"', 1)
    report = validate_opendrive(write_odr(tmp_path / "bad.xodr", bogus, north), validator=validator)
    assert not report.valid
    text = " ".join(i.reason for i in report.issues)
    assert "bogus" in text
    assert "north" in text
    assert all("/OpenDRIVE/road" in i.path for i in report.issues)
    assert sum(report.summary().values()) == len(report.issues)


def test_schema_follows_the_header_revision(tmp_path):
    r17 = validate_opendrive(write_odr(tmp_path / "a.xodr", straight_road(), minor=7))
    assert r17.schema == "1.7/opendrive_17_core.xsd" and r17.note == ""
    r18 = validate_opendrive(write_odr(tmp_path / "b.xodr", straight_road(), minor=8))
    assert r18.schema == "1.7/opendrive_17_core.xsd" and "1.8" in r18.note
    with pytest.raises(InputError, match="not supported"):
        validate_opendrive(write_odr(tmp_path / "c.xodr", straight_road(), minor=3))


def test_non_opendrive_and_bad_validator(tmp_path):
    p = tmp_path / "x.xodr"
    p.write_text('<?xml version="1.0"?><osm/>')
    with pytest.raises(InputError, match="expected an OpenDRIVE file"):
        validate_opendrive(p)
    with pytest.raises(ConfigError):
        validate_opendrive(write_odr(tmp_path / "ok.xodr", straight_road()), validator="java")
    no_header = tmp_path / "nh.xodr"
    no_header.write_text(HEADER.split("<header")[0] + "<road/></OpenDRIVE>")
    with pytest.raises(InputError, match="no <header>"):
        validate_opendrive(no_header)


def test_carla_check_without_carla_is_a_dependency_error(tmp_path, monkeypatch):
    import sys

    from vei.errors import DependencyError
    from vei.maps.validate import carla_check

    monkeypatch.setitem(sys.modules, "carla", None)  # import carla -> ImportError
    with pytest.raises(DependencyError, match="vei\\[carla\\]"):
        carla_check(write_odr(tmp_path / "ok.xodr", straight_road()))


def test_carla_check_on_a_hand_written_road(tmp_path):
    pytest.importorskip("carla")
    from vei.maps.validate import carla_check

    info = carla_check(write_odr(tmp_path / "ok.xodr", straight_road()), distance_m=2.0)
    # Two driving lanes (+1, -1) on one 100 m road; the sidewalk gets no waypoints.
    assert info["roads"] == 1 and info["lanes"] == 2
    assert info["waypoints"] == pytest.approx(2 * 50, abs=4)
    assert info["mean_lane_width_m"] == pytest.approx(3.25, abs=0.01)
    assert info["origin_lat_deg"] == pytest.approx(48.0, abs=1e-9)
    assert info["origin_lon_deg"] == pytest.approx(11.0, abs=1e-9)
