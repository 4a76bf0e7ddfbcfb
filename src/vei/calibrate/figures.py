"""Model vs data: speed and acceleration distributions of the fitted riders.

The fitted model runs closed loop over the fit's windows (3 s from every moving sample
every 0.5 s, each track with its own fitted parameters, the recorded vehicles around it);
the distributions of its speed and |acceleration| are compared with the smoothed
recording's over the same steps (quantiles in the report, histograms in the figure).
Whole-track runs are not used for this: the model has no reason to stop (it does not see
traffic lights), so on stop-and-go tracks it reaches the end of the path early and stands
there, which says more about the missing signal than about the fitted dynamics.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.calibrate.fit import MASS_KG, SIGMA_M, TrackFit
from vei.calibrate.rollout import make_windows, pack_paths, rollout_sfm
from vei.calibrate.tracks import RiderTrack, SceneTracks
from vei.io.atomic import atomic_path

FloatArray = npt.NDArray[np.float64]
_Q = (0.05, 0.25, 0.5, 0.75, 0.95)


def simulate_tracks(
    tracks: Sequence[RiderTrack],
    fits: Mapping[str, TrackFit],
    scenes: Mapping[str, SceneTracks],
    a_veh_n: float,
    b_veh_per_m: float,
    *,
    horizon_s: float = 3.0,
    stride_s: float = 0.5,
) -> dict[str, dict[str, FloatArray]]:
    """Closed-loop runs of the fitted model over every window of every track.

    Args:
        tracks: rider tracks. fits: track key -> its TrackFit. scenes: scenario -> tracks.
        a_veh_n, b_veh_per_m: the vehicle repulsion used.
        horizon_s, stride_s: the windows (as in the fit).
    Returns:
        {track key: {"model_speed", "model_accel", "data_speed", "data_accel"}} (speed
        [m/s], |acceleration| [m/s^2] at every step of every window, model and the smoothed
        recording over the same steps) for every track with a fit and a window.
    """
    keep = [t for t in tracks if t.key in fits]
    out: dict[str, dict[str, FloatArray]] = {}
    if not keep:
        return out
    paths = pack_paths(keep)
    dt = float(keep[0].t_s[1] - keep[0].t_s[0])
    win = make_windows(keep, dict(scenes), paths, horizon_s, stride_s, dt)
    if win.size == 0:
        return out
    f = [fits[t.key] for t in keep]
    p = {
        "v0_mps": np.array([f[j].v0_mps for j in win.track]),
        "k_des_nspm": np.array([MASS_KG / f[j].tau_s for j in win.track]),
        "mass_kg": MASS_KG,
        "sigma_m": SIGMA_M,
        "lookahead_m": np.array([f[j].lookahead_m for j in win.track]),
        "a_veh_n": a_veh_n,
        "b_veh_per_m": b_veh_per_m,
        "max_speed_mps": np.array([f[j].max_speed_mps for j in win.track]),
        "max_accel_mps2": np.array([f[j].max_accel_mps2 for j in win.track]),
    }
    x, y = rollout_sfm(paths, win, p)
    vx, vy = np.diff(x, axis=1) / dt, np.diff(y, axis=1) / dt
    msp = np.hypot(vx, vy)  # [B, H] speed over each step
    macc = np.hypot(np.diff(vx, axis=1), np.diff(vy, axis=1)) / dt  # [B, H - 1]
    h = win.horizon_steps
    for j, tr in enumerate(keep):
        sel = np.flatnonzero(win.track == j)
        if sel.size == 0:
            continue
        idx = win.start[sel][:, None] + np.arange(1, h + 1)[None, :]
        dacc = np.hypot(tr.ax_mps2, tr.ay_mps2)
        out[tr.key] = {
            "model_speed": msp[sel].ravel(),
            "model_accel": macc[sel].ravel(),
            "data_speed": tr.speed_mps[idx].ravel(),
            "data_accel": dacc[idx[:, :-1]].ravel(),
        }
    return out


def distribution_summary(
    sims: Mapping[str, Mapping[str, FloatArray]], keys: Sequence[str]
) -> dict[str, Any]:
    """Quantiles (5/25/50/75/95 %) of speed and |acceleration|, model and data, pooled."""
    res: dict[str, Any] = {}
    for name in ("model_speed", "data_speed", "model_accel", "data_accel"):
        vals = [sims[k][name] for k in keys if k in sims]
        v = np.concatenate(vals) if vals else np.zeros(0)
        res[name] = {f"{q:g}": float(np.quantile(v, q)) for q in _Q} if v.size else {}
    return res


def plot_distributions(
    sims: Mapping[str, Mapping[str, FloatArray]],
    categories: Mapping[str, str],
    path: str | Path,
) -> Path:
    """Histograms of speed and |acceleration|, model vs data, one row per category.

    Args:
        sims: from :func:`simulate_tracks`. categories: track key -> category.
        path: PNG to write (atomically).
    Returns:
        The path written.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cats = sorted({categories[k] for k in sims})
    fig, axes = plt.subplots(
        max(len(cats), 1), 2, figsize=(10, 3.2 * max(len(cats), 1)), squeeze=False
    )
    for r, cat in enumerate(cats):
        keys = [k for k in sims if categories[k] == cat]
        for c, (what, unit, hi) in enumerate((("speed", "m/s", 8.0), ("accel", "m/s$^2$", 6.0))):
            ax = axes[r][c]
            bins = np.linspace(0.0, hi, 33)
            for src, color in (("data", "0.3"), ("model", "tab:blue")):
                v = np.concatenate([sims[k][f"{src}_{what}"] for k in keys])
                ax.hist(
                    np.clip(v, 0, hi),
                    bins=bins,
                    density=True,
                    histtype="step",
                    lw=1.8,
                    color=color,
                    label=src,
                )
            ax.set_xlabel(f"{'speed' if what == 'speed' else '|acceleration|'} [{unit}]")
            ax.set_title(f"{cat}: {len(keys)} tracks")
            ax.legend()
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)
    return Path(path)
