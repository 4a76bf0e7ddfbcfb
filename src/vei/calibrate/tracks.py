"""Rider and vehicle tracks from the TrafficMonitoring roadside-camera trajectories.

Every road user the camera tracked (30 frames/s, UTM zone 32N easting / northing) is read
from ``<scenario>_trajectories.csv``; the category of a track is the majority of its
detector labels (:func:`vei.datasets.trafficmonitoring.majority_categories`). Positions
stay in UTM metres: the rider model only needs a local metric plane (the UTM scale error
near Ingolstadt is 4e-4, 0.4 mm per metre).

Processing of one track (the documented rule, constants below):

1. frames sorted; the track is split where the tracker lost it for more than
   ``MAX_GAP_S`` (0.5 s); shorter gaps are filled by linear interpolation on the 30 fps grid;
2. Savitzky-Golay smoothing over ``SMOOTH_WINDOW_S`` (1 s, 31 frames, polynomial order 2) of
   x and y, with its analytic first and second derivatives (velocity, acceleration): the
   camera positions jitter by 0.06-0.55 m, so raw finite differences are useless;
3. resampled (linear interpolation) on the engine grid ``k * dt_s`` (20 Hz);
4. a rider segment is kept when it lasts >= ``MIN_DURATION_S`` (3 s), travels >=
   ``MIN_PATH_M`` (5 m) and moves (smoothed speed > ``MOVING_MPS`` = 0.5 m/s) for >=
   ``MIN_MOVING_S`` (2 s): short tracks (tracker fragments), standing riders and
   jitter-only tracks are dropped.

Vehicles (majority label car, bus, truck, ...) get the same smoothing; their heading is
the direction of the smoothed velocity where they move (> 1 m/s), held before / after;
vehicles that never move (parked) are left out: riders pass parked cars closely all the
time, which is not the vehicle interaction the model's repulsion describes. The
instrumented car (``relevant_track_id`` of the matching file) is flagged.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.signal import savgol_filter

from vei.datasets.trafficmonitoring import (
    CAMERA_FPS,
    TRAJECTORIES_DIR,
    TRAJECTORIES_SUFFIX,
    list_scenarios,
    majority_categories,
    read_camera_utm,
    read_matching,
)

FloatArray = npt.NDArray[np.float64]

#: Rider categories that are calibrated (vei categories).
RIDER_CATEGORIES: tuple[str, ...] = ("escooter", "cyclist")
#: A gap in a track longer than this [s] splits it into segments.
MAX_GAP_S = 0.5
#: Savitzky-Golay window [s] (31 frames at 30 fps) and polynomial order.
SMOOTH_WINDOW_S = 1.0
SMOOTH_ORDER = 2
#: Segment filter: duration [s], path length [m], moving time [s], moving speed [m/s].
MIN_DURATION_S = 3.0
MIN_PATH_M = 5.0
MIN_MOVING_S = 2.0
MOVING_MPS = 0.5
#: A vehicle's heading comes from its velocity above this speed [m/s].
VEHICLE_MOVING_MPS = 1.0
#: Footprints [m] (length, width) by raw detector label; others use the car's.
VEHICLE_DIMENSIONS_M: dict[str, tuple[float, float]] = {
    "car": (4.7, 1.85),
    "transporter": (5.5, 2.0),
    "van": (5.5, 2.0),
    "bus": (12.0, 2.55),
    "truck": (8.0, 2.5),
    "motorcycle": (2.2, 0.8),
}


@dataclass(frozen=True)
class RiderTrack:
    """One smoothed rider segment on the engine grid.

    Attributes:
        scenario: scenario name. track_id: camera track id (``<id>`` or ``<id>#<segment>``).
        category: 'escooter' or 'cyclist'.
        t_s: [N] times since the video start [s] (multiples of dt_s).
        x_m, y_m: [N] smoothed UTM easting / northing [m].
        vx_mps, vy_mps: [N] smoothed velocity [m/s]. ax_mps2, ay_mps2: [N] acceleration.
    """

    scenario: str
    track_id: str
    category: str
    t_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    vx_mps: FloatArray
    vy_mps: FloatArray
    ax_mps2: FloatArray
    ay_mps2: FloatArray

    @property
    def speed_mps(self) -> FloatArray:
        """[N] smoothed speed [m/s]."""
        return np.hypot(self.vx_mps, self.vy_mps)

    @property
    def duration_s(self) -> float:
        """Length of the segment in time [s]."""
        return float(self.t_s[-1] - self.t_s[0])

    @property
    def key(self) -> str:
        """Unique name ``<scenario>/<track_id>``."""
        return f"{self.scenario}/{self.track_id}"

    def median_moving_speed_mps(self) -> float:
        """Median smoothed speed over the samples above MOVING_MPS [m/s]."""
        sp = self.speed_mps
        mv = sp[sp > MOVING_MPS]
        return float(np.median(mv)) if mv.size else 0.0


@dataclass(frozen=True)
class VehicleTracks:
    """The moving vehicles of one scenario on the scenario's engine grid ``k * dt_s``.

    Attributes:
        dt_s: grid step [s]. ids: [V] track ids. ego_index: index of the instrumented car
            (-1 if it is not among them).
        x_m, y_m, yaw_rad: [T, V] centre and heading (held where not active).
        active: [T, V] bool, tracked at that step. length_m, width_m: [V] footprints [m].
    """

    dt_s: float
    ids: tuple[str, ...]
    ego_index: int
    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    active: npt.NDArray[np.bool_]
    length_m: FloatArray
    width_m: FloatArray


@dataclass(frozen=True)
class SceneTracks:
    """Rider segments and vehicles of one scenario.

    Attributes:
        scenario: name. riders: kept rider segments. vehicles: the moving vehicles.
        dropped: {track key: reason} for rider tracks left out by the filter.
    """

    scenario: str
    riders: tuple[RiderTrack, ...]
    vehicles: VehicleTracks
    dropped: dict[str, str]


def _segments(frames: npt.NDArray[np.int64]) -> list[tuple[int, int]]:
    """Index ranges [a, b) of runs of frames without a gap longer than MAX_GAP_S."""
    gap = np.diff(frames) > MAX_GAP_S * CAMERA_FPS
    cuts = np.concatenate([[0], np.flatnonzero(gap) + 1, [frames.size]])
    return [(int(a), int(b)) for a, b in zip(cuts[:-1], cuts[1:], strict=True)]


def smooth_segment(
    frames: npt.NDArray[np.int64], x: FloatArray, y: FloatArray, dt_s: float
) -> tuple[FloatArray, ...] | None:
    """Savitzky-Golay smoothing of one gap-free segment, resampled on the grid ``k * dt_s``.

    Args:
        frames: [n] camera frame numbers (increasing, gaps <= MAX_GAP_S). x, y: [n] [m].
        dt_s: output grid step [s].
    Returns:
        (t_s, x_m, y_m, vx_mps, vy_mps, ax_mps2, ay_mps2), each [N], or None when the
        segment is shorter than the smoothing window.
    """
    full = np.arange(frames[0], frames[-1] + 1)
    win = int(round(SMOOTH_WINDOW_S * CAMERA_FPS)) | 1
    if full.size < win:
        return None
    xi = np.interp(full, frames, x)
    yi = np.interp(full, frames, y)
    h = 1.0 / CAMERA_FPS
    sm = [
        savgol_filter(v, win, SMOOTH_ORDER, deriv=d, delta=h, mode="interp")
        for v in (xi, yi)
        for d in (0, 1, 2)
    ]
    t_cam = full / CAMERA_FPS
    k0 = int(np.ceil(t_cam[0] / dt_s - 1e-9))
    k1 = int(np.floor(t_cam[-1] / dt_s + 1e-9))
    if k1 <= k0:
        return None
    t = np.arange(k0, k1 + 1) * dt_s
    xs, vxs, axs, ys, vys, ays = (np.interp(t, t_cam, v) for v in sm)
    return t, xs, ys, vxs, vys, axs, ays


def _keep_reason(
    t: FloatArray, x: FloatArray, y: FloatArray, sp: FloatArray, dt: float
) -> str | None:
    dur = float(t[-1] - t[0])
    if dur < MIN_DURATION_S:
        return f"shorter than {MIN_DURATION_S:g} s ({dur:.1f} s)"
    path = float(np.sum(np.hypot(np.diff(x), np.diff(y))))
    if path < MIN_PATH_M:
        return f"travels less than {MIN_PATH_M:g} m ({path:.1f} m)"
    moving = float(np.sum(sp > MOVING_MPS) * dt)
    if moving < MIN_MOVING_S:
        return f"moves less than {MIN_MOVING_S:g} s ({moving:.1f} s)"
    return None


def _vehicles(
    df: pd.DataFrame, ids: list[str], ego_id: str, n_steps: int, dt: float
) -> VehicleTracks:
    cols: list[
        tuple[str, FloatArray, FloatArray, FloatArray, npt.NDArray[np.bool_], float, float]
    ] = []
    for tid in ids:
        tr = df[df["track_id"] == tid]
        frames = tr["frame_id"].to_numpy()
        xs = tr["x"].to_numpy()
        ys = tr["y"].to_numpy()
        label = tr["class_id"].value_counts().index[0]
        length, width = VEHICLE_DIMENSIONS_M.get(label, VEHICLE_DIMENSIONS_M["car"])
        X, Y, YAW = (np.zeros(n_steps) for _ in range(3))
        act = np.zeros(n_steps, dtype=bool)
        moved = False
        for a, b in _segments(frames):
            sm = smooth_segment(frames[a:b], xs[a:b], ys[a:b], dt)
            if sm is None:
                continue
            t, x, y, vx, vy, _, _ = sm
            k = np.rint(t / dt).astype(np.intp)
            ok = k < n_steps
            k, x, y, vx, vy = k[ok], x[ok], y[ok], vx[ok], vy[ok]
            sp = np.hypot(vx, vy)
            mv = sp > VEHICLE_MOVING_MPS
            if not mv.any():
                continue
            moved = True
            yaw = np.where(mv, np.arctan2(vy, vx), np.nan)
            yaw = pd.Series(yaw).ffill().bfill().to_numpy()
            X[k], Y[k], YAW[k], act[k] = x, y, yaw, True
        if moved:
            cols.append((tid, X, Y, YAW, act, length, width))
    v = len(cols)
    stack = (
        (lambda j: np.stack([c[j] for c in cols], axis=1))
        if v
        else (lambda j: np.zeros((n_steps, 0)))
    )
    names = tuple(c[0] for c in cols)
    return VehicleTracks(
        dt_s=dt,
        ids=names,
        ego_index=names.index(ego_id) if ego_id in names else -1,
        x_m=stack(1),
        y_m=stack(2),
        yaw_rad=stack(3),
        active=stack(4).astype(bool) if v else np.zeros((n_steps, 0), dtype=bool),
        length_m=np.array([c[5] for c in cols], dtype=np.float64),
        width_m=np.array([c[6] for c in cols], dtype=np.float64),
    )


def load_scene(root: str | Path, scenario: str, *, dt_s: float = 0.05) -> SceneTracks:
    """Rider segments (kept by the filter rule) and moving vehicles of one scenario.

    Args:
        root: dataset root (the folder that holds ``data/measurements``).
        scenario: scenario name (``<name>_matching.csv`` and ``<name>_trajectories.csv``).
        dt_s: engine grid step [s].
    Returns:
        The SceneTracks (possibly with no riders).
    """
    matching = read_matching(root, scenario)
    path = Path(root) / TRAJECTORIES_DIR / f"{scenario}{TRAJECTORIES_SUFFIX}"
    df = read_camera_utm(path).rename(columns={"x_m": "x", "y_m": "y"})
    cats = majority_categories(df)
    n_steps = int(np.floor(df["frame_id"].max() / CAMERA_FPS / dt_s)) + 1
    riders: list[RiderTrack] = []
    dropped: dict[str, str] = {}
    for tid, cat in cats.items():
        if cat not in RIDER_CATEGORIES:
            continue
        tr = df[df["track_id"] == tid]
        frames = tr["frame_id"].to_numpy()
        segs = _segments(frames)
        for j, (a, b) in enumerate(segs):
            name = str(tid) if len(segs) == 1 else f"{tid}#{j}"
            sm = smooth_segment(frames[a:b], tr["x"].to_numpy()[a:b], tr["y"].to_numpy()[a:b], dt_s)
            if sm is None:
                dropped[f"{scenario}/{name}"] = (
                    f"shorter than the {SMOOTH_WINDOW_S:g} s smoothing window"
                )
                continue
            t, x, y, vx, vy, ax, ay = sm
            why = _keep_reason(t, x, y, np.hypot(vx, vy), dt_s)
            if why is not None:
                dropped[f"{scenario}/{name}"] = why
                continue
            riders.append(RiderTrack(scenario, name, str(cat), t, x, y, vx, vy, ax, ay))
    veh_ids = [str(t) for t, c in cats.items() if c == "vehicle"]
    vehicles = _vehicles(df, veh_ids, matching.relevant_track_id, n_steps, dt_s)
    return SceneTracks(scenario, tuple(riders), vehicles, dropped)


def load_scenes(
    root: str | Path, scenarios: list[str] | None = None, *, dt_s: float = 0.05
) -> list[SceneTracks]:
    """:func:`load_scene` for every scenario of a dataset root (or the given ones), sorted."""
    names = scenarios if scenarios is not None else list_scenarios(root)
    return [load_scene(root, s, dt_s=dt_s) for s in names]
