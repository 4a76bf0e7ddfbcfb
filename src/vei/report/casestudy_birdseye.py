"""The case study's Fig. 4: one bird's-eye panel per configuration (the ego's path, the
road user's keyframes and simulated path, its run-in / run-out shaded, the collision
point, every other road user that can hide it: its path and its box at the panel's key
moment), the map's roads underneath when given. Re-exported by
:mod:`vei.report.casestudy_figures`, which writes it with the other figures.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pandas as pd

from vei.report.birdseye import CATEGORY_COLOURS, draw_box
from vei.types import EGO_ID

#: Footprint [m] of a road user whose size the figure is not given, by category.
DEFAULT_DIMS_M: dict[str, tuple[float, float]] = {
    "vehicle": (4.5, 1.8), "escooter": (1.2, 0.6), "cyclist": (1.8, 0.6),
    "pedestrian": (0.5, 0.5),
}  # fmt: skip


def _configs(frame: pd.DataFrame) -> list[str]:
    return list(dict.fromkeys(frame["config"].astype(str)))


def _first_variants(frame: pd.DataFrame) -> pd.DataFrame:
    """Rows of the first variant of each configuration (the batch index may differ per config)."""
    first = frame.groupby("config", sort=False)["variant"].transform("min")
    return frame[frame["variant"] == first]


def plot_birdseye_configs(
    frame: pd.DataFrame,
    *,
    other_id: str,
    keyframes: pd.DataFrame | None = None,
    roads: Callable | None = None,
    ego_id: str = EGO_ID,
    margin_m: float = 6.0,
    dims: dict[str, tuple[float, float]] | None = None,
):
    """Fig. 4: one bird's-eye panel per configuration (plane x east, y north [m]).

    In each panel: the ego's path, solid red (label 'ego'); the e-scooter's original
    keyframes, dashed black with markers ('keyframes'); its simulated path, dashed green
    ('<other_id> (sim)'); a star at the ego's position at the first collision
    ('collision'). Every other road user of the frame (each can hide the rider from the
    car's sensor; vehicles block V2X links too) is drawn: its path, thin, and its box
    (label '<agent_id> box', hatched for a vehicle) at the panel's key moment, the
    collision or else the ego's and the rider's closest approach. The view is the part of
    the scene where the road user is present.

    Args:
        frame: long time series of the runs (the first variant of each configuration is drawn).
        other_id: the road user (primary threat).
        keyframes: the scenario's keyframes (t_s, agent_id, x_m, y_m), or None.
        roads: optional callable roads(ax) drawing the map underneath (None: each panel
            says 'no road map').
        dims: {agent_id: (length_m, width_m)} of the road users' boxes (missing ones:
            :data:`DEFAULT_DIMS_M` by category).
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
    t_lo = float(np.floor(oth["t_s"].min())) if len(oth) else float(sub["t_s"].min())
    t_hi = float(np.ceil(oth["t_s"].max())) if len(oth) else float(sub["t_s"].max())
    scat = None
    for ax, name in zip(axes, names, strict=True):
        if roads is not None:
            roads(ax)
        else:
            _no_map(ax)
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
        if "continuation" in rider and rider["continuation"].astype(bool).any():
            # its run-in and run-out (vei.continuation): not recorded, marked
            cont = rider["continuation"].to_numpy(bool)
            ax.plot(
                np.where(cont, rider["x_m"].to_numpy(), np.nan),
                np.where(cont, rider["y_m"].to_numpy(), np.nan),
                "-",
                color="tab:green",
                lw=6.0,
                alpha=0.25,
                label="run-in / run-out",
                zorder=4,
            ).__getitem__(0).set_gid("continuation")
        _occluders(ax, run, ego, rider, other_id, ego_id, dims or {})
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
        for rows, size in ((ego, 22), (rider, 16)):
            t = rows["t_s"].to_numpy()
            on = _every_second(t, t_lo, t_hi)
            if on.any():
                scat = ax.scatter(rows["x_m"].to_numpy()[on], rows["y_m"].to_numpy()[on], c=t[on],
                                  cmap="viridis", vmin=t_lo, vmax=t_hi, s=size, zorder=7,
                                  edgecolors="black", linewidths=0.3)  # fmt: skip
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
        f"Bird's-eye view: ego (red), original keyframes (dashed black), simulated {other_id} (dashed green; "
        "shaded: its run-in / run-out); other road users' boxes at the collision or closest "
        "approach; dots every 1 s coloured by time",
        fontsize=10,
    )
    fig.tight_layout(rect=(0.0, 0.0, 0.92, 0.97))
    if scat is not None:
        cax = fig.add_axes((0.93, 0.15, 0.012, 0.7))
        fig.colorbar(scat, cax=cax, label="time [s]")
    return fig


def _key_time(ego: pd.DataFrame, rider: pd.DataFrame) -> float | None:
    """The panel's key moment [s]: the first collision, else the ego's and the rider's
    closest approach (None: the rider is never present)."""
    hit = rider[rider["collided"].astype(bool)]
    if len(hit):
        return float(hit["t_s"].iloc[0])
    both = rider.merge(ego, on="t_s", suffixes=("", "_ego"))
    if both.empty:
        return None
    d = np.hypot(both["x_m"] - both["x_m_ego"], both["y_m"] - both["y_m_ego"])
    return float(both["t_s"].iloc[int(np.argmin(d.to_numpy()))])


def _occluders(ax, run: pd.DataFrame, ego: pd.DataFrame, rider: pd.DataFrame, other_id: str,
               ego_id: str, dims: dict[str, tuple[float, float]]) -> None:  # fmt: skip
    """Every road user of ``run`` but the ego and the rider: its path (thin) and its box
    at the key moment (:func:`_key_time`; its last present pose before, if it is absent
    then)."""
    t_key = _key_time(ego, rider)
    others = run[~run["agent_id"].isin([ego_id, other_id]) & run["active"].astype(bool)]
    for agent_id, tr in others.groupby("agent_id", sort=True):
        tr = tr.sort_values("t_s")
        cat = str(tr["category"].iloc[0]) if "category" in tr else "vehicle"
        colour = CATEGORY_COLOURS.get(cat, "black")
        ax.plot(tr["x_m"].to_numpy(), tr["y_m"].to_numpy(), "-", color=colour, lw=0.8,
                alpha=0.6, label=f"_{agent_id} path", zorder=2)  # fmt: skip
        t = tr["t_s"].to_numpy()
        k = (
            0
            if t_key is None
            else int(np.clip(np.searchsorted(t, t_key + 1e-9) - 1, 0, t.size - 1))
        )
        length, width = dims.get(str(agent_id), DEFAULT_DIMS_M.get(cat, (4.5, 1.8)))
        row = tr.iloc[k]
        draw_box(ax, float(row["x_m"]), float(row["y_m"]), float(row["yaw_rad"]), length, width,
                 colour=colour, label=f"{agent_id} box", hatch="//" if cat == "vehicle" else None)  # fmt: skip


def _every_second(t: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """Mask of the samples nearest to each whole second in [lo, hi] (one per second)."""
    mask = np.zeros(t.size, dtype=bool)
    if t.size == 0:
        return mask
    for sec in np.arange(np.ceil(lo), np.floor(hi) + 1):
        k = int(np.argmin(np.abs(t - sec)))
        if abs(t[k] - sec) < 0.5 * (np.median(np.diff(t)) if t.size > 1 else 1.0) + 1e-9:
            mask[k] = True
    return mask


def _no_map(ax) -> None:
    """Say on a panel that no road network is drawn (the scenario has no map)."""
    from vei.maps.roads import draw_no_map_note

    draw_no_map_note(ax)
