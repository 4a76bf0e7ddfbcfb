"""Bird's-eye view of a scenario: ego path, every road user's path, keyframes, primary threat.

Artists carry labels so tests (and users) can find them: the ego path is labelled
``'ego'``, each road user's interpolated path ``'<agent_id>'``, its keyframes
``'<agent_id> keyframes'``, start markers ``'<agent_id> start'``, its footprint where it
starts ``'<agent_id> box'`` (a parked car, which has no path to draw, and any road user
that can hide another), simulated tracks ``'<agent_id> (sim)'``. The primary threat is drawn thicker, in red-orange, and named in the
legend. ``roads`` is a hook: a callable ``roads(ax)`` that draws the map underneath
(vei.maps provides one); it is called first so that roads lie below the paths.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from vei.io.atomic import atomic_path
from vei.types import EGO_ID, Scenario

#: Colours per category (the ego in blue; the primary threat overrides its category colour).
CATEGORY_COLOURS: dict[str, str] = {
    "ego": "tab:blue",
    "escooter": "tab:green",
    "cyclist": "tab:purple",
    "pedestrian": "tab:brown",
    "vehicle": "tab:gray",
}
PRIMARY_COLOUR = "tab:red"


def plot_birdseye(
    scenario: Scenario,
    *,
    ax=None,
    sim_tracks: pd.DataFrame | None = None,
    title: str | None = None,
    roads: Callable | None = None,
    time_dots: bool = True,
):
    """Draw the scenario from above (plane x east, y north [m], equal aspect).

    Args:
        scenario: the scenario (trajectories, keyframes, primary_threat).
        ax: matplotlib Axes to draw into (a new figure if None).
        sim_tracks: optional simulated trajectories (columns agent_id, t_s, x_m, y_m), drawn
            dashed over the recorded ones.
        title: axes title (default: the scenario id).
        roads: optional callable roads(ax) drawing the map underneath. When None and the
            scenario was read from a folder whose scenario.json names an OpenDRIVE map, that
            map's roads are drawn (lanes, lane borders, kerbs); without one the axes say
            'no road map'.
        time_dots: time-code the ego's and the primary threat's paths (a dot every whole
            second coloured by time, colour bar 'time [s]').
    Returns:
        The matplotlib Figure.
    """
    if ax is None:
        from matplotlib.figure import Figure  # no pyplot: no global figure registry

        fig = Figure(figsize=(8, 8))
        ax = fig.add_subplot()
    else:
        fig = ax.figure
    if roads is None:
        roads = scenario_roads(scenario)
    if roads is not None:
        roads(ax)
    else:
        _no_map(ax)
    traj = scenario.trajectories
    primary = scenario.primary_threat
    keyframes = scenario.keyframes
    order = [a.agent_id for a in scenario.agents if a.agent_id != EGO_ID]
    if EGO_ID in set(traj["agent_id"]):
        order = [EGO_ID, *order]
    for agent_id in order:
        tr = traj[traj["agent_id"] == agent_id].sort_values("t_s")
        if tr.empty:
            continue
        cat = scenario.agent(agent_id).category
        is_primary = agent_id == primary
        colour = PRIMARY_COLOUR if is_primary else CATEGORY_COLOURS.get(cat, "black")
        width = 2.8 if is_primary or agent_id == EGO_ID else 1.4
        label = agent_id + (" (primary threat)" if is_primary else "")
        ax.plot(
            tr["x_m"].to_numpy(),
            tr["y_m"].to_numpy(),
            "-",
            color=colour,
            lw=width,
            label=label,
            zorder=3,
        )
        ax.plot(
            tr["x_m"].iloc[0],
            tr["y_m"].iloc[0],
            "o",
            color=colour,
            ms=7 if is_primary or agent_id == EGO_ID else 5,
            mfc="white",
            label=f"{agent_id} start",
            zorder=4,
        )
        ax.annotate(
            agent_id,
            (tr["x_m"].iloc[0], tr["y_m"].iloc[0]),
            textcoords="offset points",
            xytext=(4, 4),
            fontsize=6,
            color=colour,
        )
        if agent_id != EGO_ID:  # its box where it starts: a parked car has no path
            info = scenario.agent(agent_id)
            draw_box(ax, float(tr["x_m"].iloc[0]), float(tr["y_m"].iloc[0]),
                     float(tr["yaw_rad"].iloc[0]), info.length_m, info.width_m, colour=colour,
                     label=f"{agent_id} box", hatch="//" if cat == "vehicle" else None)  # fmt: skip
        if keyframes is not None and agent_id != EGO_ID:
            kf = keyframes[keyframes["agent_id"] == agent_id]
            if len(kf):
                ax.plot(
                    kf["x_m"].to_numpy(),
                    kf["y_m"].to_numpy(),
                    "x",
                    color=colour,
                    ms=5,
                    label=f"{agent_id} keyframes",
                    zorder=5,
                )
    if sim_tracks is not None:
        for agent_id, tr in sim_tracks.groupby("agent_id", sort=True):
            tr = tr.sort_values("t_s")
            ax.plot(
                tr["x_m"].to_numpy(),
                tr["y_m"].to_numpy(),
                "--",
                color="black",
                lw=1.2,
                label=f"{agent_id} (sim)",
                zorder=6,
            )
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x east [m]")
    ax.set_ylabel("y north [m]")
    ax.set_title(title if title is not None else scenario.id)
    ax.grid(True, lw=0.3, alpha=0.5)
    # Legend: paths only (start markers, keyframes and boxes are explained by the key).
    handles = [
        h
        for h in ax.get_lines()
        if not h.get_label().endswith((" start", " keyframes", " box"))
        and not h.get_label().startswith("_")
    ]
    if handles:
        ax.legend(
            handles=handles,
            loc="best",
            fontsize=7,
            title="o start   x keyframes   box: footprint",
            title_fontsize=7,
        )
    if time_dots:
        _time_dots(ax, traj, [a for a in (EGO_ID, primary) if a is not None])
    return fig


def draw_box(ax, x_m: float, y_m: float, yaw_rad: float, length_m: float, width_m: float, *,
             colour: str = "black", label: str = "_box", hatch: str | None = None) -> None:  # fmt: skip
    """Draw a road user's footprint (an oriented box [m, rad]) as a closed outline (a Line2D
    labelled ``label``, so that tests find it) filled lightly (hatched for ``hatch``)."""
    from matplotlib.patches import Polygon

    from vei.boxes import box_corners

    c = box_corners(x_m, y_m, yaw_rad, length_m, width_m)
    ring = np.vstack([c, c[:1]])
    ax.add_patch(Polygon(c, closed=True, facecolor=colour, alpha=0.25, hatch=hatch,
                         edgecolor=colour, lw=0.0, zorder=2))  # fmt: skip
    ax.plot(ring[:, 0], ring[:, 1], "-", color=colour, lw=1.2, label=label, zorder=2)


def _time_dots(ax, traj: pd.DataFrame, agents: list[str]) -> None:
    """Time-code the paths of ``agents``: a dot at each whole second, coloured by time
    (one shared scale over the agents' spans), with a colour bar 'time [s]'."""
    import numpy as np

    rows = traj[traj["agent_id"].isin(agents)]
    if rows.empty:
        return
    lo, hi = float(np.floor(rows["t_s"].min())), float(np.ceil(rows["t_s"].max()))
    scat = None
    for agent_id in agents:
        tr = rows[rows["agent_id"] == agent_id].sort_values("t_s")
        t = tr["t_s"].to_numpy()
        whole = np.abs(t - np.round(t)) < 1e-6
        if whole.any():
            scat = ax.scatter(tr["x_m"].to_numpy()[whole], tr["y_m"].to_numpy()[whole], c=t[whole],
                              cmap="viridis", vmin=lo, vmax=max(hi, lo + 1e-9), s=14, zorder=6,
                              edgecolors="black", linewidths=0.3, label=f"_{agent_id} seconds")  # fmt: skip
    if scat is not None:
        ax.figure.colorbar(scat, ax=ax, shrink=0.6, pad=0.02, label="time [s] (dots every 1 s)")


def _no_map(ax) -> None:
    """Say on the Axes that the scenario has no map (nothing drawn under the tracks)."""
    from vei.maps.roads import draw_no_map_note

    draw_no_map_note(ax)


def scenario_roads(scenario: Scenario) -> Callable | None:
    """A roads(ax) drawer for the scenario's own OpenDRIVE map, or None if it has none."""
    name = scenario.maps.get("opendrive")
    if not name or scenario.root is None or not (Path(scenario.root) / name).is_file():
        return None
    from vei.maps import draw_roads, load_roads

    geometry = load_roads(Path(scenario.root) / name)
    return lambda ax: draw_roads(ax, geometry)


def save_figure(fig, path: str | Path, dpi: int = 150, *, also: tuple[str, ...] = ()) -> Path:
    """Save a figure atomically as PNG (or the format the suffix names); closes nothing.

    Args:
        fig: matplotlib Figure.
        path: target file.
        dpi: resolution [dots per inch].
        also: further formats written beside it with the same stem (e.g. ('pdf', 'svg')).
    Returns:
        The path.
    """
    path = Path(path)
    fmt = path.suffix.lstrip(".") or "png"
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=dpi, format=fmt, bbox_inches="tight")
    for extra in also:
        with atomic_path(path.with_suffix(f".{extra}")) as tmp:
            fig.savefig(tmp, dpi=dpi, format=extra, bbox_inches="tight")
    return path
