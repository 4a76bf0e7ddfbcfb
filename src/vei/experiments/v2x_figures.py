"""Figures and summary of the V2X case study (:mod:`vei.experiments.v2x_study`).

Every figure is a ``matplotlib.figure.Figure`` (no pyplot state), saved atomically as PNG
and PDF (a vector copy for a paper). Collision shares are over the variants of a sweep
cell: the time shifts of the occlusion window (the shifts at which perception alone
collides), each with its own random draws; they are conditional shares of this scene, not
probabilities of a crash in traffic, and the figures say so.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.experiments.v2x_study import COMPARED, collision_share, occluded_crossing, study_case
from vei.report.casestudy_figures import save_figure

_FORMATS = ("pdf",)
_NOTE = "share of time shifts in the occlusion window that collide (synthetic scene)"


def _figure(size: tuple[float, float]) -> Any:
    from matplotlib.figure import Figure

    return Figure(figsize=size, layout="constrained")


def plot_comparison(table: pd.DataFrame, window: tuple[float, float]) -> Any:
    """Collision or not at every time shift, one row per compared configuration."""
    fig = _figure((7.5, 2.8))
    ax = fig.add_subplot()
    labels = list(COMPARED)
    for i, label in enumerate(labels):
        hit = table[label].to_numpy(bool)
        x = table["time_shift_s"].to_numpy()
        ax.scatter(x[hit], np.full(hit.sum(), i), marker="|", s=120, color="tab:red")
        ax.scatter(x[~hit], np.full((~hit).sum(), i), marker="|", s=40, color="0.75")
    ax.axvspan(window[0], window[1], color="tab:orange", alpha=0.15, lw=0)
    ax.set_yticks(range(len(labels)), labels)
    ax.invert_yaxis()
    ax.set_xlabel("rider time shift [s] (red: collision; band: occlusion window)")
    ax.set_title("Occluded crossing: collisions by time shift")
    return fig


def plot_latency_pdr(results: pd.DataFrame) -> Any:
    """Heat map of the collision share over latency x packet-delivery factor."""
    share = collision_share(results, ["v2x.latency_s", "v2x.pdr_factor"])
    lat = np.sort(share["v2x.latency_s"].unique())
    pdr = np.sort(share["v2x.pdr_factor"].unique())[::-1]
    grid = np.full((pdr.size, lat.size), np.nan)
    for row in share.itertuples(index=False):
        i = int(np.flatnonzero(pdr == row[1])[0])
        j = int(np.flatnonzero(lat == row[0])[0])
        grid[i, j] = row.share
    fig = _figure((7.0, 5.0))
    ax = fig.add_subplot()
    im = ax.imshow(grid, cmap="Reds", vmin=0.0, vmax=1.0, aspect="auto")
    for i in range(pdr.size):
        for j in range(lat.size):
            v = grid[i, j]
            ax.text(j, i, f"{v:.2f}", ha="center", va="center", fontsize=7,
                    color="white" if v > 0.6 else "black")  # fmt: skip
    ax.set_xticks(range(lat.size), [f"{v:g}" for v in lat])
    ax.set_yticks(range(pdr.size), [f"{v:g}" for v in pdr])
    ax.set_xlabel("V2X latency, fixed part [s]")
    ax.set_ylabel("pdr_factor (x each link's delivery ratio)")
    ax.set_title("Perception + V2X: collision share (synthetic occluded crossing)")
    fig.colorbar(im, ax=ax, label="collision share in the occlusion window", shrink=0.85)
    return fig


def _share_line(results: pd.DataFrame, column: str, xlabel: str, title: str) -> Any:
    share = collision_share(results, [column])
    fig = _figure((6.0, 3.6))
    ax = fig.add_subplot()
    x = share[column].to_numpy()
    ax.fill_between(x, share["lo"], share["hi"], color="tab:blue", alpha=0.2, lw=0,
                    label="95 % Wilson interval")  # fmt: skip
    ax.plot(x, share["share"], "o-", color="tab:blue", label="collision share")
    ax.set_ylim(-0.02, 1.02)
    ax.set_xlabel(xlabel)
    ax.set_ylabel("collision share")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8, title=_NOTE, title_fontsize=7)
    return fig


def plot_penetration(results: pd.DataFrame) -> Any:
    """Collision share against the share of equipped riders, and its expectation."""
    fig = _share_line(results, "v2x.penetration_rate", "penetration rate (share of riders "
                      "equipped)", "Collision share against V2X penetration")  # fmt: skip
    share = collision_share(results, ["v2x.penetration_rate"])
    p = share["v2x.penetration_rate"].to_numpy()
    s0, s1 = float(share["share"].iloc[0]), float(share["share"].iloc[-1])
    ax = fig.axes[0]
    ax.plot(p, (1 - p) * s0 + p * s1, "--", color="0.4",
            label="(1 - p) share(p=0) + p share(p=1)")  # fmt: skip
    ax.legend(loc="best", fontsize=8, title=_NOTE, title_fontsize=7)
    return fig


def plot_gnss(results: pd.DataFrame) -> Any:
    """Collision share against the rider's GNSS error."""
    return _share_line(results, "v2x.position_error_std_m", "rider's GNSS error per axis, "
                       "1 sigma [m]", "Collision share against GNSS accuracy")  # fmt: skip


def plot_case(shift_s: float) -> Any:
    """Ego speed and its distance to the rider over time at one shift: perception alone
    against perception + V2X (corrected GNSS)."""
    from vei.config import SimConfig
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario

    arrays = prepare_scenario(occluded_crossing(), SimConfig())
    fig = _figure((7.0, 4.6))
    ax1, ax2 = fig.subplots(2, 1, sharex=True)
    for label, colour in (("perception alone", "tab:red"),
                          ("perception + V2X (corrected GNSS)", "tab:blue")):  # fmt: skip
        perceived, v2x = COMPARED[label]
        case = study_case(v2x)
        p = VariantParams.from_case(case, arrays, 1, time_shift_s=shift_s)
        r = simulate(arrays, p.with_values(labels=np.array([f"shift{shift_s:+.3f}"], dtype=object)))
        t = arrays.t_s
        dist = np.hypot(r.rider_x_m[0] - r.ego_x_m[0], r.rider_y_m[0] - r.ego_y_m[0])
        ax1.plot(t, r.ego_speed_mps[0], color=colour, label=label)
        ax2.plot(t, dist, color=colour)
        tc = r.collision_time_s[0]
        if np.isfinite(tc):
            ax1.axvline(tc, color=colour, ls=":", lw=1)
            ax2.axvline(tc, color=colour, ls=":", lw=1)
    ax1.set_ylabel("ego speed [m/s]")
    ax1.legend(fontsize=8)
    ax1.set_title(f"Occluded crossing at time shift {shift_s:+.2f} s (dotted: collision)")
    ax2.set_ylabel("ego-rider centre distance [m]")
    ax2.set_xlabel("t [s]")
    ax2.set_ylim(0, 40)
    for ax in (ax1, ax2):
        ax.grid(alpha=0.3)
    return fig


def plot_scene() -> Any:
    """The scene from above (x 0..75 m): the car's path, the van's box, the rider waiting
    ahead of it, and the rider -> car link from the car's position every second until the
    car passes the van (perception alone at the window's middle shift: the same car path
    up to its braking), coloured by its state (vei.policy.v2x.links: NLOSv where the van's
    box crosses it), with the ITS-G5 delivery ratio of the link budget at the mean blockage
    loss (vei.policy.v2x.channel.link_pdr)."""
    from vei.experiments import v2x_study as st
    from vei.policy.v2x import channel as ch
    from vei.policy.v2x.links import blocker_heights_m, tallest_blocker_m
    from vei.report.birdseye import plot_birdseye
    from vei.types import EGO_ID

    sc = occluded_crossing()
    fig = _figure((9.0, 3.6))
    ax = fig.add_subplot()
    plot_birdseye(sc, ax=ax, time_dots=False, title="Occluded crossing: the scene and its V2X link")
    van = sc.agent("van")
    vx, vy = st.VAN_FRONT_X_M - van.length_m / 2.0, st.VAN_Y_M
    rx, ry = st.CROSSING_X_M, st.RIDER_WAIT_Y_M
    ego = sc.track(EGO_ID)
    h = blocker_heights_m(np.array([van.length_m]), 5.5)
    for t in range(0, 8):
        row = ego.iloc[int(np.argmin(np.abs(ego["t_s"].to_numpy() - t)))]
        ex, ey = float(row["x_m"]), float(row["y_m"])
        if ex > st.VAN_FRONT_X_M:
            break
        blocked = tallest_blocker_m(
            np.array([rx]), np.array([ry]), np.array([ex]), np.array([ey]),
            np.array([[vx]]), np.array([[vy]]), np.zeros((1, 1)), np.array([[van.length_m]]),
            np.array([[van.width_m]]), h[None, :], np.ones((1, 1), bool),
        )[0] > 0.0  # fmt: skip
        state = ch.NLOSV if blocked else ch.LOS
        mean, _ = ch.blockage_stats_db(np.array([max(rx - ex, 3.0)]), 1.5, 1.6, h)
        pdr = float(ch.link_pdr(np.array([np.hypot(rx - ex, ry - ey)]), np.array([state]),
                                "its-g5", blockage_db=mean if blocked else 0.0)[0])  # fmt: skip
        ax.plot([ex, rx], [ey, ry], "--" if blocked else "-", lw=0.8,
                color="tab:red" if blocked else "tab:green",
                label=f"_link {t} s")  # fmt: skip
        ax.annotate(f"{t} s: {ch.LINK_STATES[state]}, PDR {pdr:.2f}", (ex, ey),
                    textcoords="offset points", xytext=(0, 6 + 7 * (t % 2)), fontsize=6,
                    rotation=0, ha="center")  # fmt: skip
    legend = ax.get_legend()
    if legend is not None:
        legend.set_loc("lower center")
    ax.set_xlim(-2, 75)
    ax.set_ylim(-8, 8)
    ax.set_aspect("equal", adjustable="box")
    return fig


def write_figures(
    out_dir: Path, table: pd.DataFrame, window: tuple[float, float], sweeps: dict[str, Path]
) -> list[Path]:
    """Every study figure into ``out_dir`` (PNG + PDF); returns the PNG paths."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    res = {k: pd.read_parquet(Path(v) / "results.parquet") for k, v in sweeps.items()}
    mid = float(table.loc[table["perception alone"], "time_shift_s"].median())
    figs = {
        "v2x_scene.png": plot_scene(),
        "v2x_comparison.png": plot_comparison(table, window),
        "v2x_case.png": plot_case(mid),
        "v2x_riskmap_latency_pdr.png": plot_latency_pdr(res["latency_pdr"]),
        "v2x_penetration.png": plot_penetration(res["penetration"]),
        "v2x_gnss.png": plot_gnss(res["gnss"]),
    }
    return [save_figure(f, out_dir / name, also=_FORMATS) for name, f in figs.items()]


def summarise(table: pd.DataFrame, window: tuple[float, float], sweeps: dict[str, Path]) -> dict:
    """summary.json: the window, collisions per compared configuration (all shifts and in
    the window) and each sweep's collision shares."""
    inside = table[(table["time_shift_s"] >= window[0]) & (table["time_shift_s"] <= window[1])]
    out: dict[str, Any] = {
        "scene": "synthetic occluded crossing (vei.experiments.v2x_study.occluded_crossing)",
        "occlusion_window_s": list(window),
        "shifts": int(len(table)),
        "shifts_in_window": int(len(inside)),
        "collisions": {k: int(table[k].sum()) for k in COMPARED},
        "collisions_in_window": {k: int(inside[k].sum()) for k in COMPARED},
        "note": _NOTE,
        "sweeps": {},
    }
    axes = {"latency_pdr": ["v2x.latency_s", "v2x.pdr_factor"],
            "penetration": ["v2x.penetration_rate"], "gnss": ["v2x.position_error_std_m"]}  # fmt: skip
    for name, folder in sweeps.items():
        res = pd.read_parquet(Path(folder) / "results.parquet")
        share = collision_share(res, axes[name])
        out["sweeps"][name] = {
            "folder": f"sweeps/{name}",
            "variants": int(len(res)),
            "share": share.to_dict(orient="records"),
        }
    return out


__all__ = [
    "plot_case",
    "plot_scene",
    "plot_comparison",
    "plot_gnss",
    "plot_latency_pdr",
    "plot_penetration",
    "summarise",
    "write_figures",
]
