"""The paper's case-study figures, drawn from backend-agnostic run time series.

- Fig. 4 ``birdseye``: per configuration, the ego's path (solid red), the e-scooter's
  original keyframes (dashed black, markers) and its simulated path (dashed green), the
  collision point (star) if any; the map's roads underneath when a ``roads`` callable is
  given.
- Fig. 5 ``speed_profiles``: ego speed over time, one line per configuration.
- Fig. 6 ``speed_std``: bar chart of the ego speed standard deviation per configuration.
- Fig. 8 ``safety_index``: bar chart of the safety index per configuration (collisions
  annotated).
- ``ttc_zones``: the paper's TTC per configuration over time on the zone bands (safe >
  2 s, attention (1, 2] s, alert (0, 1] s).

Artists carry labels (the configuration name) so tests can find them. Figures use
``matplotlib.figure.Figure`` (no pyplot state) and are saved atomically.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from vei.io.atomic import atomic_path
from vei.types import EGO_ID

#: Colour per configuration name (others cycle through the default palette).
CONFIG_COLOURS: dict[str, str] = {
    "replay": "tab:gray",
    "normal": "tab:blue",
    "aggressive": "tab:red",
    "normal-cap": "tab:green",
    "aggressive-cap": "tab:purple",
}
_FALLBACK = ("tab:orange", "tab:brown", "tab:pink", "tab:olive", "tab:cyan")

#: File names written by :func:`write_casestudy_figures`.
FIGURE_FILES: dict[str, str] = {
    "birdseye": "fig4_birdseye.png",
    "speed_profiles": "fig5_speed_profiles.png",
    "speed_std": "fig6_speed_std.png",
    "safety_index": "fig8_safety_index.png",
    "ttc_zones": "ttc_zones.png",
}


def config_colour(name: str, index: int = 0) -> str:
    """Colour of a configuration (fixed for the paper's five)."""
    return CONFIG_COLOURS.get(name, _FALLBACK[index % len(_FALLBACK)])


def _new_axes(ax, figsize=(7.0, 4.0)):
    if ax is not None:
        return ax.figure, ax
    from matplotlib.figure import Figure

    fig = Figure(figsize=figsize)
    return fig, fig.add_subplot()


def _configs(frame: pd.DataFrame) -> list[str]:
    return list(dict.fromkeys(frame["config"].astype(str)))


def _first_variants(frame: pd.DataFrame) -> pd.DataFrame:
    """Rows of the first variant of each configuration (the batch index may differ per config)."""
    first = frame.groupby("config", sort=False)["variant"].transform("min")
    return frame[frame["variant"] == first]


def plot_speed_profiles(frame: pd.DataFrame, *, ax=None, ego_id: str = EGO_ID):
    """Fig. 5: ego speed [m/s] over time [s], one line per configuration (its first variant).

    Args:
        frame: long time series (vei.types.TIMESERIES_COLUMNS).
    Returns:
        The Figure; each line's label is the configuration name.
    """
    fig, ax = _new_axes(ax)
    sub = _first_variants(frame)
    ego = sub[sub["agent_id"] == ego_id]
    for i, name in enumerate(_configs(frame)):
        rows = ego[ego["config"] == name].sort_values("t_s")
        ax.plot(
            rows["t_s"].to_numpy(),
            rows["speed_mps"].to_numpy(),
            lw=1.8,
            color=config_colour(name, i),
            label=name,
        )
    ax.set_xlabel("time [s]")
    ax.set_ylabel("ego speed [m/s]")
    ax.set_title("Ego speed profiles")
    ax.set_ylim(bottom=0.0)
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=8, loc="lower left")
    return fig


def _bars(summary: pd.DataFrame, column: str, ylabel: str, title: str, ax, fmt: str):
    fig, ax = _new_axes(ax, figsize=(6.0, 4.0))
    names = summary["name"].astype(str).tolist()
    values = summary[column].to_numpy(dtype=float)
    heights = np.nan_to_num(values, nan=0.0)
    colours = [config_colour(n, i) for i, n in enumerate(names)]
    bars = ax.bar(names, heights, color=colours, label=column)
    for rect, v, n in zip(bars, values, names, strict=True):
        rect.set_gid(n)
        text = "n/a" if not np.isfinite(v) else format(v, fmt)
        ax.annotate(
            text,
            (rect.get_x() + rect.get_width() / 2, rect.get_height()),
            ha="center",
            va="bottom",
            fontsize=8,
        )
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.tick_params(axis="x", labelrotation=20, labelsize=8)
    ax.grid(True, axis="y", lw=0.3, alpha=0.5)
    return fig, ax


def plot_speed_std(summary: pd.DataFrame, *, ax=None):
    """Fig. 6: ego speed standard deviation [m/s] per configuration (bar per summary row).

    Args:
        summary: columns 'name' and 'ego_speed_std_mps'.
    """
    fig, _ = _bars(
        summary,
        "ego_speed_std_mps",
        "ego speed std [m/s]",
        "Ego speed standard deviation",
        ax,
        ".2f",
    )
    return fig


def plot_safety_index(summary: pd.DataFrame, *, ax=None):
    """Fig. 8: safety index per configuration; 'collision' written on colliding bars.

    Args:
        summary: columns 'name', 'safety_index', 'collision'.
    """
    fig, ax = _bars(summary, "safety_index", "safety index [-]", "Safety index", ax, ".2f")
    ax.set_ylim(0.0, 1.15)
    for i, hit in enumerate(summary["collision"].astype(bool).tolist()):
        if hit:
            ax.annotate(
                "collision",
                (i, 0.06),
                ha="center",
                va="bottom",
                fontsize=8,
                color="black",
                rotation=90,
            )
    return fig


def plot_ttc_zones(
    t_s: np.ndarray,
    ttc_s: np.ndarray,
    names: Sequence[str],
    *,
    ax=None,
    safe_ttc_s: float = 2.0,
    alert_ttc_s: float = 1.0,
    ymax_s: float = 6.0,
):
    """The paper's TTC over time on its zone bands, one line per configuration.

    Args:
        t_s: [T] time [s]. ttc_s: [B, T] paper TTC [s] (NaN inactive, inf -> clipped at
            ymax_s for display only). names: B configuration names.
    """
    fig, ax = _new_axes(ax)
    ax.axhspan(safe_ttc_s, ymax_s, color="tab:green", alpha=0.10, label="safe zone")
    ax.axhspan(alert_ttc_s, safe_ttc_s, color="gold", alpha=0.18, label="attention zone")
    ax.axhspan(0.0, alert_ttc_s, color="tab:red", alpha=0.12, label="alert zone")
    ttc = np.asarray(ttc_s, dtype=float)
    for i, name in enumerate(names):
        y = np.minimum(ttc[i], ymax_s)
        ax.plot(t_s, y, lw=1.5, color=config_colour(name, i), label=name)
    ax.set_ylim(0.0, ymax_s)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"TTC = gap / v_ego [s] (clipped at {ymax_s:g})")
    ax.set_title("Time to collision and its zones")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=7, loc="upper right", ncol=2)
    return fig


def plot_birdseye_configs(
    frame: pd.DataFrame,
    *,
    other_id: str,
    keyframes: pd.DataFrame | None = None,
    roads: Callable | None = None,
    ego_id: str = EGO_ID,
    margin_m: float = 6.0,
):
    """Fig. 4: one bird's-eye panel per configuration (plane x east, y north [m]).

    In each panel: the ego's path, solid red (label 'ego'); the e-scooter's original
    keyframes, dashed black with markers ('keyframes'); its simulated path, dashed green
    ('<other_id> (sim)'); a star at the ego's position at the first collision
    ('collision'). The view is the part of the scene where the road user is present.

    Args:
        frame: long time series of the runs (the first variant of each configuration is drawn).
        other_id: the road user (primary threat).
        keyframes: the scenario's keyframes (t_s, agent_id, x_m, y_m), or None.
        roads: optional callable roads(ax) drawing the map underneath.
    """
    from matplotlib.figure import Figure

    names = _configs(frame)
    n = len(names)
    sub = _first_variants(frame)
    oth = sub[(sub["agent_id"] == other_id) & sub["active"].astype(bool)]
    kf = (
        None
        if keyframes is None
        else keyframes[keyframes["agent_id"] == other_id].sort_values("t_s")
    )
    pts = [oth[["x_m", "y_m"]].to_numpy()]
    if kf is not None and len(kf):
        pts.append(kf[["x_m", "y_m"]].to_numpy())
    allp = np.concatenate(pts) if sum(len(p) for p in pts) else np.zeros((1, 2))
    lo, hi = allp.min(axis=0) - margin_m, allp.max(axis=0) + margin_m
    aspect = float((hi[0] - lo[0]) / max(hi[1] - lo[1], 1e-6))
    # wide scenes (a street seen from above) stack the panels; compact ones tile them
    cols = 1 if aspect > 2.5 else min(n, 3)
    rows = int(np.ceil(n / cols))
    panel_w = 11.0 if cols == 1 else 4.6
    panel_h = min(max(panel_w / aspect, 1.6), 4.6) + 0.7
    fig = Figure(figsize=(panel_w * cols, panel_h * rows))
    axes = [fig.add_subplot(rows, cols, i + 1) for i in range(n)]
    for ax, name in zip(axes, names, strict=True):
        if roads is not None:
            roads(ax)
        run = sub[sub["config"] == name]
        ego = run[run["agent_id"] == ego_id].sort_values("t_s")
        rider = run[(run["agent_id"] == other_id) & run["active"].astype(bool)].sort_values("t_s")
        ax.plot(
            ego["x_m"].to_numpy(),
            ego["y_m"].to_numpy(),
            "-",
            color="red",
            lw=2.4,
            label="ego",
            zorder=3,
        )
        if kf is not None and len(kf):
            ax.plot(
                kf["x_m"].to_numpy(),
                kf["y_m"].to_numpy(),
                "--",
                color="black",
                lw=1.0,
                marker="x",
                ms=4,
                label="keyframes",
                zorder=4,
            )
        ax.plot(
            rider["x_m"].to_numpy(),
            rider["y_m"].to_numpy(),
            "--",
            color="tab:green",
            lw=2.0,
            label=f"{other_id} (sim)",
            zorder=5,
        )
        hit = rider[rider["collided"].astype(bool)]
        if len(hit):
            t_hit = float(hit["t_s"].iloc[0])
            e = ego[np.isclose(ego["t_s"].to_numpy(), t_hit)]
            ax.plot(
                e["x_m"].to_numpy(),
                e["y_m"].to_numpy(),
                "*",
                color="black",
                ms=14,
                mfc="yellow",
                label="collision",
                zorder=6,
            )
        ax.set_xlim(lo[0], hi[0])
        ax.set_ylim(lo[1], hi[1])
        ax.set_aspect("equal", adjustable="box")
        ax.set_title(name, fontsize=10)
        ax.set_xlabel("x east [m]", fontsize=8)
        ax.set_ylabel("y north [m]", fontsize=8)
        ax.tick_params(labelsize=7)
        ax.grid(True, lw=0.3, alpha=0.5)
    if axes:
        axes[0].legend(fontsize=7, loc="best")
    fig.suptitle(
        f"Bird's-eye view: ego (red), original keyframes (dashed black), simulated {other_id} (dashed green)",
        fontsize=10,
    )
    fig.tight_layout(rect=(0.0, 0.0, 1.0, 0.97))
    return fig


def save_figure(fig, path: str | Path, dpi: int = 130) -> Path:
    """Save a figure atomically (format from the suffix, PNG by default); returns the path."""
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=fmt, bbox_inches="tight")
    return path


def write_casestudy_figures(
    out_dir: str | Path,
    *,
    frame: pd.DataFrame,
    summary: pd.DataFrame,
    other_id: str,
    ttc_t_s: np.ndarray,
    ttc_s: np.ndarray,
    keyframes: pd.DataFrame | None = None,
    roads: Callable | None = None,
    safe_ttc_s: float = 2.0,
    alert_ttc_s: float = 1.0,
) -> dict[str, Path]:
    """Write the five figures into ``out_dir`` (names in FIGURE_FILES); returns name -> path.

    Args:
        frame: long time series of the runs. summary: one row per configuration (columns
        name, collision, safety_index, ego_speed_std_mps). other_id: the primary threat.
        ttc_t_s [T], ttc_s [B, T]: the paper's TTC series (rows in summary order).
    """
    out = Path(out_dir)
    figs = {
        "birdseye": plot_birdseye_configs(
            frame, other_id=other_id, keyframes=keyframes, roads=roads
        ),
        "speed_profiles": plot_speed_profiles(frame),
        "speed_std": plot_speed_std(summary),
        "safety_index": plot_safety_index(summary),
        "ttc_zones": plot_ttc_zones(
            ttc_t_s,
            ttc_s,
            summary["name"].astype(str).tolist(),
            safe_ttc_s=safe_ttc_s,
            alert_ttc_s=alert_ttc_s,
        ),
    }
    return {key: save_figure(fig, out / FIGURE_FILES[key]) for key, fig in figs.items()}
