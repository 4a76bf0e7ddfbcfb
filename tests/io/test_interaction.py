"""Interaction format v1: validation (one test per rule), timestamps, round trip."""

from __future__ import annotations

import json
from datetime import UTC, datetime

import numpy as np
import pandas as pd
import pytest

from tests.helpers_interaction import (
    DELETE,
    EGO_BEARING_DEG,
    EGO_START,
    expected_tables,
    make_interaction,
)
from vei.errors import InputError
from vei.io.interaction import (
    ANNOTATION_COLUMNS,
    EGO_COLUMNS,
    GROUND_TRUTH_COLUMNS,
    read_interaction,
    write_interaction,
)
from vei.types import Interaction


def _err(folder) -> InputError:
    with pytest.raises(InputError) as info:
        read_interaction(folder)
    return info.value


def _assert_where(exc: InputError, file: str, row: int | None, field: str) -> None:
    msg = str(exc)
    assert exc.path is not None and exc.path.name == file, msg
    assert file in msg
    assert exc.field == field and f"field '{field}'" in msg, msg
    assert exc.row == row, msg
    if row is not None:
        assert f"row {row}" in msg


# ----------------------------------------------------------------------------- happy path


def test_reads_tiny_interaction_with_documented_columns(tmp_path):
    it = read_interaction(make_interaction(tmp_path))
    assert tuple(it.ego.columns) == EGO_COLUMNS
    assert tuple(it.annotations.columns) == ANNOTATION_COLUMNS
    assert tuple(it.ground_truth.columns) == GROUND_TRUTH_COLUMNS
    assert it.ego["t_s"].dtype == np.float64 and it.annotations["x_m"].dtype == np.float64
    assert it.annotations["track_id"].map(type).eq(str).all()
    assert it.meta.start_time_utc == datetime(2021, 2, 9, 12, 40, 35, 690000, tzinfo=UTC)
    assert it.meta.y_axis == "left" and it.meta.annotation_rate_hz == 1.0
    assert len(it.ego) == 61 and len(it.annotations) == 14
    # first escooter annotation: 25 m ahead, 4 m left, crossing to the right
    first = it.annotations.iloc[0]
    assert (first.track_id, first.category) == ("1", "escooter")
    assert first.x_m == pytest.approx(25.0, abs=1e-6) and first.y_m == pytest.approx(4.0, abs=1e-6)
    assert first.yaw_deg == pytest.approx(-90.0)


def test_optional_columns_absent_are_nan_and_extra_columns_dropped(tmp_path):
    ego, ann, _ = expected_tables()
    ego = ego.drop(columns=["heading_deg", "speed_mps"]).assign(hdop=1.0)
    ann = ann.drop(columns=["yaw_deg", "length_m", "width_m"]).assign(score=0.9)
    it = read_interaction(make_interaction(tmp_path, ego=ego, annotations=ann, ground_truth=None))
    assert tuple(it.ego.columns) == EGO_COLUMNS and it.ego["heading_deg"].isna().all()
    assert tuple(it.annotations.columns) == ANNOTATION_COLUMNS
    assert it.annotations[["yaw_deg", "length_m", "width_m"]].isna().all().all()
    assert it.ground_truth is None


def test_annotations_sorted_by_track_then_time(tmp_path):
    _, ann, _ = expected_tables()
    shuffled = ann.sample(frac=1.0, random_state=3)
    # keep per-track order increasing in file order: sort by t within a track later
    shuffled = shuffled.sort_values("t_s", kind="stable")
    it = read_interaction(make_interaction(tmp_path, annotations=shuffled))
    pd.testing.assert_frame_equal(
        it.annotations, read_interaction(make_interaction(tmp_path, name="b")).annotations
    )


def test_timestamp_utc_columns_convert_to_t_s(tmp_path):
    ego, ann, _ = expected_tables()
    start = pd.Timestamp("2021-02-09T12:40:35.690Z")
    ego_ts = ego.drop(columns=["t_s"]).assign(
        timestamp_utc=[(start + pd.to_timedelta(t, unit="s")).isoformat() for t in ego["t_s"]]
    )
    # CET (+01:00) stamps on the annotations: the same instants
    ann_ts = ann.drop(columns=["t_s"]).assign(
        timestamp_utc=[
            (start + pd.to_timedelta(t, unit="s")).tz_convert("Etc/GMT-1").isoformat()
            for t in ann["t_s"]
        ]
    )
    assert ann_ts["timestamp_utc"].iloc[1] == "2021-02-09T13:40:36.690000+01:00"
    it = read_interaction(make_interaction(tmp_path, ego=ego_ts, annotations=ann_ts))
    np.testing.assert_allclose(it.ego["t_s"], ego["t_s"], atol=1e-9)
    np.testing.assert_allclose(it.annotations["t_s"], ann["t_s"], atol=1e-9)


# ----------------------------------------------------------------------------- round trip


@pytest.mark.parametrize("y_axis", ["left", "right"])
def test_write_read_round_trip_is_equal(tmp_path, y_axis):
    it = read_interaction(make_interaction(tmp_path, y_axis=y_axis))
    out = write_interaction(it, tmp_path / "copy")
    back = read_interaction(out)
    assert back.meta == it.meta
    pd.testing.assert_frame_equal(back.ego, it.ego)
    pd.testing.assert_frame_equal(back.annotations, it.annotations)
    pd.testing.assert_frame_equal(back.ground_truth, it.ground_truth)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["copy", "interaction"]


def test_writer_refuses_invalid_and_leaves_target_untouched(tmp_path):
    it = read_interaction(make_interaction(tmp_path))
    target = write_interaction(it, tmp_path / "out")
    before = {p.name: p.read_bytes() for p in target.iterdir()}
    bad_ann = it.annotations.copy()
    bad_ann.loc[3, "category"] = "scooter"
    bad = Interaction(meta=it.meta, ego=it.ego, annotations=bad_ann, ground_truth=it.ground_truth)
    with pytest.raises(InputError) as info:
        write_interaction(bad, target)
    assert "refusing to write" in str(info.value) and info.value.field == "category"
    assert info.value.path == target / "annotations.csv" and info.value.row == 4
    assert {p.name: p.read_bytes() for p in target.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["interaction", "out"]
    with pytest.raises(FileExistsError):
        write_interaction(it, target, overwrite=False)


# ----------------------------------------------------------------------------- interaction.json


@pytest.mark.parametrize(
    ("override", "field", "needle"),
    [
        ({"format": "vei.interaction/2"}, "format", "vei.interaction/1"),
        ({"y_axis": "up"}, "y_axis", "'left' or 'right'"),
        ({"start_time_utc": "2021-02-09 13:40:35.69"}, "start_time_utc", "no timezone"),
        ({"start_time_utc": "9 Feb 2021 13:40"}, "start_time_utc", "not an ISO 8601"),
        ({"start_time_utc": DELETE}, "start_time_utc", "missing key"),
        ({"annotation_rate_hz": -1}, "annotation_rate_hz", "positive number"),
        ({"id": ""}, "id", "non-empty string"),
        ({"camera": "front"}, "camera", "unknown key"),
    ],
)
def test_bad_interaction_json(tmp_path, override, field, needle):
    exc = _err(make_interaction(tmp_path, **override))
    _assert_where(exc, "interaction.json", None, field)
    assert needle in str(exc)


def test_interaction_json_not_json(tmp_path):
    folder = make_interaction(tmp_path)
    (folder / "interaction.json").write_text('{"format": "vei.interaction/1",\n "id": }\n')
    exc = _err(folder)
    assert exc.path.name == "interaction.json" and exc.row == 2 and "not valid JSON" in str(exc)


def test_naive_start_time_message_suggests_timezone(tmp_path):
    exc = _err(make_interaction(tmp_path, start_time_utc="2021-02-09T13:40:35"))
    assert "2021-02-09T13:40:35Z" in str(exc) and "+01:00" in str(exc)


def test_missing_file(tmp_path):
    folder = make_interaction(tmp_path)
    (folder / "annotations.csv").unlink()
    exc = _err(folder)
    assert exc.path.name == "annotations.csv" and "file not found" in str(exc)


# ----------------------------------------------------------------------------- CSV rules


def test_missing_column(tmp_path):
    ego, _, _ = expected_tables()
    exc = _err(make_interaction(tmp_path, ego=ego.drop(columns=["lon_deg"])))
    _assert_where(exc, "ego.csv", None, "lon_deg")
    assert "missing column in the header" in str(exc)


def test_missing_time_column(tmp_path):
    _, ann, _ = expected_tables()
    exc = _err(make_interaction(tmp_path, annotations=ann.drop(columns=["t_s"])))
    _assert_where(exc, "annotations.csv", None, "t_s")
    assert "t_s or timestamp_utc" in str(exc)


def test_nan_in_required_column(tmp_path):
    _, ann, _ = expected_tables()
    ann.loc[4, "x_m"] = np.nan
    exc = _err(make_interaction(tmp_path, annotations=ann))
    _assert_where(exc, "annotations.csv", 5, "x_m")
    assert "NaN" in str(exc)


def test_text_in_numeric_column(tmp_path):
    ego, _, _ = expected_tables()
    ego["lat_deg"] = ego["lat_deg"].astype(object)
    ego.loc[9, "lat_deg"] = "48,7665"
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 10, "lat_deg")
    assert "expected a number" in str(exc)


def test_non_monotonic_ego_time(tmp_path):
    ego, _, _ = expected_tables()
    ego.loc[20, "t_s"] = 1.5  # row 21, after 1.9 at row 20
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 21, "t_s")
    assert "backwards" in str(exc) and "row 20" in str(exc)


def test_duplicate_ego_time(tmp_path):
    ego, _, _ = expected_tables()
    ego.loc[31, "t_s"] = ego.loc[30, "t_s"]
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 32, "t_s")
    assert "duplicate time" in str(exc)


def test_duplicate_time_within_annotation_track(tmp_path):
    _, ann, _ = expected_tables()
    # track "2" occupies rows 8..14; make row 11 repeat row 10's time
    ann.loc[10, "t_s"] = ann.loc[9, "t_s"]
    exc = _err(make_interaction(tmp_path, annotations=ann))
    _assert_where(exc, "annotations.csv", 11, "t_s")
    assert "track '2'" in str(exc) and "duplicate time" in str(exc)


def test_same_time_in_different_tracks_is_fine(tmp_path):
    it = read_interaction(make_interaction(tmp_path))
    assert it.annotations.groupby("t_s").size().max() == 2


def test_annotation_outside_gps_span(tmp_path):
    _, ann, _ = expected_tables()
    ann.loc[6, "t_s"] = 6.5  # ego ends at 6.0
    exc = _err(make_interaction(tmp_path, annotations=ann))
    _assert_where(exc, "annotations.csv", 7, "t_s")
    assert "outside the GPS time span" in str(exc)


def test_latitude_out_of_range(tmp_path):
    ego, _, _ = expected_tables()
    ego.loc[2, "lat_deg"] = 95.0
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 3, "lat_deg")
    assert "outside [-90, 90]" in str(exc) and "swapped" not in str(exc)


def test_longitude_out_of_range_in_ground_truth(tmp_path):
    _, _, gt = expected_tables()
    gt.loc[7, "lon_deg"] = 190.0
    exc = _err(make_interaction(tmp_path, ground_truth=gt))
    _assert_where(exc, "ground_truth.csv", 8, "lon_deg")


def test_swapped_lat_lon_out_of_range(tmp_path):
    # San Francisco with the columns exchanged: 'lat_deg' = -122.4 is impossible
    ego, _, _ = expected_tables()
    ego["lat_deg"], ego["lon_deg"] = ego["lon_deg"] - 133.8345, ego["lat_deg"] - 11.0
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 1, "lat_deg")
    assert "look swapped" in str(exc)


def test_swapped_lat_lon_detected_from_heading(tmp_path):
    ego, _, _ = expected_tables()
    ego["lat_deg"], ego["lon_deg"] = ego["lon_deg"].copy(), ego["lat_deg"].copy()
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 1, "lat_deg")
    assert "look swapped" in str(exc)


def test_heading_in_radians(tmp_path):
    ego, _, _ = expected_tables()
    ego["heading_deg"] = np.radians(EGO_BEARING_DEG)
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 1, "heading_deg")
    assert "radians" in str(exc)


def test_small_heading_in_degrees_is_not_mistaken_for_radians(tmp_path):
    # driving due north with heading 1 deg: all values within 2*pi, yet degrees
    from pyproj import Geod

    t = np.arange(0.0, 6.01, 0.1)
    lon, lat, _ = Geod(ellps="WGS84").fwd(
        np.full(t.size, EGO_START[1]), np.full(t.size, EGO_START[0]), np.full(t.size, 1.0), 5.0 * t
    )
    ego = pd.DataFrame({"t_s": t, "lat_deg": lat, "lon_deg": lon, "heading_deg": 1.0})
    _, ann, _ = expected_tables()
    it = read_interaction(make_interaction(tmp_path, ego=ego, annotations=ann, ground_truth=None))
    assert it.ego["heading_deg"].eq(1.0).all()


def test_heading_out_of_range(tmp_path):
    ego, _, _ = expected_tables()
    ego.loc[5, "heading_deg"] = 400.0
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 6, "heading_deg")


def test_negative_speed(tmp_path):
    ego, _, _ = expected_tables()
    ego.loc[12, "speed_mps"] = -0.5
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 13, "speed_mps")


def test_empty_track_id(tmp_path):
    _, ann, _ = expected_tables()
    ann["track_id"] = ann["track_id"].astype(object)
    ann.loc[2, "track_id"] = ""
    exc = _err(make_interaction(tmp_path, annotations=ann))
    _assert_where(exc, "annotations.csv", 3, "track_id")


def test_no_annotations(tmp_path):
    _, ann, _ = expected_tables()
    exc = _err(make_interaction(tmp_path, annotations=ann.iloc[:0]))
    assert exc.path.name == "annotations.csv" and "no annotations" in str(exc)


def test_ego_with_one_fix(tmp_path):
    ego, ann, _ = expected_tables()
    exc = _err(make_interaction(tmp_path, ego=ego.iloc[:1], annotations=ann[ann.t_s == 0.0]))
    _assert_where(exc, "ego.csv", 1, "t_s")
    assert "at least 2" in str(exc)


def test_unknown_category(tmp_path):
    _, ann, _ = expected_tables()
    ann.loc[8, "category"] = "scooter"
    exc = _err(make_interaction(tmp_path, annotations=ann))
    _assert_where(exc, "annotations.csv", 9, "category")
    assert "escooter" in str(exc)


def test_category_changes_within_track(tmp_path):
    _, _, gt = expected_tables()
    gt.loc[30, "category"] = "pedestrian"
    exc = _err(make_interaction(tmp_path, ground_truth=gt))
    _assert_where(exc, "ground_truth.csv", 31, "category")
    assert "changes category" in str(exc)


def test_naive_timestamp_column(tmp_path):
    ego, _, _ = expected_tables()
    ego = ego.drop(columns=["t_s"]).assign(timestamp_utc="2021-02-09T12:40:35")
    exc = _err(make_interaction(tmp_path, ego=ego))
    _assert_where(exc, "ego.csv", 1, "timestamp_utc")
    assert "no timezone" in str(exc)


def test_timestamp_disagreeing_with_t_s(tmp_path):
    _, ann, _ = expected_tables()
    start = pd.Timestamp("2021-02-09T12:40:35.690Z")
    ann["timestamp_utc"] = [(start + pd.to_timedelta(t, unit="s")).isoformat() for t in ann["t_s"]]
    ann.loc[3, "timestamp_utc"] = (start + pd.to_timedelta(3.5, unit="s")).isoformat()
    exc = _err(make_interaction(tmp_path, annotations=ann))
    _assert_where(exc, "annotations.csv", 4, "timestamp_utc")


def test_meta_file_written_is_plain_json(tmp_path):
    it = read_interaction(make_interaction(tmp_path))
    out = write_interaction(it, tmp_path / "w")
    doc = json.loads((out / "interaction.json").read_text())
    assert doc["format"] == "vei.interaction/1"
    assert doc["start_time_utc"] == "2021-02-09T12:40:35.690000Z"


def test_example_in_the_spec_is_valid(tmp_path):
    import re
    from pathlib import Path

    spec = (Path(__file__).resolve().parents[2] / "docs" / "interaction-format.md").read_text()
    example = spec.split("## A tiny example", 1)[1]
    blocks = re.findall(r"`([a-z_]+\.(?:json|csv))`[^\n]*\n```[a-z]*\n(.*?)```", example, re.S)
    assert [name for name, _ in blocks] == [
        "interaction.json",
        "ego.csv",
        "annotations.csv",
        "ground_truth.csv",
    ]
    folder = tmp_path / "example"
    folder.mkdir()
    for name, text in blocks:
        (folder / name).write_text(text)
    it = read_interaction(folder)
    assert len(it.ego) == 3 and list(it.annotations["y_m"]) == [4.0, 2.5, 1.0]
    # the ground-truth point is the first annotation placed in the world (25 m ahead, 4 m left)
    from pyproj import Geod

    az, _, dist = Geod(ellps="WGS84").inv(
        11.4345, 48.7665, it.ground_truth.lon_deg[0], it.ground_truth.lat_deg[0]
    )
    rel = np.radians(az - 60.0)
    assert dist * np.cos(rel) == pytest.approx(25.0, abs=0.01)
    assert -dist * np.sin(rel) == pytest.approx(4.0, abs=0.01)


def test_infinite_value(tmp_path):
    _, ann, _ = expected_tables()
    ann.loc[1, "y_m"] = np.inf
    exc = _err(make_interaction(tmp_path, annotations=ann))
    _assert_where(exc, "annotations.csv", 2, "y_m")
    assert "finite" in str(exc)


def test_padded_cells_are_read(tmp_path):
    folder = make_interaction(tmp_path)
    text = (folder / "ego.csv").read_text().splitlines()
    padded = [text[0]] + [" " + ", ".join(line.split(",")) + " " for line in text[1:]]
    (folder / "ego.csv").write_text("\n".join(padded) + "\n")
    it = read_interaction(folder)
    np.testing.assert_array_equal(
        it.ego.to_numpy(), read_interaction(make_interaction(tmp_path, name="b")).ego.to_numpy()
    )
