"""The data of the catalogue's HTML report, read from a catalogue folder.

:func:`collect` gathers what the report shows (JSON-ready): the ranked encounters, the
recordings' status, and per encounter the recorded tracks, the replay arrays of every
case-study configuration over the interaction, the summary and the sweep's risk map.
:func:`write_report` renders it with :mod:`vei.report.html_report` (``vei report``).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.catalogue.store import MANIFEST, TABLE, encounter_dir, encounter_scores, read_json
from vei.errors import InputError

#: Replay rate in the report [Hz] (the engine's 20 Hz time series, every other step).
REPLAY_RATE_HZ = 10.0
#: Seconds of replay kept before / after the interaction (rider within 30 m of the ego, up to
#: a collision: vei.report.casestudy_figures.interaction_window).
REPLAY_MARGIN_S = 2.0
#: Overview columns: (key, header, format, title).
OVERVIEW_COLUMNS: tuple[tuple[str, str, str, str], ...] = (
    ("rank", "rank", "d", "criticality rank (1 = most critical)"),
    ("encounter_id", "encounter", "s", "recording__rider"),
    ("category", "rider", "s", "rider category"),
    ("rec_path_distance_m", "route dist [m]", ".2f", "closest approach of the routes (recorded)"),
    (
        "rec_pet_s",
        "PET [s]",
        ".2f",
        "post-encroachment time at the routes' closest point (recorded)",
    ),
    ("rec_min_gap_m", "rec. gap [m]", ".2f", "smallest same-time distance (recorded)"),
    ("time_shift_auto_s", "shift [s]", ".2f", "automatic time shift of the rider"),
    ("n_configs", "configs", "d", "simulated configurations (case study + sweep)"),
    (
        "n_flagged",
        "seen too late",
        "d",
        "configurations in which the rider was first seen too late for any planner "
        "(seen_too_late): counted apart, left out of every score",
    ),
    (
        "collision_share",
        "collision share",
        ".3f",
        "share of the unflagged configurations that collide",
    ),
    ("mean_safety_index", "mean SI", ".3f", "mean safety index over the unflagged configurations"),
    ("worst_min_gap_m", "worst gap [m]", ".2f", "smallest simulated box gap"),
    ("casestudy_collisions", "case-study collisions", "d", "of the paper's five configurations"),
)


def _tracks(scenario_dir: Path) -> dict[str, Any]:
    traj = pd.read_parquet(scenario_dir / "trajectories.parquet")
    out = {}
    for aid, g in traj.groupby("agent_id", sort=True):
        g = g.sort_values("t_s").iloc[::4]  # 5 Hz is plenty for a map
        out[str(aid)] = {
            "category": str(g["category"].iloc[0]),
            "x": g["x_m"].to_numpy(),
            "y": g["y_m"].to_numpy(),
            "t": g["t_s"].to_numpy(),
        }
    return out


def _roads(scenario_dir: Path) -> dict[str, Any] | None:
    """Outlines of the drivable lanes of the scenario's OpenDRIVE map (x, y [m] with None
    between lanes, each ring thinned to <= 80 points), or None without a map."""
    doc = read_json(scenario_dir / "scenario.json")
    name = (doc.get("maps") or {}).get("opendrive")
    if not name or not (scenario_dir / name).is_file():
        return None
    from vei.maps import load_roads

    xs: list[float | None] = []
    ys: list[float | None] = []
    for lane in load_roads(scenario_dir / name).drivable_lanes:
        ring = lane.outline
        ring = ring[:: max(1, len(ring) // 80)]
        ring = np.vstack([ring, ring[:1]])
        xs += [*ring[:, 0].tolist(), None]
        ys += [*ring[:, 1].tolist(), None]
    return {"x": xs, "y": ys} if xs else None


def _replay(
    edir: Path, rider_id: str, agents: dict[str, tuple[float, float]], safe: float, alert: float
) -> dict[str, Any]:
    """Per configuration the replay arrays over the interaction window at REPLAY_RATE_HZ."""
    ts = pd.read_parquet(edir / "casestudy" / "timeseries.parquet")
    ttc = pd.read_parquet(edir / "ttc.parquet")
    t_all = np.sort(ts["t_s"].unique())
    dt = float(np.median(np.diff(t_all))) if t_all.size > 1 else 0.05
    step = max(1, int(round(1.0 / (REPLAY_RATE_HZ * dt))))
    from vei.report.casestudy_figures import interaction_window

    win = interaction_window(ts, rider_id, margin_s=REPLAY_MARGIN_S)
    lo, hi = win if win is not None else (float(t_all[0]), float(t_all[-1]))
    grid = t_all[(t_all >= lo - 1e-9) & (t_all <= hi + 1e-9)][::step]
    configs = []
    for name, g in ts.groupby("config", sort=False):
        g = g[g["t_s"].isin(grid)]

        def agent(aid: str, g: pd.DataFrame = g) -> dict[str, Any]:
            a = g[g["agent_id"] == aid].set_index("t_s").reindex(grid)
            act = a["active"].fillna(False).astype(bool).to_numpy()
            return {
                "x": np.where(act, a["x_m"], np.nan),
                "y": np.where(act, a["y_m"], np.nan),
                "yaw": np.where(act, a["yaw_rad"], np.nan),
                "speed": np.where(act, a["speed_mps"], np.nan),
            }

        ego = agent("ego")
        ego_rows = g[g["agent_id"] == "ego"].set_index("t_s").reindex(grid)
        rider = agent(rider_id)
        others = {
            str(aid): {k: v for k, v in agent(str(aid)).items() if k in ("x", "y")}
            for aid in g["agent_id"].unique()
            if aid not in ("ego", rider_id)
        }
        tt = ttc[ttc["config"] == name].set_index("t_s")["ttc_s"]
        ttc_grid = tt.reindex(grid).to_numpy(np.float64)
        collided = ego_rows["collided"].fillna(False).astype(bool).to_numpy()
        zone = np.where(
            collided, 3, np.where(ttc_grid <= alert, 2, np.where(ttc_grid <= safe, 1, 0))
        )
        zone = np.where(np.isfinite(ttc_grid) | collided, zone, 0)
        full_ttc = tt.to_numpy(np.float64)
        configs.append(
            {
                "name": str(name),
                "ego": ego,
                "rider": rider,
                "others": others,
                "cap": ego_rows["cap_state"].fillna("").astype(str).tolist(),
                "zone": zone,
                "ttc": ttc_grid,
                "ttc_t": tt.index.to_numpy(np.float64),
                "ttc_full": np.where(np.isfinite(full_ttc), full_ttc, np.nan),
            }
        )
    return {
        "t": grid,
        "configs": configs,
        "dims": {k: list(v) for k, v in agents.items()},
        "window": [lo, hi],
    }


def _risk_map(rows: pd.DataFrame) -> dict[str, Any] | None:
    x, y = "p.time_shift_s", "p.ego.cruise_speed_mps"
    sw = rows[rows["kind"] == "sweep"]
    if len(sw) < 4 or x not in sw or y not in sw or sw[x].isna().all() or sw[y].isna().all():
        return None
    from vei.metrics.seen import flagged_mask

    flag = flagged_mask(sw)  # never coloured by: marked (points.flagged)
    xs_all, ys_all = sw[x].to_numpy(float), sw[y].to_numpy(float)
    n = int(np.clip(np.sqrt(len(sw) / 6.0), 3, 15))
    xe = np.linspace(xs_all.min(), xs_all.max(), n + 1)
    ye = np.linspace(ys_all.min(), ys_all.max(), n + 1)
    coll_all = sw["collision"].astype(bool).to_numpy()
    sw = sw[~flag]
    xs, ys = sw[x].to_numpy(float), sw[y].to_numpy(float)
    si = sw["safety_index"].to_numpy(float)
    fin = np.isfinite(si)  # NaN: the shifted rider never met the ego in the simulated span
    num, _, _ = np.histogram2d(xs[fin], ys[fin], bins=[xe, ye], weights=si[fin])
    n_si, _, _ = np.histogram2d(xs[fin], ys[fin], bins=[xe, ye])
    cnt, _, _ = np.histogram2d(xs, ys, bins=[xe, ye])
    col, _, _ = np.histogram2d(
        xs, ys, bins=[xe, ye], weights=sw["collision"].astype(float).to_numpy()
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(n_si > 0, num / n_si, np.nan)
        share = np.where(cnt > 0, col / cnt, np.nan)
    return {
        "x": 0.5 * (xe[:-1] + xe[1:]),
        "y": 0.5 * (ye[:-1] + ye[1:]),
        "z": mean.T,
        "share": share.T,
        "count": cnt.T,
        "count_si": n_si.T,
        "x_label": "time-shift offset to the automatic shift [s]",
        "y_label": "ego cruise speed [m/s]",
        "n": int(len(sw)),
        "n_flagged": int(flag.sum()),
        "points": {"x": xs_all, "y": ys_all, "collision": coll_all, "flagged": flag},
    }


def collect(catalogue_dir: str | Path) -> dict[str, Any]:
    """Everything the report shows, as one JSON-ready mapping (see the module docstring).

    Raises:
        InputError: not a catalogue folder (no catalogue.json / catalogue.parquet).
    """
    root = Path(catalogue_dir)
    if not (root / MANIFEST).is_file() or not (root / TABLE).is_file():
        raise InputError(
            "not a catalogue folder (catalogue.json and catalogue.parquet expected; run vei catalogue)",
            path=root,
        )
    manifest = read_json(root / MANIFEST)
    rows = pd.read_parquet(root / TABLE)
    enc = (
        encounter_scores(rows)
        if len(rows)
        else pd.DataFrame(columns=[c for c, *_ in OVERVIEW_COLUMNS])
    )
    encounters = []
    for rec in enc.to_dict("records"):
        eid = rec["encounter_id"]
        edir = encounter_dir(root, eid)
        summary = read_json(edir / "casestudy" / "summary.json")
        mcfg = summary.get("metrics_config", {})
        scen = read_json(edir / "scenario" / "scenario.json")
        dims = {a["agent_id"]: (a["length_m"], a["width_m"]) for a in scen["agents"]}
        er = rows[rows["encounter_id"] == eid]
        encounters.append(
            {
                "id": eid,
                "row": {c: rec.get(c) for c, *_ in OVERVIEW_COLUMNS},
                "rider_id": rec["rider_id"],
                "recording": rec["recording"],
                "tracks": _tracks(edir / "scenario"),
                "roads": _roads(edir / "scenario"),
                "replay": _replay(
                    edir,
                    rec["rider_id"],
                    dims,
                    mcfg.get("safe_ttc_s", 2.0),
                    mcfg.get("alert_ttc_s", 1.0),
                ),
                "summary": [
                    {
                        k: c.get(k)
                        for k in (
                            "name",
                            "collision",
                            "collision_time_s",
                            "safety_index",
                            "safety_index_rel",
                            "min_gap_m",
                            "min_ttc_s",
                            "peak_decel_mps2",
                            "ego_speed_std_mps",
                            "first_seen_gap_m",
                            "seen_too_late",
                        )
                    }
                    for c in summary["configs"]
                ],  # fmt: skip
                "time_shift_s": summary.get("time_shift_s"),
                "riskmap": _risk_map(er),
            }
        )
    recs = [
        {"recording": k, **{f: v.get(f) for f in ("status", "reason", "n_riders")},
         "encounters": ", ".join(e.split("__", 1)[-1] for e in v.get("encounters", []))}
        for k, v in sorted(manifest.get("recordings", {}).items())
    ]  # fmt: skip
    return {
        "dataset": manifest.get("dataset"),
        "status": manifest.get("status"),
        "n_rows": int(len(rows)),
        "settings": manifest.get("settings"),
        "recordings": recs,
        "failed_encounters": manifest.get("failed_encounters", []),
        "columns": [
            {"key": k, "label": lab, "fmt": f, "title": t} for k, lab, f, t in OVERVIEW_COLUMNS
        ],
        "encounters": encounters,
    }


def write_report(catalogue_dir: str | Path, out: str | Path | None = None) -> Path:
    """Write the catalogue's report.html (atomically); returns its path.

    Args:
        catalogue_dir: a catalogue folder (vei catalogue --out).
        out: HTML file; default ``catalogue_dir/report.html``.
    Raises:
        InputError: not a catalogue folder.
    """
    from vei.report.html_report import write_html

    data = collect(catalogue_dir)
    path = Path(out) if out is not None else Path(catalogue_dir) / "report.html"
    return write_html(data, path)
