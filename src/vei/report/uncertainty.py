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
    zoom_xy_m: FloatArray | None = None,
    zoom_half_m: float = 4.0,
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
        zoom_xy_m: [2] centre of an inset that magnifies +- zoom_half_m [m] around it (e.g.
            where the rider comes closest to the ego path), or None.
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
    ax.grid(True, lw=0.3)
    pts = np.vstack([mean_xy_m] + ([ego_xy_m] if ego_xy_m is not None else []))
    corners = _corners_by_emptiness(ax, pts)
    if zoom_xy_m is None:
        ax.legend(loc="best", fontsize=8)
    else:
        ax.legend(loc=_CORNERS[corners[1]], fontsize=8)
        _inset(
            ax,
            agent_id,
            mean_xy_m,
            std_m,
            ego_xy_m,
            samples_xy_m,
            keyframes_xy_m,
            ground_truth_xy_m,
            np.asarray(zoom_xy_m, float),
            zoom_half_m,
            corners[0],
        )
    return fig


#: Corners of the axes (lower-left of a 0.38 x 0.38 box, axes fraction) and legend places.
_CORNERS: dict[tuple[float, float], str] = {
    (0.02, 0.02): "lower left",
    (0.60, 0.02): "lower right",
    (0.02, 0.60): "upper left",
    (0.60, 0.60): "upper right",
}


def _corners_by_emptiness(ax, pts: FloatArray) -> list[tuple[float, float]]:
    """The corners of the view, those that the given points cross least first."""
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    u = (pts[:, 0] - x0) / (x1 - x0)
    v = (pts[:, 1] - y0) / (y1 - y0)

    def busy(c: tuple[float, float]) -> int:
        return int(np.sum((u >= c[0]) & (u <= c[0] + 0.38) & (v >= c[1]) & (v <= c[1] + 0.38)))

    return sorted(_CORNERS, key=busy)


def _inset(ax, agent_id, mean, std, ego, samples, keyframes, gt, centre, half, corner) -> None:
    """Magnified view (gid 'zoom') of the band around ``centre``."""
    from matplotlib.patches import Polygon

    cx, cy = corner
    ins = ax.inset_axes([cx, cy, 0.38, 0.38])
    ins.set_gid("zoom")
    if mean.shape[0] >= 2:
        ins.add_patch(
            Polygon(
                band_polygon(mean, std),
                closed=True,
                facecolor="tab:red",
                alpha=0.25,
                edgecolor="none",
            )
        )
    if samples is not None:
        for smp in samples[:50]:
            ins.plot(smp[:, 0], smp[:, 1], color="tab:red", lw=0.4, alpha=0.35)
    ins.plot(mean[:, 0], mean[:, 1], color="tab:red", lw=1.5)
    if keyframes is not None:
        ins.plot(keyframes[:, 0], keyframes[:, 1], "o", color="black", ms=3)
    if gt is not None:
        ins.plot(gt[:, 0], gt[:, 1], ".", color="tab:gray", ms=1.5)
    if ego is not None:
        ins.plot(ego[:, 0], ego[:, 1], color="tab:blue", lw=1.5)
    ins.set_xlim(centre[0] - half, centre[0] + half)
    ins.set_ylim(centre[1] - half, centre[1] + half)
    ins.set_aspect("equal")
    ins.tick_params(labelsize=6)
    ins.set_title(f"zoom +-{half:g} m", fontsize=7)


def sample_dependence(
    results, design_columns: list[str], sample_column: str = "reconstruction_sample"
) -> tuple[dict, object]:
    """How much a sweep's outcome depends on the reconstruction sample.

    Args:
        results: sweep results (pandas DataFrame) with ``sample_column``, the design
            columns, ``collision`` (bool) and ``min_gap_m``.
        design_columns: the swept parameters (a design point = one combination of them).
        sample_column: the reconstruction-sample column.
    Returns:
        (summary, per_point): per_point is a DataFrame, one row per design point, with
        n_samples, collision_share (share of samples that collide), min_gap_spread_m
        (max - min of the minimum gap over the samples [m]); summary counts the design
        points that always collide, never collide, and depend on the sample (0 < share < 1),
        with the median / max gap spread [m].
    """
    cols = [c for c in design_columns if c in results.columns]
    grouped = results.groupby(cols, sort=True) if cols else results.groupby(lambda _: 0)
    per_point = grouped.agg(
        n_samples=(sample_column, "nunique"),
        collision_share=("collision", "mean"),
        min_gap_spread_m=("min_gap_m", lambda g: float(np.nanmax(g) - np.nanmin(g))),
    ).reset_index()
    share = per_point["collision_share"].to_numpy(float)
    spread = per_point["min_gap_spread_m"].to_numpy(float)
    summary = {
        "n_design_points": int(len(per_point)),
        "n_samples": int(results[sample_column].nunique()),
        "always_collide": int(np.sum(share == 1.0)),
        "never_collide": int(np.sum(share == 0.0)),
        "sample_dependent": int(np.sum((share > 0.0) & (share < 1.0))),
        "median_min_gap_spread_m": float(np.nanmedian(spread)) if spread.size else None,
        "max_min_gap_spread_m": float(np.nanmax(spread)) if spread.size else None,
    }
    return summary, per_point


def _cell_edges(c: FloatArray) -> FloatArray:
    """[n + 1] cell edges around n increasing centres (midpoints; half a step outside)."""
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = 0.5 * (c[1:] + c[:-1])
    return np.r_[2 * c[0] - mid[0], mid, 2 * c[-1] - mid[-1]]


def share_edges(
    x_centres: FloatArray, y_centres: FloatArray, value: FloatArray, level: float = 0.5
) -> FloatArray:
    """Cell edges between neighbouring cells on opposite sides of ``level`` (a staircase
    boundary on the grid; NaN cells have none).

    Args:
        x_centres: [nx], y_centres: [ny] increasing cell centres; value: [ny, nx].
    Returns:
        [S, 2, 2] segments ((x0, y0), (x1, y1)) in x/y units.
    """
    xe, ye = _cell_edges(np.asarray(x_centres, float)), _cell_edges(np.asarray(y_centres, float))
    v = np.asarray(value, float)
    above = v >= level
    ok = np.isfinite(v)
    segs = []
    for i, j in zip(
        *np.nonzero((above[:, 1:] != above[:, :-1]) & ok[:, 1:] & ok[:, :-1]), strict=True
    ):
        segs.append(((xe[j + 1], ye[i]), (xe[j + 1], ye[i + 1])))
    for i, j in zip(*np.nonzero((above[1:] != above[:-1]) & ok[1:] & ok[:-1]), strict=True):
        segs.append(((xe[j], ye[i + 1]), (xe[j + 1], ye[i + 1])))
    return np.array(segs, dtype=float).reshape(-1, 2, 2)


#: Most cells per axis of the share map (issue 35.0: at most 400 cells whatever the design).
MAX_CELLS_PER_AXIS = 20


def _binned_share(per_point, x: str, y: str) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(x centres [Kx], y centres [Ky], mean collision share [Ky, Kx]) of the design points:
    one cell per distinct value up to MAX_CELLS_PER_AXIS per axis, beyond that that many
    equal cells over the values' span (NaN where a cell holds no design point)."""
    xs, ys = per_point[x].to_numpy(float), per_point[y].to_numpy(float)
    share = per_point["collision_share"].to_numpy(float)

    def axis(v: FloatArray) -> tuple[FloatArray, npt.NDArray[np.intp]]:
        u = np.unique(v)
        if u.size <= MAX_CELLS_PER_AXIS:
            return u, np.searchsorted(u, v)
        e = np.linspace(u[0], u[-1], MAX_CELLS_PER_AXIS + 1)
        idx = np.clip(np.searchsorted(e, v, side="right") - 1, 0, MAX_CELLS_PER_AXIS - 1)
        return 0.5 * (e[:-1] + e[1:]), idx

    xc, bi = axis(xs)
    yc, bj = axis(ys)
    flat = bj * xc.size + bi
    cnt = np.bincount(flat, minlength=xc.size * yc.size)
    tot = np.bincount(flat, weights=share, minlength=xc.size * yc.size)
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(cnt > 0, tot / np.maximum(cnt, 1), np.nan)
    return xc, yc, mean.reshape(yc.size, xc.size)


def write_sample_share_map(per_point, x: str, y: str, path, title: str = ""):
    """Heatmap of the share of reconstruction samples without collision per design point
    (x, y: two swept parameters; with more, the cells average over the others; beyond
    MAX_CELLS_PER_AXIS values per axis, equal cells of consecutive values). Cells
    strictly between 0 and 1 are design points whose outcome depends on where the rider
    really was; the black staircase separates cells where most samples collide from the
    others (:func:`share_edges` at 0.5). Written atomically; returns the path."""
    from vei.report.riskmap import write_risk_map

    xc, yc, share = _binned_share(per_point, x, y)
    value = 1.0 - share
    return write_risk_map(
        path,
        x_centres=xc,
        y_centres=yc,
        value=value,
        segments=share_edges(xc, yc, value),
        x_label=x,
        y_label=y,
        value_label="share of reconstruction samples without collision",
        title=title
        or "outcome over reconstruction samples: 1 = no sample collides, 0 = all collide",
    )
