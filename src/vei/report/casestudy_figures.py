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

# Fig. 4 lives in its own module (this one stays small); re-exported here.
from vei.report.casestudy_birdseye import _configs, _first_variants, plot_birdseye_configs
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


#: Line styles cycled per configuration, so that identical curves stay visible.
_STYLES: tuple = ("-", (0, (6, 2)), (0, (3, 2, 1, 2)), (0, (1, 1.5)), (0, (8, 2, 2, 2)))
#: Colours of the CAP states in the state band.
CAP_STATE_COLOURS: dict[str, str] = {"CRUISE": "#9ccc65", "BRAKE": "#e53935", "RECOVER": "#ffb300"}
#: Seconds of context kept before / after the interaction on time axes.
TIME_MARGIN_S = 2.0


#: The interaction: ego and rider centres closer than this [m] (before any collision).
NEAR_M = 30.0


def interaction_window(
    frame: pd.DataFrame,
    other_id: str | None,
    margin_s: float = TIME_MARGIN_S,
    near_m: float = NEAR_M,
    ego_id: str = EGO_ID,
) -> tuple[float, float] | None:
    """[t0, t1] [s] of the interaction, widened by ``margin_s`` and clipped to the run.

    The interaction: the steps at which ``other_id`` is active and within ``near_m`` of the
    ego, up to its first collision, in any configuration (so an event at 5 s of a 61 s run
    is not drawn over 0-61 s). Falls back to the rider's active span when it never comes
    that close; None if it is never active.
    """
    if other_id is None:
        return None
    sub = _first_variants(frame)
    oth = sub[(sub["agent_id"] == other_id) & sub["active"].astype(bool)]
    if oth.empty:
        return None
    ego = sub[sub["agent_id"] == ego_id][["config", "t_s", "x_m", "y_m"]]
    both = oth.merge(ego, on=["config", "t_s"], suffixes=("", "_ego"))
    dist = np.hypot(both["x_m"] - both["x_m_ego"], both["y_m"] - both["y_m_ego"])
    first_hit = both[both["collided"].astype(bool)].groupby("config")["t_s"].min()
    limit = both["config"].map(first_hit).fillna(np.inf)
    near = both[(dist.to_numpy() < near_m) & (both["t_s"] <= limit).to_numpy()]
    span = near if len(near) else oth
    lo = max(float(span["t_s"].min()) - margin_s, float(frame["t_s"].min()))
    hi = min(float(span["t_s"].max()) + margin_s, float(frame["t_s"].max()))
    return lo, hi


def identical_groups(curves: dict[str, np.ndarray], tol: float = 1e-6) -> list[list[str]]:
    """Groups (>= 2 names, in input order) of curves equal within ``tol`` everywhere
    (NaN equal to NaN): lines that would hide each other."""
    names = list(curves)
    seen: set[str] = set()
    groups = []
    for i, a in enumerate(names):
        if a in seen:
            continue
        grp = [a]
        for b in names[i + 1 :]:
            x, y = np.asarray(curves[a], float), np.asarray(curves[b], float)
            if b not in seen and x.shape == y.shape and np.allclose(x, y, atol=tol, equal_nan=True):
                grp.append(b)
        if len(grp) > 1:
            seen.update(grp)
            groups.append(grp)
    return groups


def _overlap_note(ax, curves: dict[str, np.ndarray]) -> None:
    """Name the identical curves in a note inside the axes, wrapped to the axes' width (a
    one-line note ran into the next panel)."""
    import textwrap

    groups = identical_groups(curves)
    if groups:
        text = "identical curves (drawn with different dashes): " + "; ".join(
            " = ".join(g) for g in groups
        )
        fontsize = 7.0
        width_pt = ax.get_position().width * ax.figure.get_figwidth() * 72.0
        chars = max(20, int(0.92 * width_pt / (0.55 * fontsize)))  # ~0.55 em per character
        ax.text(0.01, 0.02, textwrap.fill(text, chars, break_on_hyphens=False), transform=ax.transAxes,
                fontsize=fontsize, va="bottom", ha="left", color="0.25",
                bbox={"boxstyle": "round,pad=0.2", "fc": "white", "ec": "0.7", "alpha": 0.85})  # fmt: skip


def _speed_panel(ax, rows_by_name: dict[str, pd.DataFrame], ylabel: str, title: str) -> None:
    curves = {}
    for i, (name, rows) in enumerate(rows_by_name.items()):
        speed = np.where(rows["active"].astype(bool), rows["speed_mps"], np.nan)
        curves[name] = speed
        ax.plot(rows["t_s"].to_numpy(), speed, lw=2.0 - 0.25 * (i % 5), ls=_STYLES[i % len(_STYLES)],
                color=config_colour(name, i), label=name)  # fmt: skip
    _overlap_note(ax, curves)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    ax.set_ylim(bottom=0.0)
    ax.grid(True, lw=0.3, alpha=0.5)


def plot_speed_profiles(
    frame: pd.DataFrame,
    *,
    ax=None,
    ego_id: str = EGO_ID,
    other_id: str | None = None,
    window_s: tuple[float, float] | None = None,
):
    """Fig. 5: ego speed [m/s] over time [s], one line per configuration (its first variant);
    with ``other_id`` also the rider's speed in a panel beside it and the CAP's state band.

    Axes: ``fig.axes[0]`` ego speed (line labels = configuration names); with ``other_id``
    ``fig.axes[1]`` the rider's speed while it is present, then one CAP-state band per
    configuration that has a CAP (broken bars labelled CRUISE / BRAKE / RECOVER). Time
    axes are zoomed to ``window_s`` (default: :func:`interaction_window`). Curves that are
    identical are named in a note (and drawn with different dashes).

    Args:
        frame: long time series (vei.types.TIMESERIES_COLUMNS).
    Returns:
        The Figure.
    """
    sub = _first_variants(frame)
    names = _configs(frame)
    ego = sub[sub["agent_id"] == ego_id]
    ego_rows = {n: ego[ego["config"] == n].sort_values("t_s") for n in names}
    if ax is not None or other_id is None:
        fig, ax = _new_axes(ax)
        _speed_panel(ax, ego_rows, "ego speed [m/s]", "Ego speed profiles")
        ax.set_xlabel("time [s]")
        ax.legend(fontsize=8, loc="center right")
        win = window_s or interaction_window(frame, other_id)
        if win is not None:
            ax.set_xlim(*win)
        return fig
    from matplotlib.figure import Figure

    cap_names = [n for n in names if (ego_rows[n]["cap_state"].astype(str) != "").any()]
    fig = Figure(figsize=(11.0, 4.2 + 0.28 * len(cap_names)))
    heights = [4.0, max(0.28 * len(cap_names), 0.01)] if cap_names else [4.0]
    gs = fig.add_gridspec(len(heights), 2, height_ratios=heights, hspace=0.12 if cap_names else 0.2)
    ax_ego = fig.add_subplot(gs[0, 0])
    ax_rider = fig.add_subplot(gs[0, 1], sharex=ax_ego)
    oth = sub[sub["agent_id"] == other_id]
    rider_rows = {n: oth[oth["config"] == n].sort_values("t_s") for n in names}
    _speed_panel(ax_ego, ego_rows, "ego speed [m/s]", "Ego speed")
    _speed_panel(ax_rider, rider_rows, f"{other_id} speed [m/s]", f"Rider speed ({other_id})")
    ax_ego.legend(fontsize=8, loc="center right")
    win = window_s or interaction_window(frame, other_id)
    if win is not None:
        ax_ego.set_xlim(*win)
    if cap_names:
        ax_cap = fig.add_subplot(gs[1, 0], sharex=ax_ego)
        for k, name in enumerate(cap_names):
            rows = ego_rows[name]
            t = rows["t_s"].to_numpy()
            state = rows["cap_state"].astype(str).to_numpy()
            dt = float(np.median(np.diff(t))) if t.size > 1 else 0.05
            for st, col in CAP_STATE_COLOURS.items():
                on = state == st
                if not on.any():
                    continue
                edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
                spans = [
                    (t[a], t[b - 1] + dt - t[a])
                    for a, b in zip(edges[::2], edges[1::2], strict=True)
                ]
                ax_cap.broken_barh(spans, (k - 0.4, 0.8), facecolors=col, label=st)
        ax_cap.set_yticks(range(len(cap_names)), cap_names, fontsize=7)
        ax_cap.set_ylim(-0.6, len(cap_names) - 0.4)
        ax_cap.set_xlabel("time [s]")
        ax_cap.set_title("CAP state", fontsize=8, loc="left", pad=2)
        from matplotlib.patches import Patch

        # every state, present or not, so that the band's colours can always be read
        ax_cap.legend([Patch(facecolor=c) for c in CAP_STATE_COLOURS.values()],
                      list(CAP_STATE_COLOURS), fontsize=7, ncol=3, title="CAP state",
                      title_fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0),
                      frameon=False)  # fmt: skip
        ax_ego.tick_params(labelbottom=False)
    else:
        ax_ego.set_xlabel("time [s]")
    ax_rider.set_xlabel("time [s]")
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
    window_s: tuple[float, float] | None = None,
):
    """The paper's TTC over time on its zone bands, one line per configuration.

    Args:
        t_s: [T] time [s]. ttc_s: [B, T] paper TTC [s] (NaN inactive, inf -> clipped at
            ymax_s for display only). names: B configuration names.
        window_s: time axis limits [s]; default: where any TTC is defined, +-2 s.
    """
    fig, ax = _new_axes(ax)
    ax.axhspan(safe_ttc_s, ymax_s, color="tab:green", alpha=0.10, label="safe zone")
    ax.axhspan(alert_ttc_s, safe_ttc_s, color="gold", alpha=0.18, label="attention zone")
    ax.axhspan(0.0, alert_ttc_s, color="tab:red", alpha=0.12, label="alert zone")
    ttc = np.asarray(ttc_s, dtype=float)
    curves = {}
    for i, name in enumerate(names):
        y = np.minimum(ttc[i], ymax_s)
        curves[name] = y
        ax.plot(t_s, y, lw=1.8 - 0.2 * (i % 5), ls=_STYLES[i % len(_STYLES)],
                color=config_colour(name, i), label=name)  # fmt: skip
    _overlap_note(ax, curves)
    ax.set_ylim(0.0, ymax_s)
    t = np.asarray(t_s, dtype=float)
    defined = np.isfinite(ttc).any(axis=0) if ttc.ndim == 2 and ttc.size else np.zeros(t.size, bool)
    if window_s is None and defined.any() and t.size > 1:
        window_s = (
            max(t[defined][0] - TIME_MARGIN_S, t[0]),
            min(t[defined][-1] + TIME_MARGIN_S, t[-1]),
        )
    if window_s is not None and window_s[1] > window_s[0]:
        ax.set_xlim(*window_s)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(f"TTC = gap / v_ego [s] (clipped at {ymax_s:g})")
    ax.set_title("Time to collision and its zones")
    ax.grid(True, lw=0.3, alpha=0.5)
    ax.legend(fontsize=7, loc="upper right", ncol=2)
    return fig


def save_figure(fig, path: str | Path, dpi: int = 130, *, also: Sequence[str] = ()) -> Path:
    """Save a figure atomically (format from the suffix, PNG by default); returns the path.

    ``also``: further formats written beside it with the same stem (e.g. ('pdf',) for a
    vector copy a paper can use).
    """
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=fmt, bbox_inches="tight")
    for extra in also:
        with atomic_path(path.with_suffix(f".{extra}")) as tmp:
            fig.savefig(tmp, dpi=dpi, format=extra, bbox_inches="tight")
    return path


def figure_title(summary: pd.DataFrame, scenario_id: str | None = None) -> str:
    """'Run <config>' for one configuration (vei run), else 'Case study' (+ the scenario)."""
    names = summary["name"].astype(str).tolist() if "name" in summary else []
    head = f"Run {names[0]}" if len(names) == 1 else "Case study"
    return f"{head}: {scenario_id}" if scenario_id else head


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
    dims: dict[str, tuple[float, float]] | None = None,
    safe_ttc_s: float = 2.0,
    alert_ttc_s: float = 1.0,
    title: str | None = None,
    formats: Sequence[str] = ("pdf",),
) -> dict[str, Path]:
    """Write the five figures into ``out_dir`` (names in FIGURE_FILES, PNG, plus a copy in
    each of ``formats``, default PDF); returns name -> PNG path.

    Args:
        frame: long time series of the runs. summary: one row per configuration (columns
        name, collision, safety_index, ego_speed_std_mps). other_id: the primary threat.
        ttc_t_s [T], ttc_s [B, T]: the paper's TTC series (rows in summary order).
        title: heading of every figure; default :func:`figure_title` ('Run <config>' when
            one configuration was run, 'Case study' otherwise).
        dims: {agent_id: (length_m, width_m)} of the road users drawn in the bird's-eye
            figure (vei.report.casestudy_birdseye.plot_birdseye_configs).
    """
    out = Path(out_dir)
    heading = title if title is not None else figure_title(summary)
    window = interaction_window(frame, other_id)
    figs = {
        "birdseye": plot_birdseye_configs(
            frame, other_id=other_id, keyframes=keyframes, roads=roads, dims=dims
        ),
        "speed_profiles": plot_speed_profiles(frame, other_id=other_id, window_s=window),
        "speed_std": plot_speed_std(summary),
        "safety_index": plot_safety_index(summary),
        "ttc_zones": plot_ttc_zones(
            ttc_t_s,
            ttc_s,
            summary["name"].astype(str).tolist(),
            safe_ttc_s=safe_ttc_s,
            alert_ttc_s=alert_ttc_s,
            window_s=window,
        ),
    }
    for fig in figs.values():
        sup = fig._suptitle.get_text() if fig._suptitle is not None else ""
        fig.suptitle(f"{heading}" + (f"\n{sup}" if sup else ""), fontsize=10)
    return {
        key: save_figure(fig, out / FIGURE_FILES[key], also=tuple(formats))
        for key, fig in figs.items()
    }
