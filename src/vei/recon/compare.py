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

from vei.recon.interpolate import INTERP_METHODS
from vei.recon.pipeline import ReconstructionConfig, reconstruct
from vei.types import RIDER_CATEGORIES, Interaction


def compare_methods(
    interactions: Mapping[str, Interaction], methods: Iterable[str] = INTERP_METHODS
) -> pd.DataFrame:
    """Per-track accuracy of each method on each recording.

    Args:
        interactions: name -> interaction with ground truth.
        methods: interpolation methods (INTERP_METHODS).
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
