"""A TrafficMonitoring recording written out in the inD layout ("two doors", docs/datasets.md).

:func:`write_as_ind` writes the roadside camera's tracks of one scenario as an inD-family
recording (``XX_tracks.csv`` / ``XX_tracksMeta.csv`` / ``XX_recordingMeta.csv`` at 30 Hz,
UTM 32N translated to a local origin), the car's own camera track among them, and adds the
car's INS as one more ``car`` track sampled at the camera frames. Importing that with
``vei import tracks --format ind --ego <camera track | INS track>`` must give what
``vei import trafficmonitoring`` gives (tests/datasets/test_two_doors.py).

Per track: the class is the majority detector label (e-scooters written as ``escooter``,
cyclists as ``bicycle``), the velocity a least-squares line through the samples within
+-0.5 s (as the TrafficMonitoring importer estimates a rider's direction), the heading its
direction (held from the nearest moving sample where slower than 0.5 m/s), no box for
riders and pedestrians (width = length = 0, as the family writes them).
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from vei.datasets.ind import write_recording
from vei.datasets.trafficmonitoring import (
    CAMERA_FPS,
    TRAJECTORIES_SUFFIX,
    YAW_MIN_SPEED_MPS,
    YAW_WINDOW_S,
    _measurements,
    _trim_ins,
    majority_categories,
    read_camera_utm,
    read_ins,
    read_matching,
)
from vei.errors import InputError
from vei.geo.grid import UtmGrid

#: inD class written per vei category (vehicles keep a class of their raw label).
_RIDER_CLASS = {"escooter": "escooter", "cyclist": "bicycle", "pedestrian": "pedestrian"}
_VEHICLE_CLASS = {"bus": "bus", "truck": "truck", "motorcycle": "motorcycle", "trailer": "trailer",
                  "van": "van", "transporter": "van", "car-transporter": "van"}  # fmt: skip
#: Footprint [m] written for the INS track (vei's default ego box).
EGO_BOX_M = (4.7, 1.85)


@dataclass(frozen=True)
class IndExport:
    """What :func:`write_as_ind` wrote.

    Attributes:
        folder: the data folder; recording: its id ('01').
        camera_ego_id: the car's own camera track id (relevant_track_id).
        ins_ego_id: the track id of the car's INS.
        frame0_s: time of frame 0 on the TrafficMonitoring importer's clock (t_s = 0 at the
            first INS sample it keeps) [s].
    """

    folder: Path
    recording: str
    camera_ego_id: str
    ins_ego_id: str
    frame0_s: float


def _velocity_heading(t: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, ...]:
    """Least-squares velocity over +-YAW_WINDOW_S [m/s] and heading [deg, CCW from grid east]."""
    vx, vy = np.zeros(t.size), np.zeros(t.size)
    for k in range(t.size):
        sel = np.abs(t - t[k]) <= YAW_WINDOW_S + 1e-9
        if sel.sum() < 2:
            continue
        tc = t[sel] - t[sel].mean()
        den = float(np.dot(tc, tc))
        if den > 0:
            vx[k] = float(np.dot(tc, x[sel] - x[sel].mean()) / den)
            vy[k] = float(np.dot(tc, y[sel] - y[sel].mean()) / den)
    heading = np.degrees(np.arctan2(vy, vx))
    moving = np.hypot(vx, vy) >= YAW_MIN_SPEED_MPS
    if moving.any() and not moving.all():
        good = np.flatnonzero(moving)
        nearest = good[np.clip(np.searchsorted(good, np.arange(t.size)), 0, good.size - 1)]
        heading = np.where(moving, heading, heading[nearest])
    elif not moving.any():
        heading = np.zeros(t.size)
    return vx, vy, np.mod(heading, 360.0)


def write_as_ind(
    root: str | Path, scenario: str, folder: str | Path, *, recording_id: int = 1
) -> IndExport:
    """Write TrafficMonitoring ``scenario`` (dataset ``root``) in the inD layout under ``folder``.

    Raises:
        InputError: the dataset's files are missing or malformed (as the importer reports).
    """
    meas = _measurements(root)
    matching = read_matching(root, scenario)
    ins = read_ins(meas / "car_data" / matching.ins_file_name)
    cam = read_camera_utm(
        meas / "videos" / "trajectory_output" / f"{scenario}{TRAJECTORIES_SUFFIX}"
    )
    offset = (matching.start_utc - ins.start_utc).total_seconds()
    t_cam = offset + cam["frame_id"].to_numpy() / CAMERA_FPS
    ins = _trim_ins(ins, float(t_cam.min()), float(t_cam.max()))
    frame0_s = (matching.start_utc - ins.start_utc).total_seconds()
    x0 = float(np.round(cam["x_m"].mean()))
    y0 = float(np.round(cam["y_m"].mean()))
    grid = UtmGrid(32, False, x0, y0)
    # majority_categories wants lat/lon-free columns only: track_id, class_id
    cats = majority_categories(cam)
    try:
        ids = {tid: int(tid) for tid in cats.index}
    except ValueError:
        raise InputError(
            "camera track ids must be whole numbers for the inD layout", path=matching.path
        ) from None
    rows = []
    for tid, cat in cats.items():
        if cat is None:
            continue
        tr = cam[cam["track_id"] == tid]
        if cat == "vehicle":
            raw = tr["class_id"].str.lower().mode().iloc[0]
            cls, size = _VEHICLE_CLASS.get(raw, "car"), EGO_BOX_M
        else:
            cls, size = _RIDER_CLASS[cat], (0.0, 0.0)
        t = tr["frame_id"].to_numpy() / CAMERA_FPS
        x, y = tr["x_m"].to_numpy() - x0, tr["y_m"].to_numpy() - y0
        vx, vy, heading = _velocity_heading(t, x, y)
        rows.append(pd.DataFrame({"trackId": ids[tid], "frame": tr["frame_id"].to_numpy(), "class": cls,
                                  "xCenter": x, "yCenter": y, "heading": heading, "xVelocity": vx,
                                  "yVelocity": vy, "width": size[1], "length": size[0]}))  # fmt: skip
    # the INS at the camera frames inside its (trimmed) span
    f_lo = int(np.ceil((ins.t_s[0] - frame0_s) * CAMERA_FPS - 1e-9))
    f_hi = int(np.floor((ins.t_s[-1] - frame0_s) * CAMERA_FPS + 1e-9))
    frames = np.arange(max(f_lo, 0), f_hi + 1)
    ts = frame0_s + frames / CAMERA_FPS
    lat, lon, bearing = ins.at(ts)
    speed = np.interp(ts, ins.t_s, ins.speed_mps)
    x, y = grid.to_xy(lat, lon)
    yaw = grid.bearing_to_yaw(bearing, lat, lon)
    ins_id = max(ids.values()) + 1
    rows.append(pd.DataFrame({"trackId": ins_id, "frame": frames, "class": "car", "xCenter": x, "yCenter": y,
                              "heading": np.mod(np.degrees(yaw), 360.0), "xVelocity": speed * np.cos(yaw),
                              "yVelocity": speed * np.sin(yaw), "width": EGO_BOX_M[1],
                              "length": EGO_BOX_M[0]}))  # fmt: skip
    lat0, lon0 = grid.to_latlon(0.0, 0.0)
    write_recording(
        folder,
        recording_id,
        pd.concat(rows, ignore_index=True),
        frame_rate_hz=CAMERA_FPS,
        x_utm_origin_m=x0,
        y_utm_origin_m=y0,
        lat_location_deg=float(lat0),
        lon_location_deg=float(lon0),
    )
    return IndExport(
        Path(folder), f"{recording_id:02d}", str(matching.relevant_track_id), str(ins_id), frame0_s
    )
