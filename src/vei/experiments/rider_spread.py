"""How far apart do real riders' routes lie? Bounds of a plausible rider-path perturbation.

``vei casestudy --make-critical timing+path`` moves the rider's recorded path by a lateral
offset or a rotation about its closest approach to the ego's path. Which sizes are
plausible? We measure it on the roadside-camera tracks of the TrafficMonitoring data
(every e-scooter and cyclist the camera tracked, 30 frames/s, UTM 32N):

- each rider track (majority category escooter / cyclist, at least ``min_length_m`` long)
  is collapsed at standstill and resampled every ``step_m`` along its arc, heading from
  neighbouring points;
- for every pair of riders of the same recording, the *overlap* is the set of points of
  rider i whose nearest point on rider j lies within ``overlap_radius_m`` and whose
  heading differs by at most ``max_heading_diff_deg`` (the same street, the same way);
  an overlap of at least ``min_overlap_m`` gives the pair's route distance (median
  distance over the overlap) and route angle (median |heading difference|);
- a rider's *nearest route* is the other rider with the smallest route distance; its
  distance and angle are one sample each.

The quantiles of those samples say how far a real rider's route lies from another real
rider's route on the same stretch: an offset (rotation) up to the ``quantile`` of the
distances (angles) puts the rider on a route that real riders take. The shipped bounds
(:data:`vei.experiments.critical_path.PLAUSIBLE_OFFSET_M` and ``PLAUSIBLE_ROTATION_DEG``)
are this measurement on the nine shared recordings; a test recomputes it.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.spatial import cKDTree

from vei.datasets.trafficmonitoring import CLASS_TO_CATEGORY

RIDER_LABELS = ("escooter", "cyclist")


@dataclass(frozen=True)
class RouteSpread:
    """Result of :func:`measure_route_spread`.

    Attributes:
        n_riders: riders with a nearest route. n_files: recordings read.
        distances_m: [n] nearest-route distances [m]. angles_deg: [n] their angles [deg].
        quantile: the quantile reported. offset_m, rotation_deg: the quantiles.
    """

    n_riders: int
    n_files: int
    distances_m: np.ndarray
    angles_deg: np.ndarray
    quantile: float
    offset_m: float
    rotation_deg: float


def _resample(xy: np.ndarray, step_m: float) -> np.ndarray:
    keep = [0]
    for i in range(1, len(xy)):
        if np.hypot(*(xy[i] - xy[keep[-1]])) >= step_m:
            keep.append(i)
    k = xy[keep]
    if len(k) < 2:
        return k
    s = np.concatenate([[0.0], np.cumsum(np.hypot(*np.diff(k, axis=0).T))])
    g = np.arange(0.0, s[-1] + 1e-9, step_m)
    return np.column_stack([np.interp(g, s, k[:, 0]), np.interp(g, s, k[:, 1])])


def rider_paths(
    csv: Path, *, step_m: float = 0.5, min_length_m: float = 10.0, heading_window_m: float = 4.0
) -> list[np.ndarray]:
    """Rider paths of one camera trajectory file: [n_i, 3] arrays (x_m, y_m, heading_rad),
    heading = direction of the chord of ``heading_window_m`` centred on the point."""
    df = pd.read_csv(
        csv,
        usecols=[
            "frame_id",
            "class_id",
            "track_id",
            "coordinate_world_x_opt",
            "coordinate_world_y_opt",
        ],
    )
    df["cat"] = df["class_id"].astype(str).str.strip().map(CLASS_TO_CATEGORY)
    out = []
    for _, tr in df.sort_values(["track_id", "frame_id"]).groupby("track_id"):
        cats = tr["cat"].dropna()
        if cats.empty or cats.value_counts().idxmax() not in RIDER_LABELS:
            continue
        xy = tr[["coordinate_world_x_opt", "coordinate_world_y_opt"]].to_numpy(dtype=float)
        xy = xy[np.isfinite(xy).all(axis=1)]
        if len(xy) < 2:
            continue
        p = _resample(xy, step_m)
        if len(p) * step_m < min_length_m:
            continue
        h = max(1, int(round(0.5 * heading_window_m / step_m)))
        lo = np.clip(np.arange(len(p)) - h, 0, len(p) - 1)
        hi = np.clip(np.arange(len(p)) + h, 0, len(p) - 1)
        d = p[hi] - p[lo]
        out.append(np.column_stack([p, np.arctan2(d[:, 1], d[:, 0])]))
    return out


def measure_route_spread(
    trajectory_files: list[Path],
    *,
    step_m: float = 0.5,
    min_length_m: float = 10.0,
    overlap_radius_m: float = 8.0,
    max_heading_diff_deg: float = 45.0,
    min_overlap_m: float = 10.0,
    quantile: float = 0.9,
) -> RouteSpread:
    """Nearest-route distances and angles of real riders (see the module doc).

    Args:
        trajectory_files: camera trajectory CSVs (``*_trajectories.csv``).
        step_m, min_length_m, overlap_radius_m, max_heading_diff_deg, min_overlap_m:
            the rule's parameters [m, deg]. quantile: reported quantile in (0, 1).
    Returns:
        RouteSpread.
    """
    dists, angles = [], []
    need = int(np.ceil(min_overlap_m / step_m))
    max_dh = np.deg2rad(max_heading_diff_deg)
    for f in trajectory_files:
        paths = rider_paths(Path(f), step_m=step_m, min_length_m=min_length_m)
        trees = [cKDTree(p[:, :2]) for p in paths]
        for i, pi in enumerate(paths):
            best = None
            for j, pj in enumerate(paths):
                if i == j:
                    continue
                d, k = trees[j].query(pi[:, :2])
                dh = np.abs((pi[:, 2] - pj[k, 2] + np.pi) % (2 * np.pi) - np.pi)
                ov = (d <= overlap_radius_m) & (dh <= max_dh)
                if ov.sum() < need:
                    continue
                cand = (float(np.median(d[ov])), float(np.rad2deg(np.median(dh[ov]))))
                if best is None or cand[0] < best[0]:
                    best = cand
            if best is not None:
                dists.append(best[0])
                angles.append(best[1])
    da, aa = np.asarray(dists), np.asarray(angles)
    return RouteSpread(
        n_riders=int(da.size),
        n_files=len(trajectory_files),
        distances_m=da,
        angles_deg=aa,
        quantile=float(quantile),
        offset_m=float(np.quantile(da, quantile)) if da.size else float("nan"),
        rotation_deg=float(np.quantile(aa, quantile)) if aa.size else float("nan"),
    )
