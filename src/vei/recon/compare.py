"""Compare the interpolation methods on recordings with ground truth: one row per track.

Used by ``benchmarks/bench_recon_accuracy.py`` (the table of docs/reconstruction.md) and
its tests. Each method reconstructs the whole interaction (``reconstruct`` with
``interp=method``) and reports, per rider track, the figures of
:mod:`vei.recon.accuracy` (RMSE vs raw and vs 1 s Savitzky-Golay denoised ground truth;
95 % coverage for 'kalman').
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping

import numpy as np
import pandas as pd

from vei.geo.frame import LocalFrame
from vei.recon import calibration
from vei.recon.accuracy import denoise_ground_truth
from vei.recon.interpolate import INTERP_METHODS
from vei.recon.pipeline import ReconstructionConfig, reconstruct
from vei.recon.samples import scenario_noise
from vei.recon.smoother import posterior
from vei.types import RIDER_CATEGORIES, Interaction, Scenario


def compare_methods(
    interactions: Mapping[str, Interaction],
    methods: Iterable[str] = INTERP_METHODS,
    keep: dict[str, Scenario] | None = None,
) -> pd.DataFrame:
    """Per-track accuracy of each method on each recording.

    Args:
        interactions: name -> interaction with ground truth.
        methods: interpolation methods (INTERP_METHODS).
        keep: if given, receives name -> the 'kalman' scenario of each recording (for
            :func:`model_d2` without reconstructing again).
    Returns:
        DataFrame, one row per (recording, rider track, method): recording, agent_id,
        method, n_keyframes, n_samples, rmse_m, rmse_sg_m, keyframe_rmse_sg_m (the
        keyframes themselves vs the denoised ground truth), coverage_sg, coverage_raw,
        mean_std_m (NaN for non-probabilistic methods), noise_m, accel_psd_m2ps3 (the
        'kalman' estimate of the recording).
    """
    rows = []
    for name, inter in interactions.items():
        for method in methods:
            sc = reconstruct(inter, ReconstructionConfig(interp=method))
            if keep is not None and method == "kalman":
                keep[name] = sc
            rec = sc.extra["reconstruction"]
            n_kf = {t["agent_id"]: t["n_keyframes"] for t in rec["tracks"]}
            noise = rec.get("noise") or {}
            for tr in sc.extra.get("reconstruction_error", {}).get("tracks", []):
                if tr["category"] not in RIDER_CATEGORIES:
                    continue
                rows.append(
                    {
                        "recording": name,
                        "agent_id": tr["agent_id"],
                        "method": method,
                        "n_keyframes": n_kf.get(tr["agent_id"], 0),
                        "n_samples": tr["n_samples"],
                        "rmse_m": tr["rmse_m"],
                        "rmse_sg_m": tr["rmse_sg_m"],
                        "keyframe_rmse_sg_m": tr.get("keyframe_rmse_sg_m", np.nan),
                        "coverage_sg": tr.get("coverage_sg", np.nan),
                        "coverage_raw": tr.get("coverage_raw", np.nan),
                        "mean_std_m": tr.get("mean_std_m", np.nan),
                        "noise_m": noise.get("noise_m", np.nan),
                        "accel_psd_m2ps3": noise.get("accel_psd_m2ps3", np.nan),
                    }
                )
    return pd.DataFrame(rows)


def summarise(table: pd.DataFrame) -> pd.DataFrame:
    """Per method: tracks, mean / max track RMSE vs raw and vs denoised ground truth [m],
    and the pooled 95 % coverage (sample-weighted) where the method has one."""
    out = []
    for method, g in table.groupby("method", sort=False):
        w = g["n_samples"].to_numpy(float)
        cov_sg = g["coverage_sg"].to_numpy(float)
        cov_raw = g["coverage_raw"].to_numpy(float)
        out.append(
            {
                "method": method,
                "n_tracks": len(g),
                "mean_rmse_m": g["rmse_m"].mean(),
                "max_rmse_m": g["rmse_m"].max(),
                "mean_rmse_sg_m": g["rmse_sg_m"].mean(),
                "max_rmse_sg_m": g["rmse_sg_m"].max(),
                "mean_keyframe_rmse_sg_m": g["keyframe_rmse_sg_m"].mean(),
                "coverage_sg": float(np.sum(w * cov_sg) / w.sum())
                if np.isfinite(cov_sg).all()
                else np.nan,
                "coverage_raw": float(np.sum(w * cov_raw) / w.sum())
                if np.isfinite(cov_raw).all()
                else np.nan,
            }
        )
    return pd.DataFrame(out)


def model_d2(scenario: Scenario, ground_truth: pd.DataFrame) -> dict[str, np.ndarray]:
    """Squared Mahalanobis distances of the denoised ground truth under the *uncalibrated*
    rider posterior (std_inflation 1), per rider track: the input of
    :func:`vei.recon.calibration.fit_inflation` / ``leave_one_out``.

    Args:
        scenario: a scenario reconstructed with ``interp='kalman'`` (keyframes, plane and
            noise estimate stored in it).
        ground_truth: the interaction's ground truth (t_s, track_id, lat_deg, lon_deg).
    Returns:
        agent_id -> [N] d^2 = |posterior mean - denoised truth|^2 / std^2 [-] at the ground
        truth times inside the track's keyframe span (tracks with >= 2 keyframes).
    """
    noise = scenario_noise(scenario)
    frame = LocalFrame.from_proj_string(scenario.projection)
    gt = ground_truth.assign(track_id=ground_truth["track_id"].astype(str))
    by_track = dict(list(gt.groupby("track_id", sort=False)))
    out: dict[str, np.ndarray] = {}
    for aid, kf in scenario.keyframes.groupby("agent_id", sort=True):
        g = by_track.get(str(kf["source_track_id"].iloc[0]))
        if kf["category"].iloc[0] not in RIDER_CATEGORIES or g is None or len(kf) < 2:
            continue
        g = g.sort_values("t_s")
        t = g["t_s"].to_numpy(np.float64)
        xy = np.column_stack(frame.to_xy(g["lat_deg"].to_numpy(), g["lon_deg"].to_numpy()))
        sg = denoise_ground_truth(t, xy)
        tk = kf["t_s"].to_numpy(np.float64)
        inside = (t >= tk[0] - 1e-9) & (t <= tk[-1] + 1e-9)
        if not inside.any():
            continue
        post = posterior(
            [(tk, kf[["x_m", "y_m"]].to_numpy(np.float64))],
            [np.clip(t[inside], tk[0], tk[-1])],
            noise.noise_m,
            noise.accel_psd_m2ps3,
        )[0]
        e2 = np.sum((post.xy_m - sg[inside]) ** 2, axis=1)
        out[str(aid)] = e2 / np.maximum(post.std_m**2, 1e-12)
    return out


def leave_one_recording_out(
    scenarios: Mapping[str, Scenario], interactions: Mapping[str, Interaction]
) -> dict:
    """:func:`vei.recon.calibration.leave_one_out` over recordings: each recording's 95 %
    coverage with the std factor fitted on the other recordings only.

    Args:
        scenarios: name -> 'kalman' scenario; interactions: name -> interaction (ground truth).
    Returns:
        the leave_one_out dict (folds per recording, pooled held-out coverage, factor on all).
    """
    d2 = {}
    for name, sc in scenarios.items():
        per_track = model_d2(sc, interactions[name].ground_truth)
        if per_track:
            d2[name] = np.concatenate(list(per_track.values()))
    return calibration.leave_one_out(d2)
