"""Does a turn-aware motion model help? The coordinated-turn smoother of
:mod:`benchmarks.recon_research.turn` against the constant-velocity ``kalman`` smoother on recordings with
ground truth (used by ``benchmarks/bench_recon_accuracy.py``; docs/reconstruction.md).

Protocol, all against the 1 s Savitzky-Golay denoised ground truth of
:func:`benchmarks.recon_research.compare.rider_truth`:

* 'kalman': the shipped constant-velocity smoother, (sigma, q) by maximum likelihood on the
  recording's own keyframes (the noise stored in the scenario).
* 'turn': the coordinated-turn smoother, (sigma, q, q_omega) by maximum likelihood on the
  keyframes of the *other* recordings (leave one recording out; its own keyframes alone
  are too few for three parameters), positions straight from the smoothed state at the
  ground-truth times.
* 'best of both (hindsight)': per ground-truth sample the smaller of the two errors. No
  method that mixes the two models' estimates by a weight between 0 and 1 per sample (an
  interacting-multiple-model smoother of the two models, say) can beat the per-sample
  best convex combination, also reported ('best mix (hindsight)').

Coverage: the held-out 95 % coverage of each model with its std factor fitted on the other
recordings (:func:`vei.recon.calibration.leave_one_out`).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from benchmarks.recon_research import turn
from benchmarks.recon_research.compare import END_S, TURN_RATE_RADPS, rider_truth
from vei.recon import calibration
from vei.recon.samples import scenario_noise
from vei.recon.smoother import posterior
from vei.types import Interaction, Scenario


def _keyframe_tracks(sc: Scenario) -> list[tuple[np.ndarray, np.ndarray]]:
    return [
        (g["t_s"].to_numpy(np.float64), g[["x_m", "y_m"]].to_numpy(np.float64))
        for _, g in sc.keyframes.groupby("agent_id", sort=True)
    ]


def _best_mix_sq(e1: np.ndarray, e2: np.ndarray) -> np.ndarray:
    """Per sample min over a in [0, 1] of |a e1 + (1 - a) e2|^2 (e1, e2 [N, 2] errors)."""
    d = e1 - e2
    dd = np.sum(d * d, axis=1)
    a = np.clip(-np.sum(e2 * d, axis=1) / np.maximum(dd, 1e-18), 0.0, 1.0)
    m = e2 + a[:, None] * d
    return np.sum(m * m, axis=1)


def turn_table(
    scenarios: Mapping[str, Scenario], interactions: Mapping[str, Interaction]
) -> tuple[pd.DataFrame, pd.DataFrame, dict]:
    """Constant velocity vs coordinated turn, per rider track and pooled.

    Args:
        scenarios: name -> scenario reconstructed with ``interp='kalman'`` (>= 2 recordings).
        interactions: name -> interaction (ground truth).
    Returns:
        (per_track, summary, noise): per_track has recording, agent_id, n_keyframes and
        rmse_sg_m / rmse_m (vs denoised / raw) for 'kalman' and 'turn', and the hindsight
        bounds best_of_both_sg_m, best_mix_sg_m; summary one row per method with the mean
        RMSE over tracks vs denoised and raw, the pooled RMSE in turns and elsewhere (truth
        turning faster than TURN_RATE_RADPS at > 1 m/s) and at the ends (within END_S of
        the first / last keyframe), and the held-out / model 95 % coverage (NaN for the
        hindsight bounds); noise maps recording -> the TurnNoise used on it.
    """
    all_tracks = {n: _keyframe_tracks(sc) for n, sc in scenarios.items()}
    rows, pooled, d2 = [], {"kalman": [], "turn": [], "best of both": [], "best mix": []}, {}
    masks: dict[str, list[np.ndarray]] = {"turning": [], "ends": []}
    noises = {}
    for name, sc in scenarios.items():
        others = [tr for n, trs in all_tracks.items() if n != name for tr in trs if len(tr[0]) >= 3]
        nz = turn.estimate_turn_noise(others)
        noises[name] = nz
        cvn = scenario_noise(sc)
        d2[name] = {"kalman": [], "turn": []}
        for tr in rider_truth(sc, interactions[name].ground_truth):
            tk, xyk, t, sg, raw = (
                tr["t_key_s"],
                tr["xy_key_m"],
                tr["t_s"],
                tr["sg_xy_m"],
                tr["raw_xy_m"],
            )
            cv = posterior([(tk, xyk)], [t], cvn.noise_m, cvn.accel_psd_m2ps3)[0]
            tu = np.unique(t)
            ct = turn.smooth_turn(tk, xyk, nz, tu)
            idx = np.searchsorted(tu, t)
            xy_ct, std_ct = ct.xy_m[idx], ct.std_m[idx]
            e_cv, e_ct = cv.xy_m - sg, xy_ct - sg
            sq = {
                "kalman": np.sum(e_cv**2, 1),
                "turn": np.sum(e_ct**2, 1),
                "best of both": np.minimum(np.sum(e_cv**2, 1), np.sum(e_ct**2, 1)),
                "best mix": _best_mix_sq(e_cv, e_ct),
            }
            for k, v in sq.items():
                pooled[k].append(v)
            d2[name]["kalman"].append(sq["kalman"] / np.maximum(cv.std_m**2, 1e-12))
            d2[name]["turn"].append(sq["turn"] / np.maximum(std_ct**2, 1e-12))
            v = np.gradient(sg, t, axis=0) if t.size >= 3 else np.zeros_like(sg)
            a = np.gradient(v, t, axis=0) if t.size >= 3 else np.zeros_like(sg)
            speed = np.hypot(v[:, 0], v[:, 1])
            rate = np.abs(v[:, 0] * a[:, 1] - v[:, 1] * a[:, 0]) / np.maximum(speed, 1e-9) ** 2
            masks["turning"].append((rate > TURN_RATE_RADPS) & (speed > 1.0))
            masks["ends"].append((t - tk[0] <= END_S) | (tk[-1] - t <= END_S))
            rows.append(
                {
                    "recording": name,
                    "agent_id": tr["agent_id"],
                    "n_keyframes": int(tk.size),
                    "kalman_rmse_sg_m": float(np.sqrt(sq["kalman"].mean())),
                    "turn_rmse_sg_m": float(np.sqrt(sq["turn"].mean())),
                    "best_of_both_sg_m": float(np.sqrt(sq["best of both"].mean())),
                    "best_mix_sg_m": float(np.sqrt(sq["best mix"].mean())),
                    "kalman_rmse_m": float(np.sqrt(np.mean(np.sum((cv.xy_m - raw) ** 2, 1)))),
                    "turn_rmse_m": float(np.sqrt(np.mean(np.sum((xy_ct - raw) ** 2, 1)))),
                }
            )
    per_track = pd.DataFrame(rows)
    turning = np.concatenate(masks["turning"])
    ends = np.concatenate(masks["ends"])
    cov = {
        k: calibration.leave_one_out({n: np.concatenate(v[k]) for n, v in d2.items() if v[k]})
        for k in ("kalman", "turn")
    }
    summary = []
    for k, col in (
        ("kalman", "kalman_rmse_sg_m"),
        ("turn", "turn_rmse_sg_m"),
        ("best of both", "best_of_both_sg_m"),
        ("best mix", "best_mix_sg_m"),
    ):
        e2 = np.concatenate(pooled[k])
        raw_col = {"kalman": "kalman_rmse_m", "turn": "turn_rmse_m"}.get(k)
        summary.append(
            {
                "method": k if k in cov else f"{k} (hindsight)",
                "mean_rmse_sg_m": per_track[col].mean(),
                "mean_rmse_m": per_track[raw_col].mean() if raw_col else np.nan,
                "rmse_turning_m": float(np.sqrt(e2[turning].mean())),
                "rmse_not_turning_m": float(np.sqrt(e2[~turning].mean())),
                "rmse_ends_m": float(np.sqrt(e2[ends].mean())),
                "coverage_model": cov[k]["coverage_model"] if k in cov else np.nan,
                "coverage_held_out": cov[k]["coverage_held_out"] if k in cov else np.nan,
            }
        )
    return per_track, pd.DataFrame(summary), noises
