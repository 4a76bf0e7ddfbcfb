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


def rider_truth(scenario: Scenario, ground_truth: pd.DataFrame) -> list[dict]:
    """Per rider track of a scenario: its keyframes and its denoised ground truth.

    Args:
        scenario: a reconstructed scenario (keyframes and plane stored in it).
        ground_truth: the interaction's ground truth (t_s, track_id, lat_deg, lon_deg).
    Returns:
        [{agent_id, t_key_s [K], xy_key_m [K, 2], t_s [N], raw_xy_m [N, 2], sg_xy_m [N, 2]}]
        for rider tracks with >= 2 keyframes, the ground truth cut to the keyframe span
        (sg: the 1 s Savitzky-Golay denoising of the whole track, then cut).
    """
    frame = LocalFrame.from_proj_string(scenario.projection)
    gt = ground_truth.assign(track_id=ground_truth["track_id"].astype(str))
    by_track = dict(list(gt.groupby("track_id", sort=False)))
    out = []
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
        if inside.any():
            out.append(
                {
                    "agent_id": str(aid),
                    "t_key_s": tk,
                    "xy_key_m": kf[["x_m", "y_m"]].to_numpy(np.float64),
                    "t_s": np.clip(t[inside], tk[0], tk[-1]),
                    "raw_xy_m": xy[inside],
                    "sg_xy_m": sg[inside],
                }
            )
    return out


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
    out: dict[str, np.ndarray] = {}
    for tr in rider_truth(scenario, ground_truth):
        post = posterior(
            [(tr["t_key_s"], tr["xy_key_m"])],
            [tr["t_s"]],
            noise.noise_m,
            noise.accel_psd_m2ps3,
        )[0]
        e2 = np.sum((post.xy_m - tr["sg_xy_m"]) ** 2, axis=1)
        out[tr["agent_id"]] = e2 / np.maximum(post.std_m**2, 1e-12)
    return out


def floor_table(
    scenarios: Mapping[str, Scenario], interactions: Mapping[str, Interaction], dof: float = 4.0
) -> pd.DataFrame:
    """Where the error comes from, per recording and rider track (all vs the denoised
    ground truth, RMSE [m]): the keyframes themselves, the 1 FPS sampling alone
    (:func:`benchmarks.recon_research.floor.clean_interp_rmse`), the best smoothing parameter in hindsight
    (:func:`benchmarks.recon_research.floor.oracle_rmse`), and the Student-t smoother
    (:mod:`benchmarks.recon_research.robust`, nu = dof, fitted per recording on its keyframes).

    Args:
        scenarios: name -> reconstructed scenario; interactions: name -> interaction.
    Returns:
        DataFrame recording, agent_id, n_keyframes, keyframes_rmse_m, clean_interp_rmse_m,
        oracle_rmse_m, oracle_lam_s3, student_t_rmse_m, student_t_min_weight.
    """
    from benchmarks.recon_research.floor import clean_interp_rmse, oracle_rmse
    from benchmarks.recon_research.robust import fit_student_t, robust_positions

    rows = []
    for name, sc in scenarios.items():
        trs = rider_truth(sc, interactions[name].ground_truth)
        kf = sc.keyframes
        all_tracks = [
            (g["t_s"].to_numpy(np.float64), g[["x_m", "y_m"]].to_numpy(np.float64))
            for _, g in kf.groupby("agent_id", sort=True)
        ]
        order = [str(a) for a, _ in kf.groupby("agent_id", sort=True)]
        fit = fit_student_t(all_tracks, dof=dof)
        w_by = dict(zip(order, fit.weights, strict=True))
        for tr in trs:
            tk, xyk, t, sg = tr["t_key_s"], tr["xy_key_m"], tr["t_s"], tr["sg_xy_m"]
            at_k = np.column_stack([np.interp(tk, t, sg[:, j]) for j in (0, 1)])
            orc, lam = oracle_rmse(tk, xyk, t, sg)
            fit1 = type(fit)(fit.noise_m, fit.accel_psd_m2ps3, fit.dof, (w_by[tr["agent_id"]],))
            xy_t = robust_positions([(tk, xyk)], fit1, [t])[0][0]
            rows.append(
                {
                    "recording": name,
                    "agent_id": tr["agent_id"],
                    "n_keyframes": int(tk.size),
                    "keyframes_rmse_m": float(np.sqrt(np.mean(np.sum((xyk - at_k) ** 2, 1)))),
                    "clean_interp_rmse_m": clean_interp_rmse(tk, t, sg),
                    "oracle_rmse_m": orc,
                    "oracle_lam_s3": lam,
                    "student_t_rmse_m": float(np.sqrt(np.mean(np.sum((xy_t - sg) ** 2, 1)))),
                    "student_t_min_weight": float(w_by[tr["agent_id"]].min()),
                }
            )
    return pd.DataFrame(rows)


#: Error breakdown: at a keyframe within this [s]; a gap longer than this [s] between
#: keyframes; the ends: within this [s] of the first or last keyframe; turning above this
#: yaw rate [rad/s] (while faster than 1 m/s); stopped below this speed [m/s].
AT_KEYFRAME_S, LONG_GAP_S, END_S, TURN_RATE_RADPS, STOP_SPEED_MPS = 0.05, 1.5, 1.0, 0.3, 0.5


def error_breakdown(
    scenarios: Mapping[str, Scenario], interactions: Mapping[str, Interaction]
) -> pd.DataFrame:
    """Where the 'kalman' error against the denoised ground truth lies, pooled over every
    rider sample of every recording.

    Conditions (a sample can be in several): 'all'; 'at keyframe' (within AT_KEYFRAME_S of
    one); 'between keyframes' (the others, in gaps <= LONG_GAP_S); 'long gap' (inside a
    keyframe gap > LONG_GAP_S); 'ends' (within END_S of the first or last keyframe);
    'turning' (denoised truth turns faster than TURN_RATE_RADPS at > 1 m/s); 'stopped'
    (denoised truth slower than STOP_SPEED_MPS).

    Args:
        scenarios: name -> 'kalman' scenario; interactions: name -> interaction.
    Returns:
        DataFrame condition, n_samples, share_samples, rmse_m, share_sq_error (share of
        the pooled squared error).
    """
    err2, masks = (
        [],
        {
            k: []
            for k in ("at keyframe", "between keyframes", "long gap", "ends", "turning", "stopped")
        },
    )
    for name, sc in scenarios.items():
        noise = scenario_noise(sc)
        for tr in rider_truth(sc, interactions[name].ground_truth):
            tk, t, sg = tr["t_key_s"], tr["t_s"], tr["sg_xy_m"]
            post = posterior([(tk, tr["xy_key_m"])], [t], noise.noise_m, noise.accel_psd_m2ps3)[0]
            err2.append(np.sum((post.xy_m - sg) ** 2, axis=1))
            near = np.min(np.abs(t[:, None] - tk[None, :]), axis=1) <= AT_KEYFRAME_S
            j = np.clip(np.searchsorted(tk, t, side="right"), 1, tk.size - 1)
            long_gap = (tk[j] - tk[j - 1]) > LONG_GAP_S
            if t.size >= 3 and np.ptp(t) > 0:
                v = np.gradient(sg, t, axis=0)
                a = np.gradient(v, t, axis=0)
                speed = np.hypot(v[:, 0], v[:, 1])
                rate = np.abs(v[:, 0] * a[:, 1] - v[:, 1] * a[:, 0]) / np.maximum(speed, 1e-9) ** 2
            else:
                speed, rate = np.full(t.size, np.inf), np.zeros(t.size)
            masks["at keyframe"].append(near)
            masks["between keyframes"].append(~near & ~long_gap)
            masks["long gap"].append(long_gap & ~near)
            masks["ends"].append((t - tk[0] <= END_S) | (tk[-1] - t <= END_S))
            masks["turning"].append((rate > TURN_RATE_RADPS) & (speed > 1.0))
            masks["stopped"].append(speed < STOP_SPEED_MPS)
    e2 = np.concatenate(err2)
    rows = [("all", np.ones(e2.size, bool))] + [(k, np.concatenate(v)) for k, v in masks.items()]
    return pd.DataFrame(
        [
            {
                "condition": k,
                "n_samples": int(m.sum()),
                "share_samples": float(m.mean()),
                "rmse_m": float(np.sqrt(e2[m].mean())) if m.any() else np.nan,
                "share_sq_error": float(e2[m].sum() / e2.sum()),
            }
            for k, m in rows
        ]
    )


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
