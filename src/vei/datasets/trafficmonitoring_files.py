"""TrafficMonitoring dataset files: layout, reading and validation (Ingolstadt, 2021-02-09).

Source: github.com/jul095/TrafficMonitoring (Apache-2.0), folder ``data/measurements``:

- ``car_data/<prefix>INSSOL.csv``: the instrumented car's dGPS/INS at 100 Hz. ``pos_x`` /
  ``pos_y`` = longitude / latitude [rad], ``rpy_z`` = heading [rad, clockwise from true
  north], ``vel_x`` / ``vel_y`` = north / east velocity [m/s], time = GPS ``week`` +
  ``gps_tow`` [s] (GPS time, 18 leap seconds ahead of UTC in 2021).
- ``videos/trajectory_output/<scenario>_trajectories.csv``: every road user tracked by a
  roadside camera at 30 frames/s; ``coordinate_world_x_opt`` / ``_y_opt`` are UTM zone 32N
  (EPSG:32632) easting / northing [m]; ``class_id`` is a detector label that can flicker.
- ``matching/<scenario>_matching.csv``: ``start_timestamp`` of the video (local time, CET =
  UTC+1), ``measurement_prefix`` of the INS record, and ``relevant_track_id`` = the
  instrumented car's own track in the camera data. Frame ``k`` is at start + k / 30 s (the
  dataset authors' own evaluation uses this convention).

This module reads and validates these files (every bad value is an InputError naming
file, row and column) and maps the detector labels to vei categories; the conversion into
an interaction is :mod:`vei.datasets.trafficmonitoring`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta, timezone
from pathlib import Path

import numpy as np
import pandas as pd

from vei.errors import InputError

#: Path of the measurements inside the dataset root.
MEASUREMENTS_DIR = Path("data") / "measurements"
CAR_DATA_DIR = MEASUREMENTS_DIR / "car_data"
MATCHING_DIR = MEASUREMENTS_DIR / "matching"
TRAJECTORIES_DIR = MEASUREMENTS_DIR / "videos" / "trajectory_output"
MATCHING_SUFFIX = "_matching.csv"
TRAJECTORIES_SUFFIX = "_trajectories.csv"
INS_SUFFIX = "INSSOL.csv"

#: Repository and commit the importer was written against.
DATASET_REPO = "jul095/TrafficMonitoring"
DATASET_COMMIT = "641075e8d42337a46e8825fc3947f0b49b405b3b"

GPS_EPOCH = datetime(1980, 1, 6, tzinfo=UTC)
#: GPS - UTC in 2021 [s] (unchanged since 2017-01-01).
GPS_UTC_LEAP_S = 18
SECONDS_PER_WEEK = 604_800
#: Camera frame rate [frames/s].
CAMERA_FPS = 30.0
#: Timezone of the matching files' start_timestamp (CET, no DST in February).
CAMERA_TIMEZONE = timezone(timedelta(hours=1), "CET")
#: CRS of coordinate_world_x_opt / coordinate_world_y_opt.
CAMERA_CRS = "EPSG:32632"

#: Detector labels -> vei categories (labels not listed are not imported).
CLASS_TO_CATEGORY: dict[str, str] = {
    "scooter": "escooter",
    "e-scooter": "escooter",
    "escooter": "escooter",
    "cyclist": "cyclist",
    "bicycle": "cyclist",
    "pedestrian": "pedestrian",
    "person": "pedestrian",
    "car": "vehicle",
    "bus": "vehicle",
    "truck": "vehicle",
    "transporter": "vehicle",
    "car-transporter": "vehicle",
    "van": "vehicle",
    "motorcycle": "vehicle",
    "trailer": "vehicle",
    "tram": "vehicle",
}

_INS_COLUMNS = ("week", "gps_tow", "rpy_z", "vel_x", "vel_y", "pos_x", "pos_y")
_CAMERA_COLUMNS = (
    "frame_id",
    "class_id",
    "track_id",
    "coordinate_world_x_opt",
    "coordinate_world_y_opt",
)
_MATCHING_COLUMNS = ("start_timestamp", "measurement_prefix", "relevant_track_id")
#: Plausible ranges of the INS columns: (column, min, max, meaning); outside is an InputError.
_INS_RANGES: tuple[tuple[str, float, float, str], ...] = (
    ("week", 0.0, 9999.0, "GPS week number"),
    ("gps_tow", 0.0, float(SECONDS_PER_WEEK), "GPS time of week [s]"),
    ("rpy_z", -4.0 * math.pi, 4.0 * math.pi, "heading [rad]"),
    ("vel_x", -200.0, 200.0, "north velocity [m/s]"),
    ("vel_y", -200.0, 200.0, "east velocity [m/s]"),
    ("pos_x", -math.pi, math.pi, "longitude in radians, not degrees"),
    ("pos_y", -math.pi / 2, math.pi / 2, "latitude in radians, not degrees"),
)
#: Plausible ranges of the camera columns (UTM 32N easting / northing [m], frame index).
_CAMERA_RANGES: tuple[tuple[str, float, float, str], ...] = (
    ("frame_id", 0.0, 1e8, "video frame index"),
    ("coordinate_world_x_opt", 100_000.0, 900_000.0, "UTM 32N easting [m]"),
    ("coordinate_world_y_opt", 0.0, 9_400_000.0, "UTM 32N northing [m]"),
)


# ----------------------------------------------------------------------------- time


def gps_to_utc(week: int, tow_s: float) -> datetime:
    """GPS week + time of week [s] -> aware UTC datetime (18 leap seconds, microsecond resolution)."""
    return GPS_EPOCH + timedelta(weeks=int(week), seconds=float(tow_s) - GPS_UTC_LEAP_S)


# ----------------------------------------------------------------------------- files


def _measurements(root: str | Path) -> Path:
    root = Path(root)
    meas = root / MEASUREMENTS_DIR
    if not meas.is_dir():
        raise InputError(
            f"not a TrafficMonitoring dataset root: {MEASUREMENTS_DIR} not found below it "
            "(give the folder that holds data/measurements; `vei datasets download "
            "trafficmonitoring` fetches it)",
            path=root,
        )
    return meas


def list_scenarios(root: str | Path) -> list[str]:
    """Scenario names of a dataset root: the ``<name>_matching.csv`` files, sorted."""
    _measurements(root)
    folder = Path(root) / MATCHING_DIR
    if not folder.is_dir():
        raise InputError("matching folder not found", path=folder)
    return sorted(p.name[: -len(MATCHING_SUFFIX)] for p in folder.glob(f"*{MATCHING_SUFFIX}"))


@dataclass(frozen=True)
class Matching:
    """Contents of ``<scenario>_matching.csv``.

    Attributes:
        scenario: scenario name.
        start_local: video start (aware, CET).
        measurement_prefix: INS record prefix (the INS file is ``<prefix>INSSOL.csv``).
        relevant_track_id: the instrumented car's track id in the camera data (str).
        path: the matching file.
    """

    scenario: str
    start_local: datetime
    measurement_prefix: str
    relevant_track_id: str
    path: Path

    @property
    def start_utc(self) -> datetime:
        """Video start in UTC."""
        return self.start_local.astimezone(UTC)

    @property
    def ins_file_name(self) -> str:
        """File name of the INS record (apostrophes included)."""
        return f"{self.measurement_prefix}{INS_SUFFIX}"


def _read_table(path: Path, columns: tuple[str, ...]) -> pd.DataFrame:
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        df = pd.read_csv(path)
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"not a readable CSV file: {exc}", path=path) from None
    for col in columns:
        if col not in df.columns:
            raise InputError(
                f"missing column (found: {', '.join(map(str, df.columns))})", path=path, field=col
            )
    if df.empty:
        raise InputError("no data rows", path=path)
    return df


def _check_ranges(
    values: pd.DataFrame, ranges: tuple[tuple[str, float, float, str], ...], path: Path
) -> None:
    """InputError naming the first row whose value lies outside its column's range."""
    for col, lo, hi, what in ranges:
        v = values[col].to_numpy(dtype=np.float64)
        bad = ~np.isfinite(v) | (v < lo) | (v > hi)
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            raise InputError(
                f"value {float(v[i])!r} outside [{lo:g}, {hi:g}] ({what})",
                path=path,
                row=i + 1,
                field=col,
            )


def read_matching(root: str | Path, scenario: str) -> Matching:
    """Read ``<scenario>_matching.csv``; an unknown scenario lists the known ones."""
    meas = _measurements(root)
    path = meas / "matching" / f"{scenario}{MATCHING_SUFFIX}"
    if not path.is_file():
        known = list_scenarios(root)
        raise InputError(
            f"unknown scenario {scenario!r}; known scenarios: {', '.join(known) or 'none'}",
            path=path,
        )
    df = _read_table(path, _MATCHING_COLUMNS)
    row = df.iloc[0]
    try:
        naive = datetime.strptime(str(row["start_timestamp"]).strip(), "%Y-%m-%d %H:%M:%S.%f")
    except ValueError:
        raise InputError(
            f"expected 'YYYY-MM-DD HH:MM:SS.ff' (local time, CET), got {row['start_timestamp']!r}",
            path=path,
            row=1,
            field="start_timestamp",
        ) from None
    try:
        track = str(int(row["relevant_track_id"]))
    except (TypeError, ValueError):
        raise InputError(
            f"expected an integer track id, got {row['relevant_track_id']!r}",
            path=path,
            row=1,
            field="relevant_track_id",
        ) from None
    return Matching(
        scenario=scenario,
        start_local=naive.replace(tzinfo=CAMERA_TIMEZONE),
        measurement_prefix=str(row["measurement_prefix"]).strip(),
        relevant_track_id=track,
        path=path,
    )


@dataclass(frozen=True)
class InsRecord:
    """The car's INS record, times relative to its first sample.

    Attributes:
        start_utc: UTC time of the first sample.
        t_s: [N] seconds since start_utc (strictly increasing).
        lat_deg, lon_deg: [N] position [deg].
        heading_deg: [N] true heading [deg clockwise from north, [0, 360)].
        speed_mps: [N] horizontal speed from the velocity (north, east) [m/s].
        path: the INSSOL file.
    """

    start_utc: datetime
    t_s: np.ndarray
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    heading_deg: np.ndarray
    speed_mps: np.ndarray
    path: Path

    def at(self, t_s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(lat_deg, lon_deg, heading_deg) at times t_s [s] (any shape), linear between samples.

        Linear interpolation of degrees over 10 ms (< 0.2 m) is exact to well under a
        millimetre; the heading is unwrapped first.
        """
        t = np.asarray(t_s, dtype=np.float64)
        lat = np.interp(t, self.t_s, self.lat_deg)
        lon = np.interp(t, self.t_s, self.lon_deg)
        unwrapped = np.degrees(np.unwrap(np.radians(self.heading_deg)))
        heading = np.mod(np.interp(t, self.t_s, unwrapped), 360.0)
        return lat, lon, heading


def read_ins(path: Path) -> InsRecord:
    """Read an ``INSSOL.csv`` (100 Hz) into an :class:`InsRecord`."""
    df = _read_table(path, _INS_COLUMNS)
    values = df[list(_INS_COLUMNS)].apply(pd.to_numeric, errors="coerce")
    bad = values.isna().any(axis=1).to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        col = next(c for c in _INS_COLUMNS if pd.isna(values[c].iloc[i]))
        raise InputError("missing or non-numeric value", path=path, row=i + 1, field=col)
    _check_ranges(values, _INS_RANGES, path)
    week = values["week"].to_numpy(dtype=np.int64)
    tow = values["gps_tow"].to_numpy(dtype=np.float64)
    # GPS time of week has microsecond resolution: round away float noise of the difference
    t = np.round((week - week[0]).astype(np.float64) * SECONDS_PER_WEEK + (tow - tow[0]), 6)
    dt = np.diff(t)
    if (dt <= 0).any():
        i = int(np.flatnonzero(dt <= 0)[0]) + 1
        raise InputError("GPS time does not increase", path=path, row=i + 1, field="gps_tow")
    lat = np.degrees(values["pos_y"].to_numpy(dtype=np.float64))
    lon = np.degrees(values["pos_x"].to_numpy(dtype=np.float64))
    if np.abs(lat).max() > 90 or np.abs(lon).max() > 180:
        raise InputError(
            "position out of range: expected pos_x/pos_y as longitude/latitude in radians",
            path=path,
            field="pos_y",
        )
    vn = values["vel_x"].to_numpy(dtype=np.float64)
    ve = values["vel_y"].to_numpy(dtype=np.float64)
    return InsRecord(
        start_utc=gps_to_utc(int(week[0]), float(tow[0])),
        t_s=t,
        lat_deg=lat,
        lon_deg=lon,
        heading_deg=np.mod(np.degrees(values["rpy_z"].to_numpy(dtype=np.float64)), 360.0),
        speed_mps=np.hypot(vn, ve),
        path=path,
    )


def read_camera_utm(path: Path) -> pd.DataFrame:
    """Read and validate ``<scenario>_trajectories.csv`` in the camera's own plane.

    Every row is checked (numbers, plausible UTM 32N ranges, one row per track and frame);
    a bad one is an InputError naming file, row and column.

    Args:
        path: the trajectories file.
    Returns:
        DataFrame [N rows]: frame_id (int), track_id (str), class_id (raw label), x_m, y_m
        (UTM 32N easting / northing [m], EPSG:32632); sorted by (track_id, frame_id).
    """
    df = _read_table(path, _CAMERA_COLUMNS)
    num = df[["frame_id", "coordinate_world_x_opt", "coordinate_world_y_opt"]].apply(
        pd.to_numeric, errors="coerce"
    )
    bad = num.isna().any(axis=1).to_numpy() | df["track_id"].isna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        col = next(
            (
                c
                for c in ("frame_id", "coordinate_world_x_opt", "coordinate_world_y_opt")
                if pd.isna(num[c].iloc[i])
            ),
            "track_id",
        )
        raise InputError("missing or non-numeric value", path=path, row=i + 1, field=col)
    _check_ranges(num, _CAMERA_RANGES, path)
    out = pd.DataFrame(
        {
            "frame_id": num["frame_id"].to_numpy(dtype=np.int64),
            "track_id": df["track_id"].astype(str).str.strip().str.replace(r"\.0$", "", regex=True),
            "class_id": df["class_id"].astype(str).str.strip(),
            "x_m": num["coordinate_world_x_opt"].to_numpy(dtype=np.float64),
            "y_m": num["coordinate_world_y_opt"].to_numpy(dtype=np.float64),
        }
    )
    dup = out.duplicated(["track_id", "frame_id"]).to_numpy()
    if dup.any():
        i = int(np.flatnonzero(dup)[0])
        raise InputError(
            f"track {out['track_id'].iloc[i]!r} appears twice in frame {out['frame_id'].iloc[i]}",
            path=path,
            row=i + 1,
            field="frame_id",
        )
    return out.sort_values(["track_id", "frame_id"], kind="stable").reset_index(drop=True)


def read_camera(path: Path, start_s: float) -> pd.DataFrame:
    """Read ``<scenario>_trajectories.csv`` (validated by :func:`read_camera_utm`).

    Args:
        path: the trajectories file.
        start_s: time of frame 0 relative to the chosen time origin [s].
    Returns:
        DataFrame [N rows]: t_s [s] (= start_s + frame_id / 30), frame_id (int), track_id
        (str), class_id (raw label), lat_deg, lon_deg (WGS84, from UTM 32N); sorted by
        (track_id, frame_id).
    """
    from pyproj import Transformer

    cam = read_camera_utm(path)
    to_wgs84 = Transformer.from_crs(CAMERA_CRS, "EPSG:4326", always_xy=True)
    lon, lat = to_wgs84.transform(cam["x_m"].to_numpy(), cam["y_m"].to_numpy())
    frame = cam["frame_id"].to_numpy()
    return pd.DataFrame(
        {
            "t_s": np.round(start_s + frame / CAMERA_FPS, 9),
            "frame_id": frame,
            "track_id": cam["track_id"],
            "class_id": cam["class_id"],
            "lat_deg": np.asarray(lat),
            "lon_deg": np.asarray(lon),
        }
    )


def majority_category(labels: pd.Series) -> str | None:
    """The most frequent vei category among a track's detector labels (ties: alphabetical).

    Labels are mapped through CLASS_TO_CATEGORY first (so 'car' and 'transporter' vote
    together for 'vehicle'); unknown labels do not vote. None if no label is known.
    """
    cats = labels.map(CLASS_TO_CATEGORY).dropna()
    if cats.empty:
        return None
    counts = cats.value_counts()
    best = counts.max()
    return sorted(counts[counts == best].index)[0]


def majority_categories(camera: pd.DataFrame) -> pd.Series:
    """Majority category per track of a camera table (see :func:`majority_category`).

    Args:
        camera: rows with 'track_id' and 'class_id' (as from :func:`read_camera`).
    Returns:
        Series indexed by track_id (sorted), values a category or None.
    """
    cats = camera["class_id"].map(CLASS_TO_CATEGORY)
    counts = (
        pd.DataFrame({"track_id": camera["track_id"], "category": cats})
        .dropna()
        .groupby(["track_id", "category"])
        .size()
        .reset_index(name="n")
        .sort_values(["track_id", "n", "category"], ascending=[True, False, True], kind="stable")
    )
    best = counts.drop_duplicates("track_id").set_index("track_id")["category"]
    tracks = pd.Index(sorted(camera["track_id"].unique()), name="track_id")
    return best.reindex(tracks).astype(object).where(lambda s: s.notna(), None)
