"""Importer for the public TrafficMonitoring dataset (Ingolstadt, 2021-02-09).

The dataset's files (the car's INS, the roadside camera's tracks, the matching of the
two) are read and validated by :mod:`vei.datasets.trafficmonitoring_files`, whose public
names this module re-exports.

:func:`import_scenario` writes an interaction (format ``vei.interaction/1``) shaped like
the paper's data: ego GPS from the INS at 10 Hz, every e-scooter and cyclist track of the
camera as ego-relative annotations (x forward, y left) at ``rate_hz`` (1 FPS default), and
the camera's full-rate world tracks as ground truth.

Geodesy: camera positions are converted from UTM to WGS84 latitude/longitude first; the
ego-relative offsets are computed on the ellipsoid (geodesic inverse from the ego to the
object: distance and true azimuth, turned by the INS true heading). UTM offsets are never
rotated by a true heading: grid north differs from true north by the meridian convergence
(about 1.8 deg at Ingolstadt), 0.6 m of error at 20 m range.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd

from vei.datasets.trafficmonitoring_files import (
    CAMERA_CRS,
    CAMERA_FPS,
    CAMERA_TIMEZONE,
    CAR_DATA_DIR,
    CLASS_TO_CATEGORY,
    DATASET_COMMIT,
    DATASET_REPO,
    GPS_EPOCH,
    GPS_UTC_LEAP_S,
    INS_SUFFIX,
    MATCHING_DIR,
    MATCHING_SUFFIX,
    MEASUREMENTS_DIR,
    SECONDS_PER_WEEK,
    TRAJECTORIES_DIR,
    TRAJECTORIES_SUFFIX,
    InsRecord,
    Matching,
    _measurements,
    gps_to_utc,
    list_scenarios,
    majority_categories,
    majority_category,
    read_camera,
    read_camera_utm,
    read_ins,
    read_matching,
)
from vei.errors import InputError, NoRidersError
from vei.geo.frame import LocalFrame
from vei.types import Interaction, InteractionMeta

#: Public names of this module; those of the file layer are re-exported from
#: vei.datasets.trafficmonitoring_files, where they live.
__all__ = [
    "ANNOTATED_CATEGORIES",
    "CLASS_DIMENSIONS_M",
    "ROAD_USERS",
    "ANNOTATION_MAX_GAP_S",
    "CAMERA_CRS",
    "CAMERA_FPS",
    "CAMERA_TIMEZONE",
    "CAR_DATA_DIR",
    "CLASS_TO_CATEGORY",
    "DATASET_COMMIT",
    "DATASET_REPO",
    "EGO_RATE_HZ",
    "GPS_EPOCH",
    "GPS_UTC_LEAP_S",
    "INS_SUFFIX",
    "ImportSummary",
    "InsRecord",
    "MATCHING_DIR",
    "MATCHING_SUFFIX",
    "MEASUREMENTS_DIR",
    "Matching",
    "SECONDS_PER_WEEK",
    "TRAJECTORIES_DIR",
    "TRAJECTORIES_SUFFIX",
    "YAW_MIN_SPEED_MPS",
    "YAW_WINDOW_S",
    "ego_relative",
    "gps_to_utc",
    "import_scenario",
    "import_scenario_with_summary",
    "list_scenarios",
    "majority_categories",
    "majority_category",
    "read_camera",
    "read_camera_utm",
    "read_ins",
    "read_matching",
]

#: Rate of the ego GPS written to ego.csv [Hz] (decimated from the 100 Hz INS).
EGO_RATE_HZ = 10.0
#: An INS sample is used for a 10 Hz grid point if it lies this close to it [s].
_EGO_GRID_TOLERANCE_S = 0.005
#: An annotation uses the track's camera frame nearest to t = k / rate_hz if it lies this
#: close [s] (3 frames: the tracker misses single frames; the frame's own time is written).
ANNOTATION_MAX_GAP_S = 0.1
#: Half-window of the camera samples used to estimate a road user's direction [s].
YAW_WINDOW_S = 0.5
#: Below this speed [m/s] a road user "does not move" and gets no yaw (NaN).
YAW_MIN_SPEED_MPS = 0.5

#: Categories turned into annotations (the paper annotates e-scooters; cyclists are riders too).
ANNOTATED_CATEGORIES: tuple[str, ...] = ("escooter", "cyclist")
#: ``road_users`` choices of :func:`import_scenario`: 'riders' annotates ANNOTATED_CATEGORIES,
#: 'all' every track of a known category (vehicles and pedestrians too: occluders, others).
ROAD_USERS: tuple[str, ...] = ("riders", "all")
#: Footprints [m] (length, width) written for the camera's vehicle classes (its tracks
#: carry no size): a typical van (e.g. a Mercedes Sprinter, 5.9 x 2.0), a 12 m city bus and
#: a delivery truck at the EU width limit of 2.55 m (Directive 96/53/EC); other classes
#: keep vei's category defaults (vei.types.DEFAULT_DIMENSIONS_M).
CLASS_DIMENSIONS_M: dict[str, tuple[float, float]] = {
    "transporter": (5.9, 2.0),
    "car-transporter": (5.9, 2.0),
    "van": (5.9, 2.0),
    "bus": (12.0, 2.55),
    "truck": (10.0, 2.55),
}


# ----------------------------------------------------------------------------- geometry


def ego_relative(
    ego_lat_deg: np.ndarray,
    ego_lon_deg: np.ndarray,
    ego_heading_deg: np.ndarray,
    lat_deg: np.ndarray,
    lon_deg: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """World points -> ego-relative (x forward, y left) [m], on the ellipsoid.

    All inputs broadcast to one shape [N]: the ego's position [deg] and true heading [deg
    clockwise from north], the object's position [deg]. The geodesic inverse from ego to
    object gives distance d and true azimuth az; with r = az - heading:
    x = d cos r, y_left = -d sin r. This is the exact inverse of
    vei.geo.frame.LocalFrame.ego_relative_to_world.
    """
    from pyproj import Geod

    a = np.broadcast_arrays(
        *(
            np.asarray(v, dtype=np.float64)
            for v in (ego_lat_deg, ego_lon_deg, ego_heading_deg, lat_deg, lon_deg)
        )
    )
    az, _, dist = Geod(ellps="WGS84").inv(a[1], a[0], a[4], a[3])
    rel = np.radians(np.asarray(az) - a[2])
    d = np.asarray(dist)
    return d * np.cos(rel), -d * np.sin(rel)


def _wrap180(deg: np.ndarray) -> np.ndarray:
    return (np.asarray(deg) + 180.0) % 360.0 - 180.0


def _track_bearing_deg(track: pd.DataFrame, t_s: np.ndarray, frame: LocalFrame) -> np.ndarray:
    """True bearing [deg] of a road user's motion at t_s ([K]), NaN where it does not move.

    Velocity from a least-squares line through the camera samples within +-YAW_WINDOW_S,
    fitted in the local tmerc plane ``frame``; the plane direction is turned into a true
    bearing with the exact meridian-convergence correction of LocalFrame.yaw_to_bearing.
    """
    tt = track["t_s"].to_numpy()
    x, y = frame.to_xy(track["lat_deg"].to_numpy(), track["lon_deg"].to_numpy())
    yaw = np.full(len(t_s), np.nan)
    at = np.zeros(len(t_s), dtype=np.int64)
    for k, t in enumerate(t_s):
        sel = np.abs(tt - t) <= YAW_WINDOW_S + 1e-9
        at[k] = int(np.argmin(np.abs(tt - t)))
        if sel.sum() < 3 or np.ptp(tt[sel]) < YAW_WINDOW_S:
            continue
        tc = tt[sel] - tt[sel].mean()
        vx = float(np.dot(tc, x[sel] - x[sel].mean()) / np.dot(tc, tc))
        vy = float(np.dot(tc, y[sel] - y[sel].mean()) / np.dot(tc, tc))
        if math.hypot(vx, vy) >= YAW_MIN_SPEED_MPS:
            yaw[k] = math.atan2(vy, vx)
    out = np.full(len(t_s), np.nan)
    ok = np.isfinite(yaw)
    if ok.any():
        out[ok] = frame.yaw_to_bearing(yaw[ok], x[at[ok]], y[at[ok]])
    return out


# ----------------------------------------------------------------------------- importer


#: Median distance [m] between the car's own camera track and its INS above which an import
#: warns: on the recordings of the dataset it is 0.2-0.42 m (docs/interaction-format.md);
#: well above that the video and the INS are out of sync or the camera's calibration is
#: off, and every rider's position inherits the error.
OWN_TRACK_WARN_M = 1.0


@dataclass(frozen=True)
class ImportSummary:
    """What :func:`import_scenario` did (for the CLI and the notes).

    Attributes:
        scenario, out: scenario name and interaction folder.
        ins_start_utc: time of t_s = 0 (first INS sample).
        video_start_utc: camera frame 0.
        video_offset_s: video_start - ins_start [s].
        ego_duration_s: span of the ego track [s].
        tracks: {category: number of annotated tracks}.
        annotations: number of annotation rows.
        own_track_median_m, own_track_p95_m: distance between the car's own camera track
            and its INS position at the camera frames inside the INS span [m].
        track_times: when each annotated track is seen, sorted by first_s:
            ({'track_id', 'category', 'first_s', 'last_s', 'n_annotations'}, ...) with
            first_s / last_s its first / last annotation [s since ins_start_utc].
    """

    scenario: str
    out: Path
    ins_start_utc: datetime
    video_start_utc: datetime
    video_offset_s: float
    ego_duration_s: float
    tracks: dict[str, int]
    annotations: int
    own_track_median_m: float | None
    own_track_p95_m: float | None
    track_times: tuple[dict, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        """What the user should check before trusting the import (may be empty)."""
        med = self.own_track_median_m
        if med is None or not med > OWN_TRACK_WARN_M:
            return ()
        return (
            f"the car's own camera track lies {med:.2f} m (median) from its INS, above "
            f"{OWN_TRACK_WARN_M:g} m (0.2-0.42 m on the dataset's recordings): the video and "
            "the INS are probably out of sync, or the camera calibration is off; every "
            "rider's world position inherits this error",
        )


def _trim_ins(ins: InsRecord, t_lo: float, t_hi: float) -> InsRecord:
    """The INS cut to [t_lo, t_hi] plus one 10 Hz step each side, re-zeroed at its first sample."""
    pad = 1.0 / EGO_RATE_HZ
    keep = (ins.t_s >= t_lo - pad - 1e-9) & (ins.t_s <= t_hi + pad + 1e-9)
    if keep.sum() < 2:
        raise InputError(
            f"the camera span [{t_lo:.2f}, {t_hi:.2f}] s does not overlap the INS record [0, {ins.t_s[-1]:.2f}] s",
            path=ins.path,
        )
    t0 = float(ins.t_s[keep][0])
    start = ins.start_utc + timedelta(seconds=t0)
    shift = (start - ins.start_utc).total_seconds()
    return InsRecord(
        start_utc=start,
        t_s=np.round(ins.t_s[keep] - shift, 6),
        lat_deg=ins.lat_deg[keep],
        lon_deg=ins.lon_deg[keep],
        heading_deg=ins.heading_deg[keep],
        speed_mps=ins.speed_mps[keep],
        path=ins.path,
    )


def _ego_10hz(ins: InsRecord) -> pd.DataFrame:
    grid = np.arange(0.0, ins.t_s[-1] + 1e-9, 1.0 / EGO_RATE_HZ)
    idx = np.clip(np.searchsorted(ins.t_s, grid), 1, len(ins.t_s) - 1)
    idx = np.where(np.abs(ins.t_s[idx - 1] - grid) <= np.abs(ins.t_s[idx] - grid), idx - 1, idx)
    keep = np.abs(ins.t_s[idx] - grid) <= _EGO_GRID_TOLERANCE_S
    idx = np.unique(idx[keep])
    return pd.DataFrame(
        {
            "t_s": ins.t_s[idx],
            "lat_deg": ins.lat_deg[idx],
            "lon_deg": ins.lon_deg[idx],
            "heading_deg": ins.heading_deg[idx],
            "speed_mps": ins.speed_mps[idx],
        }
    )


def _sample_track(track: pd.DataFrame, rate_hz: float, t_end: float) -> pd.DataFrame:
    """Camera frames of one track nearest to the grid k / rate_hz (within
    ANNOTATION_MAX_GAP_S, as the tracker misses frames), inside [0, t_end]."""
    tt = track["t_s"].to_numpy()
    lo, hi = max(tt[0], 0.0), min(tt[-1], t_end)
    if hi < lo:
        return track.iloc[:0]
    grid = np.arange(math.ceil(lo * rate_hz - 1e-9), math.floor(hi * rate_hz + 1e-9) + 1) / rate_hz
    if grid.size == 0:
        return track.iloc[:0]
    idx = (
        np.clip(np.searchsorted(tt, grid), 1, len(tt) - 1)
        if len(tt) > 1
        else np.zeros(grid.size, int)
    )
    if len(tt) > 1:
        idx = np.where(np.abs(tt[idx - 1] - grid) <= np.abs(tt[idx] - grid), idx - 1, idx)
    tol = min(ANNOTATION_MAX_GAP_S, 0.5 / rate_hz)
    ok = (np.abs(tt[idx] - grid) <= tol + 1e-9) & (tt[idx] >= 0.0) & (tt[idx] <= t_end)
    return track.iloc[np.unique(idx[ok])]


def import_scenario(
    root: str | Path,
    scenario: str,
    out: str | Path,
    *,
    rate_hz: float = 1.0,
    include_ego_track: bool = False,
    full_ins: bool = False,
    road_users: str = "riders",
) -> Path:
    """Import one TrafficMonitoring scenario as an interaction folder; returns ``out``.

    Writes (atomically, format ``vei.interaction/1``):

    - ego.csv: the INS decimated to 10 Hz (real samples, no interpolation), cut to the
      camera's span unless ``full_ins``: t_s [s since the first sample kept, which is
      start_time_utc = GPS week/tow - 18 s], lat_deg, lon_deg, heading_deg (true, clockwise from north),
      speed_mps (horizontal, from the north/east velocity);
    - annotations.csv: every camera track whose majority category is escooter or cyclist,
      at its camera frames nearest to t = k / rate_hz (within ANNOTATION_MAX_GAP_S; the
      frame's own time is written) inside the INS span, ego-relative
      (x forward, y left, ``y_axis = left``) from the INS pose at the frame's time;
      yaw_deg = motion direction relative to the ego heading (positive left; NaN where
      the road user moves slower than YAW_MIN_SPEED_MPS); length/width unknown (empty);
      the car's own camera track is left out (unless ``include_ego_track``: then it is
      annotated as category 'vehicle', a check of time sync and geodesy);
    - ground_truth.csv: the same tracks at the full 30 fps, lat/lon, over their whole
      camera span (it may extend past the INS span).

    Args:
        root: dataset root (the folder holding data/measurements).
        scenario: scenario name (see :func:`list_scenarios`).
        out: interaction folder to write (replaced if it exists).
        rate_hz: annotation rate [Hz], > 0 and <= 30.
        include_ego_track: also annotate the car's own camera track (diagnostics).
        full_ins: keep the whole INS record; by default the ego track is cut to the span
            the camera covers (plus one 10 Hz step each side), like the paper's clips.
        road_users: 'riders' (default: e-scooters and cyclists, the paper's annotations)
            or 'all' (also vehicles and pedestrians, e.g. the stopped cars that hide a
            rider; vehicles of the classes in CLASS_DIMENSIONS_M get those footprints).
    Raises:
        InputError: missing files, unknown scenario, malformed data.
    """
    return import_scenario_with_summary(
        root,
        scenario,
        out,
        rate_hz=rate_hz,
        include_ego_track=include_ego_track,
        full_ins=full_ins,
        road_users=road_users,
    ).out


def import_scenario_with_summary(
    root: str | Path,
    scenario: str,
    out: str | Path,
    *,
    rate_hz: float = 1.0,
    include_ego_track: bool = False,
    full_ins: bool = False,
    road_users: str = "riders",
) -> ImportSummary:
    """:func:`import_scenario`, returning an :class:`ImportSummary` of what was written."""
    from vei.io.interaction import write_interaction

    if not (
        isinstance(rate_hz, int | float) and math.isfinite(rate_hz) and 0 < rate_hz <= CAMERA_FPS
    ):
        raise InputError(
            f"rate_hz must be in (0, {CAMERA_FPS:g}] Hz, got {rate_hz!r}", field="rate_hz"
        )
    if road_users not in ROAD_USERS:
        raise InputError(
            f"road_users must be one of {', '.join(ROAD_USERS)}, got {road_users!r}",
            field="road_users",
        )
    meas = _measurements(root)
    matching = read_matching(root, scenario)
    ins = read_ins(meas / "car_data" / matching.ins_file_name)
    video_offset_s = (matching.start_utc - ins.start_utc).total_seconds()
    camera = read_camera(
        meas / "videos" / "trajectory_output" / f"{scenario}{TRAJECTORIES_SUFFIX}", video_offset_s
    )
    if not full_ins:
        ins = _trim_ins(ins, float(camera["t_s"].min()), float(camera["t_s"].max()))
        video_offset_s = (matching.start_utc - ins.start_utc).total_seconds()
        camera = camera.assign(
            t_s=np.round(video_offset_s + camera["frame_id"].to_numpy() / CAMERA_FPS, 9)
        )
    t_end = float(ins.t_s[-1])
    plane = LocalFrame(float(ins.lat_deg[0]), float(ins.lon_deg[0]))

    categories = majority_categories(camera)
    own = matching.relevant_track_id
    if own not in categories.index:
        raise InputError(
            f"relevant_track_id {own} (the car's own track) does not occur in the camera data",
            path=matching.path,
            row=1,
            field="relevant_track_id",
        )
    kept = ANNOTATED_CATEGORIES if road_users == "riders" else tuple(CLASS_TO_CATEGORY.values())
    wanted = [tid for tid, cat in categories.items() if cat in kept and tid != own]
    if include_ego_track:
        wanted.append(own)

    ann_parts, gt_parts = [], []
    for tid in wanted:
        cat = "vehicle" if tid == own else str(categories[tid])
        track = camera[camera["track_id"] == tid]
        gt_parts.append(
            track.assign(category=cat)[["t_s", "track_id", "category", "lat_deg", "lon_deg"]]
        )
        samples = _sample_track(track, rate_hz, t_end)
        if samples.empty:
            continue
        ts = samples["t_s"].to_numpy()
        elat, elon, ehead = ins.at(ts)
        x, y = ego_relative(
            elat, elon, ehead, samples["lat_deg"].to_numpy(), samples["lon_deg"].to_numpy()
        )
        yaw_left = -_wrap180(_track_bearing_deg(track, ts, plane) - ehead)
        size = (np.nan, np.nan)
        if cat == "vehicle" and tid != own:
            size = CLASS_DIMENSIONS_M.get(str(track["class_id"].mode().iloc[0]), size)
        ann_parts.append(
            pd.DataFrame(
                {
                    "t_s": ts,
                    "track_id": tid,
                    "category": cat,
                    "x_m": x,
                    "y_m": y,
                    "yaw_deg": yaw_left,
                    "length_m": size[0],
                    "width_m": size[1],
                }
            )
        )
    riders_seen = any(bool(part["category"].isin(ANNOTATED_CATEGORIES).any()) for part in ann_parts)
    if not riders_seen:
        raise NoRidersError(
            f"scenario {scenario!r} has no e-scooter or cyclist seen by the camera while the car's INS records "
            f"([0, {t_end:.1f}] s after {ins.start_utc.isoformat()})",
            path=matching.path,
        )
    annotations = pd.concat(ann_parts, ignore_index=True)
    ground_truth = pd.concat(gt_parts, ignore_index=True)

    own_track = camera[camera["track_id"] == own]
    inside = own_track[(own_track["t_s"] >= 0.0) & (own_track["t_s"] <= t_end)]
    median_m = p95_m = None
    if not inside.empty:
        elat, elon, _ = ins.at(inside["t_s"].to_numpy())
        from pyproj import Geod

        _, _, dist = Geod(ellps="WGS84").inv(
            elon, elat, inside["lon_deg"].to_numpy(), inside["lat_deg"].to_numpy()
        )
        median_m, p95_m = float(np.median(dist)), float(np.percentile(dist, 95))

    counts = (
        annotations[annotations["track_id"] != own]
        .groupby("category")["track_id"]
        .nunique()
        .to_dict()
    )
    ego = _ego_10hz(ins)
    notes = (
        f"Imported by vei from {DATASET_REPO}@{DATASET_COMMIT[:7]} (Apache-2.0), scenario {scenario}. "
        f"Ego: INS {matching.ins_file_name} (100 Hz) decimated to {EGO_RATE_HZ:g} Hz"
        + ("" if full_ins else ", cut to the span the camera covers")
        + f"; t_s = 0 at its first sample (UTC = GPS week/tow - {GPS_UTC_LEAP_S} leap s). "
        f"Camera: 30 fps, frame k at "
        f"{matching.start_local.strftime('%Y-%m-%d %H:%M:%S.%f')[:-4]} CET + k/30 s = "
        f"{video_offset_s:+.3f} s after t_s = 0; UTM 32N -> WGS84. Annotations: "
        + ("e-scooter and cyclist" if road_users == "riders" else "every road user's")
        + f" tracks (majority label), {rate_hz:g} Hz, ego-relative via geodesic inverse and the INS true "
        f"heading; car's own camera track {own} "
        + ("annotated as 'vehicle' (diagnostics)" if include_ego_track else "left out")
        + ". "
        + (
            f"Own camera track vs INS: median {median_m:.2f} m, p95 {p95_m:.2f} m. "
            if median_m is not None
            else "Own camera track not inside the INS span. "
        )
        + "Ground truth: the same tracks at 30 fps."
    )
    interaction = Interaction(
        meta=InteractionMeta(
            id=scenario,
            source=f"TrafficMonitoring dataset ({DATASET_REPO}), Ingolstadt roadside camera + instrumented car INS",
            start_time_utc=ins.start_utc,
            y_axis="left",
            annotation_rate_hz=float(rate_hz),
            notes=notes,
        ),
        ego=ego,
        annotations=annotations,
        ground_truth=ground_truth,
    )
    folder = write_interaction(interaction, out)
    return ImportSummary(
        scenario=scenario,
        out=folder,
        ins_start_utc=ins.start_utc,
        video_start_utc=matching.start_utc,
        video_offset_s=video_offset_s,
        ego_duration_s=float(ego["t_s"].iloc[-1] - ego["t_s"].iloc[0]),
        tracks={c: int(counts.get(c, 0)) for c in ANNOTATED_CATEGORIES},
        annotations=int((annotations["track_id"] != own).sum()),
        own_track_median_m=median_m,
        own_track_p95_m=p95_m,
        track_times=tuple(
            {
                "track_id": str(tid),
                "category": str(g["category"].iloc[0]),
                "first_s": float(g["t_s"].min()),
                "last_s": float(g["t_s"].max()),
                "n_annotations": len(g),
            }
            for tid, g in sorted(
                annotations.groupby("track_id"), key=lambda kv: (kv[1]["t_s"].min(), kv[0])
            )
        ),
    )
