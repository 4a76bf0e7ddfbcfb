"""SinD (SOTIF-AVLab, signalised intersections in China): reader and writer.

Layout (the repository's Format.md; the columns its visualiser ``SIND-Vis-tool/utils/
DataReader.py`` asserts), one record per folder:

- ``Veh_smoothed_tracks.csv``: track_id, frame_id, timestamp_ms [ms], agent_type (car,
  truck, bus, motorcycle, bicycle, tricycle), x, y [m], vx, vy [m/s], yaw_rad (body axis
  from +x), heading_rad (direction of motion from +x), length, width [m], ax, ay [m/s^2],
  v_lon, v_lat [m/s], a_lon, a_lat [m/s^2];
- ``Ped_smoothed_tracks.csv`` (optional): track_id (P1, P2, ...), frame_id, timestamp_ms,
  agent_type (pedestrian), x, y, vx, vy, ax, ay;
- ``Veh_tracks_meta.csv``, ``Ped_tracks_meta.csv``, ``recording_metas.csv``,
  ``TrafficLight_*.csv``: not needed (the class is in every row).

Frame: SinD's "ground coordinate system" is a local metric plane (the origin of its
Lanelet2 map) with no geographic reference in the files. vei places it as the transverse-
Mercator plane centred on ``origin`` (x east, y north; default (0, 0), a placeholder: give
the intersection's latitude / longitude to fetch an OSM map); every interaction declares
that origin, so the reconstructed scenario's plane coordinates equal SinD's x / y (the
projection distorts distances by less than 1e-9 within 200 m of the origin). Time:
timestamp_ms / 1000 (data frames every third camera frame at 29.97 Hz: about 10 Hz).
"""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from vei.datasets import csv_checks as cc
from vei.datasets.world_tracks import RecordingTracks, normalised_table
from vei.errors import InputError
from vei.geo.frame import LocalFrame

VEH_FILE = "Veh_smoothed_tracks.csv"
PED_FILE = "Ped_smoothed_tracks.csv"
VEH_COLUMNS: tuple[str, ...] = (
    "track_id", "frame_id", "timestamp_ms", "agent_type", "x", "y", "vx", "vy", "yaw_rad",
    "heading_rad", "length", "width", "ax", "ay", "v_lon", "v_lat", "a_lon", "a_lat",
)  # fmt: skip
PED_COLUMNS: tuple[str, ...] = (
    "track_id", "frame_id", "timestamp_ms", "agent_type", "x", "y", "vx", "vy", "ax", "ay",
)  # fmt: skip
LAYOUT = "SinD layout, docs/datasets.md"

#: agent_type -> vei category ('pedestrain' is the spelling of SinD's Format.md).
CLASS_TO_CATEGORY: dict[str, str | None] = {
    "car": "vehicle",
    "truck": "vehicle",
    "bus": "vehicle",
    "motorcycle": "cyclist",
    "bicycle": "cyclist",
    "tricycle": "cyclist",
    "pedestrian": "pedestrian",
    "pedestrain": "pedestrian",
}
EGO_CLASSES: frozenset[str] = frozenset({"car"})
#: SinD records carry no calendar date in the track files: placeholder for t_s = 0.
PLACEHOLDER_START_UTC = datetime(1970, 1, 1, tzinfo=UTC)


def list_recordings(root: str | Path) -> list[str]:
    """Record folders under ``root`` (those holding Veh_smoothed_tracks.csv), sorted by
    their path relative to root; ``root`` itself when it is a record folder."""
    folder = Path(root)
    if not folder.is_dir():
        raise InputError(
            "not a folder (expected a SinD record folder or a folder of them)", path=folder
        )
    if (folder / VEH_FILE).is_file():
        return ["."]
    found = sorted(str(p.parent.relative_to(folder)) for p in folder.rglob(VEH_FILE))
    if not found:
        raise InputError(f"no {VEH_FILE} below this folder", path=folder)
    return found


def _read(path: Path, columns: tuple[str, ...], *, yaw: bool) -> pd.DataFrame:
    df = cc.read_table(path, text_columns=("track_id", "agent_type"))
    need = ("track_id", "frame_id", "timestamp_ms", "agent_type", "x", "y", "vx", "vy")
    need += ("yaw_rad", "length", "width") if yaw else ()
    cc.require(df, path, need, layout=LAYOUT)
    track = cc.texts(df, path, "track_id", what="a track id").astype(str)
    cls = np.array([c.lower() for c in cc.texts(df, path, "agent_type", what="an agent type")])
    unknown = ~np.isin(cls, list(CLASS_TO_CATEGORY))
    if unknown.any():
        i = int(np.flatnonzero(unknown)[0])
        raise InputError(
            f"unknown agent_type {df['agent_type'].iloc[i]!r}; expected one of "
            f"{', '.join(CLASS_TO_CATEGORY)}",
            path=path,
            row=i + 1,
            field="agent_type",
        )
    frame = cc.integers(df, path, "frame_id", lo=0)
    t_ms = cc.numbers(df, path, "timestamp_ms", lo=0.0, unit=" [ms]")
    cc.check_increasing(track, t_ms, path, "timestamp_ms")
    out = pd.DataFrame(
        {
            "track_id": track,
            "frame_id": frame,
            "t_s": t_ms / 1000.0,
            "agent_type": cls,
            "x": cc.numbers(df, path, "x", unit=" [m]"),
            "y": cc.numbers(df, path, "y", unit=" [m]"),
            "vx": cc.numbers(df, path, "vx", unit=" [m/s]"),
            "vy": cc.numbers(df, path, "vy", unit=" [m/s]"),
        }
    )
    if yaw:
        out["yaw_rad"] = cc.numbers(df, path, "yaw_rad", lo=-10.0, hi=10.0, unit=" [rad]")
        out["length"] = cc.numbers(df, path, "length", lo=0.0, unit=" [m]")
        out["width"] = cc.numbers(df, path, "width", lo=0.0, unit=" [m]")
    else:
        out["yaw_rad"] = np.nan
        out["length"] = np.nan
        out["width"] = np.nan
    return out


def read_recording(
    root: str | Path, recording: str = ".", *, origin_deg: tuple[float, float] = (0.0, 0.0)
) -> RecordingTracks:
    """Read one SinD record folder (``root / recording``) into a :class:`RecordingTracks`.

    The ground frame becomes the tmerc plane at ``origin_deg`` (lat, lon): positions via
    :meth:`LocalFrame.to_latlon`, yaw_rad via :meth:`LocalFrame.yaw_to_bearing` (pedestrians
    have none: NaN), speed |(vx, vy)|, sizes from the per-row length / width.

    Raises:
        InputError: a missing file or column, a value that is not a number, an unknown
            agent_type, timestamps not increasing per track, a track id in both files.
    """
    folder = Path(root) / recording
    veh = _read(folder / VEH_FILE, VEH_COLUMNS, yaw=True)
    parts = [veh]
    ped_path = folder / PED_FILE
    if ped_path.is_file():
        ped = _read(ped_path, PED_COLUMNS, yaw=False)
        both = np.intersect1d(veh["track_id"].unique(), ped["track_id"].unique())
        if both.size:
            i = int(np.flatnonzero(ped["track_id"].to_numpy() == both[0])[0])
            raise InputError(
                f"track_id {both[0]!r} is also a vehicle track in {VEH_FILE}",
                path=ped_path,
                row=i + 1,
                field="track_id",
            )
        parts.append(ped)
    df = pd.concat(parts, ignore_index=True)
    plane = LocalFrame(*origin_deg)
    x, y = df["x"].to_numpy(), df["y"].to_numpy()
    lat, lon = plane.to_latlon(x, y)
    yaw = df["yaw_rad"].to_numpy()
    bearing = np.full(len(df), np.nan)
    ok = np.isfinite(yaw)
    if ok.any():
        bearing[ok] = plane.yaw_to_bearing(yaw[ok], x[ok], y[ok])
    table = normalised_table(
        t_s=df["t_s"],
        track_id=df["track_id"],
        source_class=df["agent_type"],
        class_to_category=CLASS_TO_CATEGORY,
        lat_deg=lat,
        lon_deg=lon,
        heading_deg=bearing,
        speed_mps=np.hypot(df["vx"], df["vy"]),
        length_m=df["length"],
        width_m=df["width"],
    )
    dt = np.diff(veh.sort_values(["track_id", "t_s"])["t_s"].to_numpy())
    dt = dt[dt > 0]
    rate = float(1.0 / np.median(dt)) if dt.size else 10.0
    name = Path(folder).resolve().name if recording == "." else recording.replace("/", "_")
    notes = (
        f"Imported by vei from the SinD record {name} ({VEH_FILE}"
        + (f", {PED_FILE}" if ped_path.is_file() else "")
        + f"): about {rate:.2f} Hz; the ground frame (not geo-referenced) placed as the tmerc "
        f"plane at ({origin_deg[0]:.7f}, {origin_deg[1]:.7f}) deg, x east, y north, which is "
        "also the interactions' declared plane origin; yaw_rad -> true bearing. No date in "
        "the files: start_time_utc is a placeholder (1970-01-01 + timestamp_ms)."
    )
    return RecordingTracks(
        dataset="sind",
        recording=name,
        source=f"SinD record {name}",
        tracks=table,
        ego_classes=EGO_CLASSES,
        rate_hz=rate,
        start_time_utc=PLACEHOLDER_START_UTC,
        notes=notes,
        origin_deg=(float(origin_deg[0]), float(origin_deg[1])),
    )


def write_recording(
    folder: str | Path, vehicles: pd.DataFrame, pedestrians: pd.DataFrame | None = None
) -> dict[str, Path]:
    """Write a record in the SinD layout (full column sets).

    Args:
        vehicles: rows track_id, frame_id, timestamp_ms, agent_type, x, y, vx, vy, yaw_rad,
            length, width (heading_rad, accelerations and lon/lat components are derived).
        pedestrians: rows track_id, frame_id, timestamp_ms, x, y, vx, vy (or None).
    Returns:
        {'vehicles': path, 'pedestrians': path (when written)}.
    """
    from vei.io.atomic import write_bytes

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)

    def accel(df: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
        ax, ay = np.zeros(len(df)), np.zeros(len(df))
        for _, idx in df.groupby("track_id").indices.items():
            if len(idx) > 1:
                t = df["timestamp_ms"].to_numpy()[idx] / 1000.0
                ax[idx] = np.gradient(df["vx"].to_numpy()[idx], t)
                ay[idx] = np.gradient(df["vy"].to_numpy()[idx], t)
        return ax, ay

    v = vehicles.reset_index(drop=True)
    ax, ay = accel(v)
    c, s = np.cos(v["yaw_rad"].to_numpy()), np.sin(v["yaw_rad"].to_numpy())
    veh = v.assign(
        heading_rad=np.arctan2(v["vy"], v["vx"]),
        ax=ax,
        ay=ay,
        v_lon=v["vx"] * c + v["vy"] * s,
        v_lat=-v["vx"] * s + v["vy"] * c,
        a_lon=ax * c + ay * s,
        a_lat=-ax * s + ay * c,
    )[list(VEH_COLUMNS)]
    files = {"vehicles": out / VEH_FILE}
    write_bytes(files["vehicles"], veh.to_csv(index=False).encode("utf-8"))
    if pedestrians is not None:
        p = pedestrians.reset_index(drop=True)
        pax, pay = accel(p)
        ped = p.assign(agent_type="pedestrian", ax=pax, ay=pay)[list(PED_COLUMNS)]
        files["pedestrians"] = out / PED_FILE
        write_bytes(files["pedestrians"], ped.to_csv(index=False).encode("utf-8"))
    return files
