"""Risk map: a safety-index heatmap over a parameter plane with the collision boundary drawn.

The function takes plain arrays (no engine, no sweep objects), so it draws both the
adaptive boundary search and binned sweep results. Matplotlib with the Agg backend.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np


def risk_map_figure(
    *,
    x_centres: np.ndarray,
    y_centres: np.ndarray,
    value: np.ndarray,
    segments: np.ndarray,
    sample_x: np.ndarray | None = None,
    sample_y: np.ndarray | None = None,
    sample_collided: np.ndarray | None = None,
    x_label: str = "x",
    y_label: str = "y",
    value_label: str = "safety index",
    title: str = "",
    vmin: float = 0.0,
    vmax: float = 1.0,
    cmap: str = "RdYlGn",
    flagged_x: np.ndarray | None = None,
    flagged_y: np.ndarray | None = None,
):
    """Build the risk-map figure.

    Args:
        x_centres: [Kx] heatmap cell centres along x; y_centres: [Ky] along y.
        value: [Ky, Kx] value per cell (e.g. safety index, NaN = no data, drawn blank).
        segments: [S, 2, 2] boundary segments in x/y units (drawn as one LineCollection,
            gid 'boundary').
        sample_x, sample_y, sample_collided: optional [N] evaluated points (drawn as
            markers: red crosses collide, gid 'collided'; white dots do not, gid 'safe').
        x_label, y_label, value_label, title: texts.
        vmin, vmax: colour scale of ``value``; cmap: its matplotlib colormap (default
            red-yellow-green, high = green; 'RdYlGn_r' where high is bad).
        flagged_x, flagged_y: optional [M] runs flagged ``seen_too_late`` (no planner
            could have reacted, vei.metrics.seen): left out of ``value`` by the caller and
            drawn here as grey plus signs (gid 'flagged').

    Returns:
        the matplotlib Figure (Agg canvas).
    """
    from matplotlib.collections import LineCollection
    from matplotlib.figure import Figure

    fig = Figure(figsize=(7.0, 5.2), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    xc, yc = np.asarray(x_centres, float), np.asarray(y_centres, float)
    mesh = ax.pcolormesh(
        _edges(xc),
        _edges(yc),
        np.ma.masked_invalid(np.asarray(value, float)),
        cmap=cmap,
        vmin=vmin,
        vmax=vmax,
        shading="flat",
    )
    mesh.set_gid("heatmap")
    fig.colorbar(mesh, ax=ax, label=value_label)
    if sample_x is not None and sample_y is not None and sample_collided is not None:
        col = np.asarray(sample_collided, bool)
        sx, sy = np.asarray(sample_x, float), np.asarray(sample_y, float)
        a = ax.scatter(
            sx[col], sy[col], marker="x", s=9, c="darkred", linewidths=0.7, label="collision"
        )
        a.set_gid("collided")
        b = ax.scatter(
            sx[~col], sy[~col], marker=".", s=6, c="white", edgecolors="none", label="no collision"
        )
        b.set_gid("safe")
    if flagged_x is not None and flagged_y is not None and len(flagged_x):
        f = ax.scatter(
            np.asarray(flagged_x, float), np.asarray(flagged_y, float), marker="+", s=14,
            c="dimgrey", linewidths=0.6, label="seen too late (not coloured)",
        )  # fmt: skip
        f.set_gid("flagged")
    seg = np.asarray(segments, float).reshape(-1, 2, 2)
    lc = LineCollection(seg, colors="black", linewidths=2.0, label="collision boundary")
    lc.set_gid("boundary")
    ax.add_collection(lc)
    ax.set_xlim(_edges(xc)[0], _edges(xc)[-1])
    ax.set_ylim(_edges(yc)[0], _edges(yc)[-1])
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    ax.set_title(title or f"risk map: {value_label}, collision boundary in black", fontsize=9)
    ax.legend(loc="upper right", fontsize=7, framealpha=0.8)
    fig.tight_layout()
    return fig


def write_risk_map(path: str | Path, **kwargs) -> Path:
    """Draw :func:`risk_map_figure` (same keyword arguments) and save it atomically (PNG)."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from vei.io.atomic import atomic_path

    fig = risk_map_figure(**kwargs)
    FigureCanvasAgg(fig)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png")
    return path


def _edges(centres: np.ndarray) -> np.ndarray:
    """[K + 1] cell edges around [K] increasing centres (half a spacing beyond the ends)."""
    c = np.asarray(centres, float)
    if c.size == 1:
        return np.array([c[0] - 0.5, c[0] + 0.5])
    mid = 0.5 * (c[:-1] + c[1:])
    return np.concatenate([[c[0] - (mid[0] - c[0])], mid, [c[-1] + (c[-1] - mid[-1])]])


#: Colour of the cells known to have P = 0 (the report's too: report.js PROB.zero).
ZERO_COLOUR = "#41ab5d"


def _zero_cmap():
    from matplotlib.colors import ListedColormap

    return ListedColormap([ZERO_COLOUR])


def write_probability_map(
    path: str | Path, *, grid: dict, x_label: str, y_label: str, title: str = ""
) -> Path:
    """A probability map (PNG, atomically): P(collision | cell) where it is known (its 95 %
    interval within the grid's limit; gid 'probability'), known P = 0 cells green
    (ZERO_COLOUR, gid 'known_zero'), the other cells hatched grey and labelled 'not
    known' (gid 'unknown'), each known cell annotated with its interval.

    Args:
        grid: :func:`vei.sweep.riskmap.probability_grid`'s result.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    from vei.io.atomic import atomic_path

    xc, yc = np.asarray(grid["x_centres"], float), np.asarray(grid["y_centres"], float)
    p, known = np.asarray(grid["p"], float), np.asarray(grid["known"], bool)
    fig = Figure(figsize=(7.0, 5.2), dpi=110)
    ax = fig.add_subplot(1, 1, 1)
    xe, ye = _edges(xc), _edges(yc)
    zero = known & (p == 0.0)
    mesh = ax.pcolormesh(xe, ye, np.ma.masked_where(~known | zero, p), cmap="Reds", vmin=0.0,
                         vmax=1.0, shading="flat")  # fmt: skip
    mesh.set_gid("probability")
    # known P = 0 in its own colour, far from the hatched grey of the cells not known and
    # from the white end of the red scale (issue 35)
    z = ax.pcolormesh(xe, ye, np.ma.masked_where(~zero, np.ones_like(p)), cmap=_zero_cmap(),
                      vmin=0.0, vmax=1.0, shading="flat")  # fmt: skip
    z.set_gid("known_zero")
    fig.colorbar(mesh, ax=ax, label="P(collision | cell)")
    unknown = np.where(known, np.nan, 1.0)
    hatch = ax.pcolor(xe, ye, np.ma.masked_invalid(unknown), cmap="Greys", vmin=0, vmax=4,
                      hatch="///", edgecolors="none", alpha=0.6)  # fmt: skip
    hatch.set_gid("unknown")
    if known.size <= 150:
        for j, i in zip(*np.nonzero(known), strict=True):
            ax.text(xc[i], yc[j], f"{p[j, i]:.2f}\n[{grid['lo'][j, i]:.2f}, {grid['hi'][j, i]:.2f}]",
                    ha="center", va="center", fontsize=5)  # fmt: skip
    ax.set_xlim(xe[0], xe[-1])
    ax.set_ylim(ye[0], ye[-1])
    ax.set_xlabel(x_label)
    ax.set_ylabel(y_label)
    ax.legend(handles=[Patch(facecolor=ZERO_COLOUR, label="known: P = 0 (95 % CI within +-0.1)"),
                       Patch(facecolor="lightgrey", hatch="///",
                             label="not known (95 % CI wider than +-0.1)")],
              loc="upper right", fontsize=7, framealpha=0.8)  # fmt: skip
    ax.set_title(title or "P(collision | cell)", fontsize=9)
    fig.tight_layout()
    FigureCanvasAgg(fig)
    path = Path(path)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format=path.suffix.lstrip(".") or "png")
    return path
