"""Argoverse 2 motion forecasting: scenario reader, map archive -> OpenDRIVE, writer for tests.

Layout (av2-api, ``av2.datasets.motion_forecasting.scenario_serialization``), one folder
per scenario: ``scenario_<id>.parquet`` with one row per track and time step: observed
(bool), track_id (str; ``AV`` is the autonomous vehicle), object_type (vehicle, pedestrian,
motorcyclist, cyclist, bus, static, background, construction, riderless_bicycle, unknown),
object_category (0-3), timestep (0..num_timestamps-1), position_x, position_y [m, city
frame], heading [rad, from city +x], velocity_x, velocity_y [m/s], scenario_id,
start_timestamp, end_timestamp [ns], num_timestamps, focal_track_id, city (ATX, DTW, MIA,
PAO, PIT, WDC); and ``log_map_archive_<id>.json``: lane_segments (left / right boundaries
as {x, y, z} lists, lane_type VEHICLE / BIKE / BUS, ...), drivable_areas (area_boundary),
pedestrian_crossings.

Frames: a city frame is its UTM zone translated to the city origin; the ``av2`` package
(extra ``av2``, imported lazily) supplies the zones and origins
(``av2.geometry.utm.UTM_ZONE_MAP``, ``CITY_ORIGIN_LATLONG_DICT``, ``convert_gps_to_utm``),
and :class:`vei.geo.grid.UtmGrid` converts positions to WGS84 and headings to true
bearings. Time: timestep x (end - start) / (num - 1), as av2's loader spaces the
timestamps. The map archive becomes ``map.xodr`` in every interaction folder
(:mod:`vei.maps.lanes_xodr`: one road per lane segment, drivable areas in the header), in
the tmerc plane that the interactions declare (centred on the map).
"""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd

from vei.datasets.world_tracks import RecordingTracks, normalised_table
from vei.errors import DependencyError, InputError
from vei.geo.grid import UtmGrid

#: Columns of scenario_<id>.parquet that vei reads (av2's writer writes these and may add
#: map_id / slice_id).
SCENARIO_COLUMNS: tuple[str, ...] = (
    "observed", "track_id", "object_type", "object_category", "timestep", "position_x",
    "position_y", "heading", "velocity_x", "velocity_y", "scenario_id", "start_timestamp",
    "end_timestamp", "num_timestamps", "focal_track_id", "city",
)  # fmt: skip
#: object_type -> vei category (None: not imported; a riderless bicycle has no rider).
CLASS_TO_CATEGORY: dict[str, str | None] = {
    "vehicle": "vehicle",
    "bus": "vehicle",
    "pedestrian": "pedestrian",
    "cyclist": "cyclist",
    "motorcyclist": "cyclist",
    "riderless_bicycle": None,
    "static": None,
    "background": None,
    "construction": None,
    "unknown": None,
}
EGO_CLASSES: frozenset[str] = frozenset({"vehicle"})
#: AV2 lane types -> OpenDRIVE lane types.
LANE_TYPES: dict[str, str] = {"VEHICLE": "driving", "BUS": "driving", "BIKE": "biking"}
#: The track id of the autonomous vehicle.
AV_TRACK_ID = "AV"


def _require_av2():
    try:
        from av2.geometry import utm
    except ImportError as exc:
        raise DependencyError(
            "reading Argoverse 2 needs the 'av2' package: pip install 'vei[av2]' and "
            "pip install --no-deps av2 (docs/datasets.md)"
        ) from exc
    return utm


def list_recordings(root: str | Path) -> list[str]:
    """Scenario ids of the ``scenario_<id>.parquet`` files below ``root``, sorted."""
    folder = Path(root)
    if not folder.is_dir():
        raise InputError("not a folder (expected Argoverse 2 scenario folders)", path=folder)
    found = sorted(p.stem[len("scenario_") :] for p in folder.rglob("scenario_*.parquet"))
    if not found:
        raise InputError("no scenario_<id>.parquet below this folder", path=folder)
    return found


def _scenario_path(root: Path, scenario_id: str) -> Path:
    hits = sorted(root.rglob(f"scenario_{scenario_id}.parquet"))
    if not hits:
        raise InputError(f"scenario_{scenario_id}.parquet not found below", path=root)
    return hits[0]


def city_grid(city: str, *, path: Path | None = None) -> UtmGrid:
    """The UTM grid of an AV2 city frame (zone and origin from the av2 package)."""
    utm = _require_av2()
    try:
        name = utm.CityName(city)
    except ValueError:
        raise InputError(
            f"unknown city {city!r}; expected one of {', '.join(c.value for c in utm.CityName)}",
            path=path,
            row=1,
            field="city",
        ) from None
    lat, lon = utm.CITY_ORIGIN_LATLONG_DICT[name]
    e, n = utm.convert_gps_to_utm(lat, lon, name)
    return UtmGrid(int(utm.UTM_ZONE_MAP[name]), False, float(e), float(n))


def _column(df: pd.DataFrame, path: Path, col: str, kind: str) -> np.ndarray:
    """A column checked to be of ``kind`` ('float', 'int', 'str', 'bool'), finite."""
    v = df[col]
    if kind == "str":
        bad = ~v.map(lambda x: isinstance(x, str) and x != "").to_numpy()
    elif kind == "bool":
        bad = ~v.map(lambda x: isinstance(x, bool | np.bool_)).to_numpy()
    else:
        num = pd.to_numeric(v, errors="coerce").to_numpy(dtype=np.float64)
        bad = ~np.isfinite(num)
        if kind == "int":
            bad |= np.isfinite(num) & (num != np.round(num))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        what = {"float": "a finite number", "int": "a whole number", "str": "a non-empty string",
                "bool": "true / false"}[kind]  # fmt: skip
        raise InputError(f"expected {what}, got {v.iloc[i]!r}", path=path, row=i + 1, field=col)
    return v.to_numpy()


def read_scenario_table(path: Path) -> pd.DataFrame:
    """The scenario parquet, validated (InputError naming file, 1-based row and column)."""
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        df = pd.read_parquet(path)
    except Exception as exc:  # pyarrow raises many types for a corrupt file
        raise InputError(
            f"not a readable parquet file: {type(exc).__name__}: {exc}", path=path
        ) from None
    for col in SCENARIO_COLUMNS:
        if col not in df.columns:
            raise InputError(
                f"missing column (Argoverse 2 scenario layout, docs/datasets.md; found: "
                f"{', '.join(map(str, df.columns))})",
                path=path,
                field=col,
            )
    if df.empty:
        raise InputError("no rows", path=path)
    kinds = {"observed": "bool", "track_id": "str", "object_type": "str", "object_category": "int",
             "timestep": "int", "position_x": "float", "position_y": "float", "heading": "float",
             "velocity_x": "float", "velocity_y": "float", "scenario_id": "str",
             "start_timestamp": "int", "end_timestamp": "int", "num_timestamps": "int",
             "focal_track_id": "str", "city": "str"}  # fmt: skip
    for col, kind in kinds.items():
        _column(df, path, col, kind)
    unknown = ~df["object_type"].isin(list(CLASS_TO_CATEGORY)).to_numpy()
    if unknown.any():
        i = int(np.flatnonzero(unknown)[0])
        raise InputError(
            f"unknown object_type {df['object_type'].iloc[i]!r}; expected one of {', '.join(CLASS_TO_CATEGORY)}",
            path=path,
            row=i + 1,
            field="object_type",
        )
    num = int(df["num_timestamps"].iloc[0])
    bad = (df["timestep"] < 0) | (df["timestep"] >= num)
    if bad.any():
        i = int(np.flatnonzero(bad.to_numpy())[0])
        raise InputError(
            f"timestep {int(df['timestep'].iloc[i])} outside [0, num_timestamps - 1 = {num - 1}]",
            path=path,
            row=i + 1,
            field="timestep",
        )
    from vei.datasets.csv_checks import check_increasing

    check_increasing(
        df["track_id"].to_numpy(dtype=object).astype(str),
        df["timestep"].to_numpy(),
        path,
        "timestep",
    )
    return df


def read_recording(root: str | Path, scenario_id: str) -> RecordingTracks:
    """Read one Argoverse 2 scenario (its parquet and, when beside it, its map archive)."""
    root = Path(root)
    path = _scenario_path(root, scenario_id)
    df = read_scenario_table(path)
    grid = city_grid(str(df["city"].iloc[0]), path=path)
    start_ns, end_ns = int(df["start_timestamp"].iloc[0]), int(df["end_timestamp"].iloc[0])
    num = int(df["num_timestamps"].iloc[0])
    dt_s = (end_ns - start_ns) / 1e9 / max(num - 1, 1)
    if not dt_s > 0:
        raise InputError(
            "end_timestamp must be after start_timestamp", path=path, row=1, field="end_timestamp"
        )
    x = df["position_x"].to_numpy(dtype=np.float64)
    y = df["position_y"].to_numpy(dtype=np.float64)
    lat, lon = grid.to_latlon(x, y)
    table = normalised_table(
        t_s=df["timestep"].to_numpy(dtype=np.float64) * dt_s,
        track_id=df["track_id"],
        source_class=df["object_type"],
        class_to_category=CLASS_TO_CATEGORY,
        lat_deg=lat,
        lon_deg=lon,
        heading_deg=grid.yaw_to_bearing(df["heading"].to_numpy(dtype=np.float64), x, y),
        speed_mps=np.hypot(df["velocity_x"], df["velocity_y"]),
        length_m=np.full(len(df), np.nan),
        width_m=np.full(len(df), np.nan),
    )
    map_path = path.with_name(f"log_map_archive_{scenario_id}.json")
    origin, writer = None, None
    if map_path.is_file():
        lanes, areas = read_map_archive(map_path)
        pts = np.vstack([np.vstack([a, b]) for _, a, b, _ in lanes] + areas)
        cx, cy = (pts.min(axis=0) + pts.max(axis=0)) / 2.0
        olat, olon = grid.to_latlon(cx, cy)
        origin = (round(float(olat), 10), round(float(olon), 10))

        def writer(folder: Path, origin_deg: tuple[float, float]) -> Path:
            return write_map_opendrive(map_path, folder / "map.xodr", grid, origin_deg)

    city = str(df["city"].iloc[0])
    notes = (
        f"Imported by vei from Argoverse 2 scenario {scenario_id} ({path.name}"
        + (f", {map_path.name}" if map_path.is_file() else ", no map archive")
        + f"): city {city}, {1.0 / dt_s:g} Hz; city frame = UTM zone {grid.zone}N translated to "
        "av2's city origin, heading -> true bearing. AV2 gives no object sizes (category "
        "defaults). start_time_utc = start_timestamp read as Unix nanoseconds."
        + (
            " The map archive is map.xodr beside this file, in the declared plane."
            if map_path.is_file()
            else ""
        )
    )
    return RecordingTracks(
        dataset="av2",
        recording=str(scenario_id),
        source=f"Argoverse 2 motion forecasting scenario {scenario_id} ({city})",
        tracks=table,
        ego_classes=EGO_CLASSES,
        rate_hz=1.0 / dt_s,
        start_time_utc=datetime(1970, 1, 1, tzinfo=UTC) + timedelta(microseconds=start_ns // 1000),
        notes=notes,
        origin_deg=origin,
        map_writer=writer,
    )


def _points(raw, path: Path, where: str) -> np.ndarray:
    try:
        pts = np.array([[float(p["x"]), float(p["y"])] for p in raw], dtype=np.float64)
    except (TypeError, KeyError, ValueError):
        raise InputError("expected a list of {x, y, z} points", path=path, field=where) from None
    if len(pts) < 2 or not np.isfinite(pts).all():
        raise InputError("expected at least 2 finite {x, y, z} points", path=path, field=where)
    return pts


def read_map_archive(
    path: Path,
) -> tuple[list[tuple[str, np.ndarray, np.ndarray, str]], list[np.ndarray]]:
    """Lane segments [(id, left [N, 2], right [M, 2], lane_type)] and drivable-area rings
    [K, 2] of a ``log_map_archive_<id>.json`` (city frame, metres). InputError names the
    file and the element (e.g. ``lane_segments/123/left_lane_boundary``)."""
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot read: {exc}", path=path) from None
    except json.JSONDecodeError as exc:
        raise InputError(f"not valid JSON: {exc.msg}", path=path, row=exc.lineno) from None
    if not isinstance(doc, dict) or not isinstance(doc.get("lane_segments"), dict):
        raise InputError(
            "expected a JSON object with 'lane_segments'", path=path, field="lane_segments"
        )
    lanes = []
    for key, seg in doc["lane_segments"].items():
        where = f"lane_segments/{key}"
        if not isinstance(seg, dict):
            raise InputError("expected an object", path=path, field=where)
        kind = seg.get("lane_type")
        if kind not in LANE_TYPES:
            raise InputError(
                f"lane_type {kind!r}; expected one of {', '.join(LANE_TYPES)}",
                path=path,
                field=f"{where}/lane_type",
            )
        left = _points(seg.get("left_lane_boundary"), path, f"{where}/left_lane_boundary")
        right = _points(seg.get("right_lane_boundary"), path, f"{where}/right_lane_boundary")
        lanes.append((str(seg.get("id", key)), left, right, LANE_TYPES[kind]))
    areas = []
    raw_areas = doc.get("drivable_areas", {})
    if not isinstance(raw_areas, dict):
        raise InputError("expected an object", path=path, field="drivable_areas")
    for key, area in raw_areas.items():
        if not isinstance(area, dict):
            raise InputError("expected an object", path=path, field=f"drivable_areas/{key}")
        areas.append(
            _points(area.get("area_boundary"), path, f"drivable_areas/{key}/area_boundary")
        )
    if not lanes:
        raise InputError("no lane segment", path=path, field="lane_segments")
    return lanes, areas


def write_map_opendrive(
    archive: Path, out: Path, grid: UtmGrid, origin_deg: tuple[float, float]
) -> Path:
    """Convert a map archive (city frame of ``grid``) into ``out`` (OpenDRIVE 1.4) in the
    tmerc plane at ``origin_deg``: every point city -> UTM -> WGS84 -> plane."""
    from vei.geo.frame import LocalFrame
    from vei.maps.lanes_xodr import LanePolylines, write_lanes_opendrive

    lanes, areas = read_map_archive(archive)
    plane = LocalFrame(*origin_deg)

    def to_plane(pts: np.ndarray) -> np.ndarray:
        lat, lon = grid.to_latlon(pts[:, 0], pts[:, 1])
        x, y = plane.to_xy(lat, lon)
        return np.column_stack([x, y])

    polylines = [LanePolylines(i, to_plane(a), to_plane(b), t) for i, a, b, t in lanes]
    return write_lanes_opendrive(
        out,
        polylines,
        proj_string=plane.proj_string,
        areas=[to_plane(a) for a in areas],
        name=f"Argoverse 2 {archive.stem}",
    )
