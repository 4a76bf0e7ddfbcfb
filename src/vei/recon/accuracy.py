"""Reconstruction accuracy and calibration against ground truth.

For each reconstructed track with a ground-truth track (the camera's 30 fps world tracks):

* ``rmse_m`` (plus p95 and max): Euclidean error [m] against the raw ground truth, at the
  ground-truth times inside the track's keyframe span (the interpolant evaluated at exactly
  those times);
* ``rmse_sg_m``: the same against the ground truth denoised by a Savitzky-Golay filter over
  1 s (:func:`denoise_ground_truth`: window 31 samples at 30 fps, polynomial order 2, gaps
  up to 0.5 s filled linearly, the rule of :mod:`vei.calibrate.tracks`). The
  camera tracks jitter by decimetres around a smooth path; this is the error with most of
  that jitter removed.
* for probabilistic methods (an interpolant with ``std(t)``): ``coverage_sg`` is the share
  of denoised ground-truth samples inside the 95 % region of the posterior of the true
  position (2-D ellipse, squared Mahalanobis distance <= chi2(2 dof, 0.95) = 5.991), and
  ``coverage_raw`` the share of raw ground-truth samples inside the 95 % region for a new
  noisy observation (posterior variance + keyframe noise variance: the raw track carries
  the same camera jitter as the keyframes).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pandas as pd
from scipy.signal import savgol_filter

from vei.geo.frame import LocalFrame
from vei.recon.calibration import CHI2_2DOF_95
from vei.types import RIDER_CATEGORIES

FloatArray = npt.NDArray[np.float64]

__all__ = ["CHI2_2DOF_95", "denoise_ground_truth", "evaluate", "track_errors"]
#: Savitzky-Golay denoising of the ground truth: window [s] and polynomial order.
SG_WINDOW_S = 1.0
SG_POLYORDER = 2
#: Ground-truth gaps up to this [s] are filled linearly before filtering; longer ones
#: split the track (the rule of vei.calibrate.tracks).
SG_MAX_GAP_S = 0.5


def denoise_ground_truth(
    t_s: npt.ArrayLike,
    xy_m: npt.ArrayLike,
    window_s: float = SG_WINDOW_S,
    polyorder: int = SG_POLYORDER,
) -> FloatArray:
    """Savitzky-Golay smoothed ground truth, at the ground truth's own sample times.

    The rule of :mod:`vei.calibrate.tracks`: the samples are laid on their uniform grid
    (median step, 30 fps), gaps up to SG_MAX_GAP_S are filled by linear interpolation,
    longer gaps split the track into runs; each run is filtered (window_s, odd number of
    samples; a run shorter than the window gets the longest odd window it holds, at least
    polyorder + 3 samples, else stays raw), then read back at the original samples.

    Args:
        t_s: [N] increasing sample times [s].
        xy_m: [N, 2] positions [m].
        window_s: filter window [s]; polyorder: polynomial order.
    Returns:
        [N, 2] smoothed positions [m].
    """
    t = np.asarray(t_s, dtype=np.float64).ravel()
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    out = xy.copy()
    if t.size < 2:
        return out
    dt = float(np.median(np.diff(t)))
    if dt <= 0:
        return out
    win = int(round(window_s / dt))
    win += 1 - win % 2  # odd
    cuts = np.flatnonzero(np.diff(t) > SG_MAX_GAP_S) + 1
    for a, b in zip(np.r_[0, cuts], np.r_[cuts, t.size], strict=True):
        k = np.round((t[a:b] - t[a]) / dt).astype(np.int64)
        n = int(k[-1]) + 1
        w = min(win, n - (1 - n % 2))
        if w < polyorder + 3:
            continue
        grid = np.arange(n) * dt + t[a]
        filled = np.column_stack([np.interp(grid, t[a:b], xy[a:b, j]) for j in (0, 1)])
        sm = savgol_filter(filled, w, polyorder, axis=0, mode="interp")
        out[a:b] = np.column_stack([np.interp(t[a:b], grid, sm[:, j]) for j in (0, 1)])
    return out


def track_errors(
    est_xy_m: FloatArray,
    gt_xy_m: FloatArray,
    gt_sg_xy_m: FloatArray,
    std_m: FloatArray | None = None,
    noise_m: float | None = None,
) -> dict:
    """Error figures of one track.

    Args:
        est_xy_m: [N, 2] reconstruction at the ground-truth times [m].
        gt_xy_m: [N, 2] raw ground truth; gt_sg_xy_m: [N, 2] denoised ground truth [m].
        std_m: [N] posterior position standard deviation per axis [m] (probabilistic
            methods), else None.
        noise_m: keyframe noise sigma [m] of the method (for coverage_raw).
    Returns:
        dict n_samples, rmse_m, p95_m, max_m, rmse_sg_m, and with std_m: coverage_sg,
        coverage_raw (shares in [0, 1]), mean_std_m.
    """
    err = np.hypot(*(est_xy_m - gt_xy_m).T)
    err_sg = np.hypot(*(est_xy_m - gt_sg_xy_m).T)
    out = {
        "n_samples": int(err.size),
        "rmse_m": float(np.sqrt(np.mean(err**2))),
        "p95_m": float(np.percentile(err, 95)),
        "max_m": float(err.max()),
        "rmse_sg_m": float(np.sqrt(np.mean(err_sg**2))),
    }
    if std_m is not None:
        var = np.asarray(std_m, dtype=np.float64) ** 2
        var_raw = var + (noise_m or 0.0) ** 2
        out["coverage_sg"] = float(np.mean(err_sg**2 / np.maximum(var, 1e-12) <= CHI2_2DOF_95))
        out["coverage_raw"] = float(np.mean(err**2 / np.maximum(var_raw, 1e-12) <= CHI2_2DOF_95))
        out["mean_std_m"] = float(np.mean(np.sqrt(var)))
    return out


def _prime(ids: pd.DataFrame, by_track: dict, interpolants: dict) -> None:
    """Batch the posteriors of probabilistic interpolants at their ground-truth times."""
    from vei.recon.smoother import prime

    items, queries = [], []
    for agent_id, track_id, _ in ids.itertuples(index=False):
        ip = interpolants.get(agent_id)
        if ip is None or track_id not in by_track or not hasattr(ip, "std"):
            continue
        t = np.sort(by_track[track_id]["t_s"].to_numpy(dtype=np.float64))
        t = t[(t >= ip.t_start_s - 1e-9) & (t <= ip.t_end_s + 1e-9)]
        items.append(ip)
        queries.append(t)
    prime(items, queries)


def _keyframe_error(
    keyframes: pd.DataFrame, agent_id: str, t_gt: FloatArray, gsg: FloatArray
) -> float:
    """RMSE [m] of a track's keyframes against the denoised ground truth (linearly
    interpolated to the keyframe times): the noise the keyframes carry, a floor that
    interpolating through them cannot beat without smoothing."""
    kf = keyframes[keyframes["agent_id"] == agent_id]
    tk = kf["t_s"].to_numpy(dtype=np.float64)
    ok = (tk >= t_gt[0]) & (tk <= t_gt[-1])
    if not ok.any():
        return float("nan")
    ref = np.column_stack([np.interp(tk[ok], t_gt, gsg[:, j]) for j in (0, 1)])
    d = kf[["x_m", "y_m"]].to_numpy(dtype=np.float64)[ok] - ref
    return float(np.sqrt(np.mean(np.sum(d**2, axis=1))))


def evaluate(
    ground_truth: pd.DataFrame, frame: LocalFrame, keyframes: pd.DataFrame, interpolants: dict
) -> dict:
    """Per-track reconstruction error and calibration against world ground truth.

    Args:
        ground_truth: t_s, track_id, category, lat_deg, lon_deg (full rate).
        frame: the scenario plane.
        keyframes: the scenario keyframes (agent_id, source_track_id, category).
        interpolants: agent_id -> interpolant (position(t) [N, 2]; probabilistic ones also
            std(t) [N] and noise.noise_m).
    Returns:
        {'tracks': [{agent_id, source_track_id, category, **track_errors,
        keyframe_rmse_sg_m (the keyframes' own RMSE against the denoised ground truth)}],
        'riders':
        {n_tracks, mean_rmse_m, max_rmse_m, max_error_m, p95_m, mean_rmse_sg_m and, for
        probabilistic methods, coverage_sg / coverage_raw over all rider samples} over
        e-scooters and cyclists (None when there are none)}. Errors are Euclidean
        distances [m] in the plane at the ground-truth times inside each track's span.
    """
    gt = ground_truth.copy()
    gt["track_id"] = gt["track_id"].astype(str)
    gx, gy = frame.to_xy(
        gt["lat_deg"].to_numpy(dtype=np.float64), gt["lon_deg"].to_numpy(dtype=np.float64)
    )
    gt["x_m"], gt["y_m"] = gx, gy
    by_track = dict(list(gt.groupby("track_id", sort=False)))
    ids = keyframes.drop_duplicates("agent_id")[["agent_id", "source_track_id", "category"]]
    _prime(ids, by_track, interpolants)
    rows = []
    rider_err, rider_cov = [], []
    for agent_id, track_id, category in ids.itertuples(index=False):
        if agent_id not in interpolants or track_id not in by_track:
            continue
        interp = interpolants[agent_id]
        g = by_track[track_id].sort_values("t_s")
        t = g["t_s"].to_numpy(dtype=np.float64)
        gxy = g[["x_m", "y_m"]].to_numpy(dtype=np.float64)
        gsg = denoise_ground_truth(t, gxy)
        inside = (t >= interp.t_start_s - 1e-9) & (t <= interp.t_end_s + 1e-9)
        if not inside.any():
            continue
        est = interp.position(t[inside])
        std = interp.std(t[inside]) if hasattr(interp, "std") else None
        noise = interp.noise.noise_m if std is not None else None
        e = track_errors(est, gxy[inside], gsg[inside], std, noise)
        e["keyframe_rmse_sg_m"] = _keyframe_error(keyframes, agent_id, t, gsg)
        rows.append({"agent_id": agent_id, "source_track_id": track_id, "category": category, **e})
        if category in RIDER_CATEGORIES:
            rider_err.append(np.hypot(*(est - gxy[inside]).T))
            if std is not None:
                rider_cov.append((e["coverage_sg"], e["coverage_raw"], e["n_samples"]))
    riders = [r for r in rows if r["category"] in RIDER_CATEGORIES]
    summary = None
    if riders:
        allerr = np.concatenate(rider_err)
        summary = {
            "n_tracks": len(riders),
            "mean_rmse_m": float(np.mean([r["rmse_m"] for r in riders])),
            "max_rmse_m": float(max(r["rmse_m"] for r in riders)),
            "p95_m": float(np.percentile(allerr, 95)),
            "max_error_m": float(allerr.max()),
            "mean_rmse_sg_m": float(np.mean([r["rmse_sg_m"] for r in riders])),
        }
        if rider_cov:
            c = np.array(rider_cov)
            summary["coverage_sg"] = float(np.sum(c[:, 0] * c[:, 2]) / np.sum(c[:, 2]))
            summary["coverage_raw"] = float(np.sum(c[:, 1] * c[:, 2]) / np.sum(c[:, 2]))
    return {"tracks": rows, "riders": summary}
