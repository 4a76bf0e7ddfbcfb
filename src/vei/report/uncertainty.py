"""Bird's-eye view of a reconstruction's uncertainty: the primary rider's 95 % band.

Plain arrays in (no recon objects), matplotlib Figure out (Agg, no pyplot). Artists are
labelled for tests and users: ``'ego'`` (ego path), ``'<rider> mean'`` (posterior mean),
``'<rider> 95 % band'`` (the band, a filled polygon), ``'<rider> samples'`` (the first
sample path; the others have no label), ``'<rider> keyframes'``, ``'ground truth'``.

The band is the lateral 95 % interval of the position, mean +- 1.96 std along the path's
normal (the posterior is isotropic, so std is the same along and across the path); the
samples show the joint spread (paths drawn whole from the posterior).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Two-sided 95 % quantile of the standard normal.
Z95 = 1.959963984540054


def band_polygon(xy_m: FloatArray, std_m: FloatArray, z: float = Z95) -> FloatArray:
    """Closed polygon [2T, 2] of the band mean +- z * std along the path normal.

    Args:
        xy_m: [T, 2] mean path [m] (T >= 2); std_m: [T] standard deviation [m].
        z: half-width in standard deviations.
    Returns:
        vertices: the left edge forwards, then the right edge backwards [m]. Where the
        path stands still the normal of the nearest moving step is used.
    """
    d = np.gradient(xy_m, axis=0)
    norm = np.hypot(d[:, 0], d[:, 1])
    moving = norm > 1e-9
    if not moving.any():
        d = np.tile([1.0, 0.0], (xy_m.shape[0], 1))
        norm = np.ones(xy_m.shape[0])
    else:
        idx = np.flatnonzero(moving)
        nearest = idx[np.clip(np.searchsorted(idx, np.arange(d.shape[0])), 0, idx.size - 1)]
        d = np.where(moving[:, None], d, d[nearest])
        norm = np.where(moving, norm, norm[nearest])
    normal = np.column_stack([-d[:, 1], d[:, 0]]) / norm[:, None]
    half = (z * np.asarray(std_m, float))[:, None] * normal
    return np.vstack([xy_m + half, (xy_m - half)[::-1]])


def plot_uncertainty(
    *,
    agent_id: str,
    t_s: FloatArray,
    mean_xy_m: FloatArray,
    std_m: FloatArray,
    ego_xy_m: FloatArray | None = None,
    samples_xy_m: FloatArray | None = None,
    keyframes_xy_m: FloatArray | None = None,
    ground_truth_xy_m: FloatArray | None = None,
    title: str = "",
    margin_m: float = 10.0,
    ax=None,
):
    """Draw the rider's mean path, its 95 % band, sample paths, keyframes and ground truth.

    Args:
        agent_id: the rider's id (labels). t_s: [T] times [s] (for the caption only).
        mean_xy_m: [T, 2] posterior mean [m]; std_m: [T] standard deviation per axis [m].
        ego_xy_m: [M, 2] ego path [m] or None.
        samples_xy_m: [S, T, 2] posterior samples [m] or None (at most 50 are drawn).
        keyframes_xy_m: [K, 2] keyframes [m]; ground_truth_xy_m: [G, 2] ground truth [m].
        title: axes title. margin_m: view margin around the rider [m] (the ego path is
            clipped to that view).
        ax: Axes to draw into (a new Figure if None).
    Returns:
        The matplotlib Figure.
    """
    if ax is None:
        from matplotlib.figure import Figure

        fig = Figure(figsize=(8, 8))
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    from matplotlib.patches import Polygon

    if mean_xy_m.shape[0] >= 2:
        poly = band_polygon(mean_xy_m, std_m)
        ax.add_patch(
            Polygon(
                poly,
                closed=True,
                facecolor="tab:red",
                alpha=0.25,
                edgecolor="none",
                label=f"{agent_id} 95 % band",
            )
        )
    if samples_xy_m is not None:
        for i, s in enumerate(samples_xy_m[:50]):
            ax.plot(
                s[:, 0],
                s[:, 1],
                color="tab:red",
                lw=0.4,
                alpha=0.35,
                label=f"{agent_id} samples" if i == 0 else None,
            )
    ax.plot(mean_xy_m[:, 0], mean_xy_m[:, 1], color="tab:red", lw=2.0, label=f"{agent_id} mean")
    if keyframes_xy_m is not None:
        ax.plot(
            keyframes_xy_m[:, 0],
            keyframes_xy_m[:, 1],
            "o",
            color="black",
            ms=4,
            label=f"{agent_id} keyframes",
        )
    if ground_truth_xy_m is not None:
        ax.plot(
            ground_truth_xy_m[:, 0],
            ground_truth_xy_m[:, 1],
            ".",
            color="tab:gray",
            ms=1.5,
            label="ground truth",
        )
    lo = mean_xy_m.min(axis=0) - margin_m
    hi = mean_xy_m.max(axis=0) + margin_m
    if ego_xy_m is not None:
        inside = np.all((ego_xy_m >= lo) & (ego_xy_m <= hi), axis=1)
        e = np.where(inside[:, None], ego_xy_m, np.nan)
        ax.plot(e[:, 0], e[:, 1], color="tab:blue", lw=2.0, label="ego")
    ax.set_xlim(lo[0], hi[0])
    ax.set_ylim(lo[1], hi[1])
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east [m]")
    ax.set_ylabel("y north [m]")
    span = f"{t_s[0]:.1f}-{t_s[-1]:.1f} s" if len(t_s) else ""
    ax.set_title(
        title
        or f"{agent_id}: posterior mean and 95 % band "
        f"(std {np.mean(std_m):.2f} m mean, {np.max(std_m):.2f} m max; {span})"
    )
    ax.legend(loc="best", fontsize=8)
    ax.grid(True, lw=0.3)
    return fig
