"""Test helper: a tiny, valid, self-consistent interaction folder (format vei.interaction/1).

``make_interaction(tmp_path, **overrides) -> Path`` writes ``tmp_path/<name>`` with:

- ego: 10 Hz for 6 s (t_s 0.0 .. 6.0, 61 fixes), straight line at 5 m/s on a true bearing
  of 60 deg starting at (48.7665 N, 11.4345 E), heading_deg = 60, speed_mps = 5;
- ground truth (10 Hz, same span): track "1" (escooter) starting 25 m ahead and 4 m left of
  the ego's start, riding at 1.5 m/s on bearing 150 deg (crossing the ego's path from its
  left to its right, yaw_deg -90); track "2" (cyclist) starting 40 m ahead, 3 m right, riding at 4 m/s on bearing 240
  (opposite direction, yaw_deg 180);
- annotations: the ground truth at 1 Hz (t_s 0..6) made ego-relative through the geodesic
  inverse (x forward, y left; negated when ``y_axis="right"``), yaw_deg = bearing - 60
  taken positive towards +y, length_m/width_m from vei.types.DEFAULT_DIMENSIONS_M.

Overrides (keyword arguments):
- any interaction.json key (``id``, ``source``, ``start_time_utc``, ``y_axis``,
  ``annotation_rate_hz``, ``notes``, ``format``) replaces the value; ``DELETE`` removes it;
- ``ego``, ``annotations``, ``ground_truth``: DataFrames written instead of the generated
  ones (``ground_truth=None`` writes no ground_truth.csv);
- ``name``: folder name (default "interaction").

Hand-checkable constants are module attributes (EGO_START, EGO_BEARING_DEG, ...), and
``expected_tables()`` returns the generated DataFrames (before any override).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
from pyproj import Geod

DELETE = object()

EGO_START = (48.7665, 11.4345)  # lat, lon [deg]
EGO_BEARING_DEG = 60.0
EGO_SPEED_MPS = 5.0
EGO_RATE_HZ = 10.0
DURATION_S = 6.0
START_TIME_UTC = "2021-02-09T12:40:35.690000Z"
#: track id -> (category, forward offset [m], left offset [m], bearing [deg], speed [m/s])
TRACKS = {
    "1": ("escooter", 25.0, 4.0, 150.0, 1.5),
    "2": ("cyclist", 40.0, -3.0, 240.0, 4.0),
}
DIMENSIONS = {"escooter": (1.2, 0.6), "cyclist": (1.8, 0.6)}

_GEOD = Geod(ellps="WGS84")


def _ego() -> pd.DataFrame:
    t = np.round(np.arange(0.0, DURATION_S + 1e-9, 1.0 / EGO_RATE_HZ), 6)
    n = t.size
    lon, lat, _ = _GEOD.fwd(
        np.full(n, EGO_START[1]),
        np.full(n, EGO_START[0]),
        np.full(n, EGO_BEARING_DEG),
        EGO_SPEED_MPS * t,
    )
    return pd.DataFrame(
        {
            "t_s": t,
            "lat_deg": np.asarray(lat),
            "lon_deg": np.asarray(lon),
            "heading_deg": np.full(n, EGO_BEARING_DEG),
            "speed_mps": np.full(n, EGO_SPEED_MPS),
        }
    )


def expected_tables(y_axis: str = "left") -> tuple[pd.DataFrame, pd.DataFrame, pd.DataFrame]:
    """(ego, annotations, ground_truth) of the default interaction."""
    ego = _ego()
    t = ego["t_s"].to_numpy()
    n = t.size
    gt_rows, ann_rows = [], []
    for tid, (cat, fwd, left, bearing, speed) in TRACKS.items():
        d0 = float(np.hypot(fwd, left))
        az0 = EGO_BEARING_DEG - np.degrees(np.arctan2(left, fwd))
        lon0, lat0, _ = _GEOD.fwd(EGO_START[1], EGO_START[0], az0, d0)
        lon, lat, _ = _GEOD.fwd(np.full(n, lon0), np.full(n, lat0), np.full(n, bearing), speed * t)
        gt = pd.DataFrame(
            {"t_s": t, "track_id": tid, "category": cat, "lat_deg": lat, "lon_deg": lon}
        )
        gt_rows.append(gt)
        keep = np.isclose(t % 1.0, 0.0) | np.isclose(t % 1.0, 1.0)
        az, _, dist = _GEOD.inv(
            ego["lon_deg"].to_numpy()[keep],
            ego["lat_deg"].to_numpy()[keep],
            np.asarray(lon)[keep],
            np.asarray(lat)[keep],
        )
        rel = np.radians(np.asarray(az) - EGO_BEARING_DEG)
        x = np.asarray(dist) * np.cos(rel)
        y_left = -np.asarray(dist) * np.sin(rel)
        yaw_left = -(((bearing - EGO_BEARING_DEG) + 180.0) % 360.0 - 180.0)
        sign = 1.0 if y_axis == "left" else -1.0
        length, width = DIMENSIONS[cat]
        ann_rows.append(
            pd.DataFrame(
                {
                    "t_s": t[keep],
                    "track_id": tid,
                    "category": cat,
                    "x_m": x,
                    "y_m": sign * y_left,
                    "yaw_deg": sign * yaw_left,
                    "length_m": length,
                    "width_m": width,
                }
            )
        )
    return ego, pd.concat(ann_rows, ignore_index=True), pd.concat(gt_rows, ignore_index=True)


def make_interaction(tmp_path: Path, **overrides: object) -> Path:
    """Write the tiny interaction (see module docstring) under tmp_path; returns its folder."""
    name = str(overrides.pop("name", "interaction"))
    meta: dict[str, object] = {
        "format": "vei.interaction/1",
        "id": "tiny",
        "source": "vei tests (synthetic)",
        "start_time_utc": START_TIME_UTC,
        "y_axis": "left",
        "annotation_rate_hz": 1.0,
        "notes": "synthetic test interaction",
    }
    tables = {}
    for key in ("ego", "annotations", "ground_truth"):
        if key in overrides:
            tables[key] = overrides.pop(key)
    for key, value in overrides.items():
        if value is DELETE:
            meta.pop(key, None)
        else:
            meta[key] = value
    y_axis = meta.get("y_axis", "left")
    ego, ann, gt = expected_tables("right" if y_axis == "right" else "left")
    ego = tables.get("ego", ego)
    ann = tables.get("annotations", ann)
    gt = tables.get("ground_truth", gt)
    folder = Path(tmp_path) / name
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "interaction.json").write_text(json.dumps(meta, indent=2) + "\n", encoding="utf-8")
    ego.to_csv(folder / "ego.csv", index=False)
    ann.to_csv(folder / "annotations.csv", index=False)
    if gt is not None:
        gt.to_csv(folder / "ground_truth.csv", index=False)
    return folder


#: make_curve_interaction: the rider's speed [m/s], curve radius [m], duration [s].
CURVE_SPEED_MPS = 4.0
CURVE_RADIUS_M = 15.0
CURVE_DURATION_S = 10.0
CURVE_ORIGIN = (48.7665, 11.4345)


def curve_xy(t_s: np.ndarray) -> np.ndarray:
    """Plane positions [N, 2] (m) of the curve rider at t_s [N]: a circle of CURVE_RADIUS_M
    from (0, 0) heading east, turning left, at CURVE_SPEED_MPS."""
    ang = CURVE_SPEED_MPS * np.asarray(t_s, dtype=np.float64) / CURVE_RADIUS_M
    return CURVE_RADIUS_M * np.column_stack([np.sin(ang), 1.0 - np.cos(ang)])


def make_curve_interaction(folder: Path, rate_hz: float, noise_m: float = 0.2, seed: int = 0):
    """Write and read a world-frame interaction (declared plane origin CURVE_ORIGIN) of
    CURVE_DURATION_S: the ego drives straight east at 5 m/s 20 m south of the curve; the
    rider (cyclist, track 7) rides :func:`curve_xy`, sampled at rate_hz [Hz] with Gaussian
    noise noise_m [m] per axis (seeded)."""
    from vei.geo.frame import LocalFrame
    from vei.io.interaction import read_interaction

    frame = LocalFrame(*CURVE_ORIGIN)
    folder = Path(folder)
    folder.mkdir(parents=True)
    meta = {
        "format": "vei.interaction/1",
        "id": f"curve_{rate_hz:g}hz",
        "source": "vei tests (synthetic)",
        "start_time_utc": "2021-02-09T12:40:35Z",
        "y_axis": "left",
        "frame": "world",
        "origin_lat_deg": CURVE_ORIGIN[0],
        "origin_lon_deg": CURVE_ORIGIN[1],
    }
    (folder / "interaction.json").write_text(json.dumps(meta), encoding="utf-8")
    te = np.round(np.arange(0.0, CURVE_DURATION_S + 1e-9, 0.1), 6)
    lat, lon = frame.to_latlon(-20.0 + 5.0 * te, np.full(te.size, -20.0))
    ego = {"t_s": te, "lat_deg": lat, "lon_deg": lon, "heading_deg": 90.0, "speed_mps": 5.0}
    pd.DataFrame(ego).to_csv(folder / "ego.csv", index=False)
    tk = np.round(np.arange(0.0, CURVE_DURATION_S + 1e-9, 1.0 / rate_hz), 6)
    xy = curve_xy(tk) + np.random.default_rng(seed).normal(0.0, noise_m, (tk.size, 2))
    lat, lon = frame.to_latlon(xy[:, 0], xy[:, 1])
    ann = {"t_s": tk, "track_id": "7", "category": "cyclist", "lat_deg": lat, "lon_deg": lon}
    pd.DataFrame(ann).to_csv(folder / "annotations.csv", index=False)
    return read_interaction(folder)
