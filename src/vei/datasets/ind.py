"""The inD family (inD, rounD, uniD, exiD; levelXdata / ika RWTH Aachen): reader and writer.

Layout (levelXdata format v1.1; the files ika-rwth-aachen/drone-dataset-tools
``src/tracks_import.py`` reads), one recording ``XX`` per three files in one folder:

- ``XX_recordingMeta.csv``, one row: recordingId, locationId, frameRate [Hz], speedLimit,
  weekday, startTime [h], duration [s], numTracks, numVehicles, numVRUs, latLocation,
  lonLocation [deg, approximate], xUtmOrigin, yUtmOrigin [m], orthoPxToMeter (exiD and
  later exports may add ``utmZone``);
- ``XX_tracksMeta.csv``, one row per track: recordingId, trackId, initialFrame, finalFrame,
  numFrames, width, length [m; 0 for road users without a box], class;
- ``XX_tracks.csv``, one row per track and frame: recordingId, trackId, frame,
  trackLifetime, xCenter, yCenter [m, local frame], heading [deg], width, length,
  xVelocity, yVelocity, xAcceleration, yAcceleration, lonVelocity, latVelocity,
  lonAcceleration, latAcceleration (exiD adds lanelet columns: ignored).

Frames: the local frame is the UTM grid translated by (xUtmOrigin, yUtmOrigin): UTM
easting = xCenter + xUtmOrigin; heading is counter-clockwise from local +x (grid east), the
visualiser draws it negated in image coordinates. The zone is ``utmZone`` where given, else
the zone of (latLocation, lonLocation) (32N for the German recordings). Time: frame /
frameRate. :func:`read_recording` converts every sample to WGS84 and the heading to a true
bearing (meridian convergence included: :class:`vei.geo.grid.UtmGrid`).
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from vei.datasets import csv_checks as cc
from vei.datasets.world_tracks import RecordingTracks, normalised_table
from vei.errors import InputError
from vei.geo.grid import UtmGrid, utm_zone_of

#: Columns of the three files, in the order the datasets (and :func:`write_recording`) write them.
RECORDING_META_COLUMNS: tuple[str, ...] = (
    "recordingId", "locationId", "frameRate", "speedLimit", "weekday", "startTime", "duration",
    "numTracks", "numVehicles", "numVRUs", "latLocation", "lonLocation", "xUtmOrigin",
    "yUtmOrigin", "orthoPxToMeter",
)  # fmt: skip
TRACKS_META_COLUMNS: tuple[str, ...] = (
    "recordingId", "trackId", "initialFrame", "finalFrame", "numFrames", "width", "length", "class",
)  # fmt: skip
TRACKS_COLUMNS: tuple[str, ...] = (
    "recordingId", "trackId", "frame", "trackLifetime", "xCenter", "yCenter", "heading", "width",
    "length", "xVelocity", "yVelocity", "xAcceleration", "yAcceleration", "lonVelocity",
    "latVelocity", "lonAcceleration", "latAcceleration",
)  # fmt: skip
LAYOUT = "inD-family layout, docs/datasets.md"

#: Dataset class (lower case) -> vei category. The published classes of the family plus
#: ``escooter`` / ``e-scooter`` / ``scooter``, which vei accepts for data written in this
#: layout from other sources (the family itself has no e-scooter class).
CLASS_TO_CATEGORY: dict[str, str | None] = {
    "car": "vehicle",
    "van": "vehicle",
    "truck": "vehicle",
    "bus": "vehicle",
    "truck_bus": "vehicle",
    "trailer": "vehicle",
    "motorcycle": "cyclist",
    "bicycle": "cyclist",
    "pedestrian": "pedestrian",
    "escooter": "escooter",
    "e-scooter": "escooter",
    "scooter": "escooter",
}
#: Classes that can be the ego.
EGO_CLASSES: frozenset[str] = frozenset({"car", "van"})
#: The family has no calendar date (recordingMeta holds weekday and hour): t_s = 0 is put
#: at this placeholder instant (docs/datasets.md).
PLACEHOLDER_START_UTC = datetime(1970, 1, 1, tzinfo=UTC)

_FILE_RE = re.compile(r"^(\d+)_tracks\.csv$")


def list_recordings(root: str | Path) -> list[str]:
    """Recording ids ('00', '01', ...) of the ``XX_tracks.csv`` files in ``root``, sorted."""
    folder = Path(root)
    if not folder.is_dir():
        raise InputError(
            "not a folder (expected the folder holding XX_tracks.csv files)", path=folder
        )
    found = sorted(m.group(1) for p in folder.iterdir() if (m := _FILE_RE.match(p.name)))
    if not found:
        raise InputError(
            "no XX_tracks.csv here (an inD/rounD/uniD/exiD data folder holds XX_tracks.csv, "
            "XX_tracksMeta.csv, XX_recordingMeta.csv)",
            path=folder,
        )
    return found


@dataclass(frozen=True)
class _RecordingMeta:
    frame_rate_hz: float
    grid: UtmGrid
    weekday: str
    start_hour: str


def _zone(df: pd.DataFrame, path: Path) -> tuple[int, bool]:
    if "utmZone" in df.columns:
        text = str(df["utmZone"].iloc[0]).strip()
        m = re.fullmatch(r"(\d{1,2})\s*([A-Za-z]?)", text)
        if m is None or not 1 <= int(m.group(1)) <= 60:
            raise InputError(
                f"expected a UTM zone such as 32 or 32U, got {text!r}",
                path=path,
                row=1,
                field="utmZone",
            )
        band = m.group(2).upper()
        return int(m.group(1)), bool(band) and band not in "NPQRSTUVWXYZ" and band != ""
    cc.require(df, path, ("latLocation", "lonLocation"), layout=LAYOUT)
    lat = float(cc.numbers(df, path, "latLocation", lo=-90.0, hi=90.0, unit=" [deg]")[0])
    lon = float(cc.numbers(df, path, "lonLocation", lo=-180.0, hi=180.0, unit=" [deg]")[0])
    return utm_zone_of(lat, lon)


def _read_recording_meta(path: Path) -> _RecordingMeta:
    df = cc.read_table(path, text_columns=("weekday", "utmZone"))
    cc.require(df, path, ("recordingId", "frameRate", "xUtmOrigin", "yUtmOrigin"), layout=LAYOUT)
    rate = float(cc.numbers(df, path, "frameRate", lo=1e-3, hi=1000.0, unit=" [Hz]")[0])
    x0 = float(cc.numbers(df, path, "xUtmOrigin", unit=" [m]")[0])
    y0 = float(cc.numbers(df, path, "yUtmOrigin", unit=" [m]")[0])
    zone, south = _zone(df, path)
    weekday = str(df["weekday"].iloc[0]) if "weekday" in df.columns else ""
    hour = str(df["startTime"].iloc[0]) if "startTime" in df.columns else ""
    return _RecordingMeta(rate, UtmGrid(zone, south, x0, y0), weekday, hour)


def _read_tracks_meta(path: Path) -> dict[int, str]:
    df = cc.read_table(path, text_columns=("class",))
    cc.require(df, path, ("trackId", "class"), layout=LAYOUT)
    ids = cc.integers(df, path, "trackId", lo=0)
    cls = np.array([c.lower() for c in cc.texts(df, path, "class", what="a class label")])
    unknown = ~np.isin(cls, list(CLASS_TO_CATEGORY))
    if unknown.any():
        i = int(np.flatnonzero(unknown)[0])
        raise InputError(
            f"unknown class {df['class'].iloc[i]!r}; expected one of {', '.join(CLASS_TO_CATEGORY)}",
            path=path,
            row=i + 1,
            field="class",
        )
    dup = pd.Series(ids).duplicated().to_numpy()
    if dup.any():
        i = int(np.flatnonzero(dup)[0])
        raise InputError(f"trackId {ids[i]} appears twice", path=path, row=i + 1, field="trackId")
    return dict(zip(ids.tolist(), cls.tolist(), strict=True))


def read_recording(root: str | Path, recording: str) -> RecordingTracks:
    """Read recording ``recording`` ('00', '07', ...) of an inD-family data folder.

    Returns a :class:`RecordingTracks`: t_s = frame / frameRate; positions in WGS84 from
    the UTM grid; heading_deg the true bearing of the dataset's heading; speed_mps =
    |(xVelocity, yVelocity)| (grid metres, within 0.04 % of true metres); length_m /
    width_m from the per-frame columns (0 -> unknown).

    Raises:
        InputError: a missing file, column or value, a value that is not a number, an
            unknown class, a track without meta row, frames not increasing per track.
    """
    folder = Path(root)
    rec_path = folder / f"{recording}_recordingMeta.csv"
    meta_path = folder / f"{recording}_tracksMeta.csv"
    tracks_path = folder / f"{recording}_tracks.csv"
    meta = _read_recording_meta(rec_path)
    classes = _read_tracks_meta(meta_path)
    df = cc.read_table(tracks_path)
    cc.require(
        df,
        tracks_path,
        ("trackId", "frame", "xCenter", "yCenter", "heading", "width", "length", "xVelocity", "yVelocity"),
        layout=LAYOUT,
    )  # fmt: skip
    ids = cc.integers(df, tracks_path, "trackId", lo=0)
    frame = cc.integers(df, tracks_path, "frame", lo=0)
    x = cc.numbers(df, tracks_path, "xCenter", unit=" [m]")
    y = cc.numbers(df, tracks_path, "yCenter", unit=" [m]")
    heading = cc.numbers(df, tracks_path, "heading", lo=-360.0, hi=360.0, unit=" [deg]")
    width = cc.numbers(df, tracks_path, "width", lo=0.0, unit=" [m]")
    length = cc.numbers(df, tracks_path, "length", lo=0.0, unit=" [m]")
    vx = cc.numbers(df, tracks_path, "xVelocity", unit=" [m/s]")
    vy = cc.numbers(df, tracks_path, "yVelocity", unit=" [m/s]")
    orphan = ~np.isin(ids, list(classes))
    if orphan.any():
        i = int(np.flatnonzero(orphan)[0])
        raise InputError(
            f"trackId {ids[i]} has no row in {meta_path.name}",
            path=tracks_path,
            row=i + 1,
            field="trackId",
        )
    cc.check_increasing(ids, frame, tracks_path, "frame")
    lat, lon = meta.grid.to_latlon(x, y)
    bearing = meta.grid.yaw_to_bearing(np.radians(heading), x, y)
    table = normalised_table(
        t_s=frame / meta.frame_rate_hz,
        track_id=ids,
        source_class=[classes[i] for i in ids.tolist()],
        class_to_category=CLASS_TO_CATEGORY,
        lat_deg=lat,
        lon_deg=lon,
        heading_deg=bearing,
        speed_mps=np.hypot(vx, vy),
        length_m=length,
        width_m=width,
    )
    g = meta.grid
    notes = (
        f"Imported by vei from the inD-family recording {recording} ({tracks_path.name}, "
        f"{meta_path.name}, {rec_path.name}): {meta.frame_rate_hz:g} Hz, UTM zone {g.zone}"
        f"{'S' if g.south else 'N'} translated by ({g.x_origin_m:.3f}, {g.y_origin_m:.3f}) m, "
        "heading from grid east counter-clockwise -> true bearing. The dataset has no date "
        f"(weekday {meta.weekday or '?'}, start hour {meta.start_hour or '?'}): start_time_utc "
        "is a placeholder (1970-01-01 + frame time)."
    )
    return RecordingTracks(
        dataset="ind",
        recording=str(recording),
        source=f"inD-family drone recording {recording} ({folder.resolve().name})",
        tracks=table,
        ego_classes=EGO_CLASSES,
        rate_hz=meta.frame_rate_hz,
        start_time_utc=PLACEHOLDER_START_UTC,
        notes=notes,
    )


def write_recording(
    folder: str | Path,
    recording_id: int,
    tracks: pd.DataFrame,
    *,
    frame_rate_hz: float,
    x_utm_origin_m: float,
    y_utm_origin_m: float,
    lat_location_deg: float,
    lon_location_deg: float,
    location_id: int = 1,
    utm_zone: str | None = None,
) -> dict[str, Path]:
    """Write one recording in the inD-family layout (the three files, full column sets).

    Args:
        folder: where XX_tracks.csv, XX_tracksMeta.csv, XX_recordingMeta.csv go (created).
        recording_id: XX (written with two digits).
        tracks: one row per track and frame: trackId (int), frame (int), class, xCenter,
            yCenter [m, local grid], heading [deg, CCW from grid east], xVelocity,
            yVelocity [m/s], width, length [m, 0 for no box].
        frame_rate_hz, x_utm_origin_m, y_utm_origin_m, lat_location_deg,
        lon_location_deg, location_id: recordingMeta values.
        utm_zone: also write a ``utmZone`` column (as exiD-style exports do), e.g. '32U'.
    Returns:
        {'tracks', 'tracksMeta', 'recordingMeta'}: the files written.
    Accelerations are the per-track time derivatives of the velocities (np.gradient), and
    lon/lat components are taken along / across the heading.
    """
    from vei.io.atomic import write_bytes

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    t = tracks.sort_values(["trackId", "frame"], kind="stable").reset_index(drop=True)
    dt = 1.0 / frame_rate_hz
    ax = np.zeros(len(t))
    ay = np.zeros(len(t))
    first = t.groupby("trackId")["frame"].transform("min").to_numpy()
    for _, idx in t.groupby("trackId").indices.items():
        if len(idx) > 1:
            ax[idx] = np.gradient(t["xVelocity"].to_numpy()[idx], dt)
            ay[idx] = np.gradient(t["yVelocity"].to_numpy()[idx], dt)
    h = np.radians(t["heading"].to_numpy(dtype=np.float64))
    c, s = np.cos(h), np.sin(h)
    vx, vy = t["xVelocity"].to_numpy(), t["yVelocity"].to_numpy()
    body = pd.DataFrame(
        {
            "recordingId": recording_id,
            "trackId": t["trackId"].astype(int),
            "frame": t["frame"].astype(int),
            "trackLifetime": t["frame"].to_numpy() - first,
            "xCenter": t["xCenter"],
            "yCenter": t["yCenter"],
            "heading": t["heading"],
            "width": t["width"],
            "length": t["length"],
            "xVelocity": vx,
            "yVelocity": vy,
            "xAcceleration": ax,
            "yAcceleration": ay,
            "lonVelocity": vx * c + vy * s,
            "latVelocity": -vx * s + vy * c,
            "lonAcceleration": ax * c + ay * s,
            "latAcceleration": -ax * s + ay * c,
        }
    )[list(TRACKS_COLUMNS)]
    per = t.groupby("trackId", sort=True)
    meta = pd.DataFrame(
        {
            "recordingId": recording_id,
            "trackId": per["frame"].min().index.astype(int),
            "initialFrame": per["frame"].min().to_numpy(),
            "finalFrame": per["frame"].max().to_numpy(),
            "numFrames": per["frame"].size().to_numpy(),
            "width": per["width"].median().to_numpy(),
            "length": per["length"].median().to_numpy(),
            "class": per["class"].first().to_numpy(),
        }
    )[list(TRACKS_META_COLUMNS)]
    vru = (
        meta["class"]
        .str.lower()
        .isin(["pedestrian", "bicycle", "motorcycle", "escooter", "e-scooter", "scooter"])
    )
    rec = {
        "recordingId": recording_id,
        "locationId": location_id,
        "frameRate": frame_rate_hz,
        "speedLimit": 13.89,
        "weekday": "tuesday",
        "startTime": 12,
        "duration": float((t["frame"].max() - t["frame"].min()) * dt),
        "numTracks": len(meta),
        "numVehicles": int((~vru).sum()),
        "numVRUs": int(vru.sum()),
        "latLocation": lat_location_deg,
        "lonLocation": lon_location_deg,
        "xUtmOrigin": x_utm_origin_m,
        "yUtmOrigin": y_utm_origin_m,
        "orthoPxToMeter": 0.1,
    }
    if utm_zone is not None:
        rec["utmZone"] = utm_zone
    name = f"{recording_id:02d}"
    files = {
        "tracks": out / f"{name}_tracks.csv",
        "tracksMeta": out / f"{name}_tracksMeta.csv",
        "recordingMeta": out / f"{name}_recordingMeta.csv",
    }
    write_bytes(files["tracks"], body.to_csv(index=False).encode("utf-8"))
    write_bytes(files["tracksMeta"], meta.to_csv(index=False).encode("utf-8"))
    write_bytes(files["recordingMeta"], pd.DataFrame([rec]).to_csv(index=False).encode("utf-8"))
    return files
