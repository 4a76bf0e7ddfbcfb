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

from vei.catalogue.report_maps import catalogue_map, probability_map, risk_map
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
    (
        "recorded_collision_share",
        "on recorded",
        ".3f",
        "share of the unflagged configurations that collide with the rider on its recorded "
        "behaviour (not on vei's run-in or run-out)",
    ),
    (
        "recorded_share_ci",
        "on recorded 95 % CI",
        "s",
        "95 % Wilson interval of the share colliding on recorded behaviour",
    ),
    (
        "collisions_on_recorded",
        "of collisions on recorded",
        ".2f",
        "share of the collisions that happen on the rider's recorded behaviour; the rest "
        "happen on vei's synthetic continuations",
    ),
    ("mean_safety_index", "mean SI", ".3f", "mean safety index over the unflagged configurations"),
    ("worst_min_gap_m", "worst gap [m]", ".2f", "smallest simulated box gap"),
    ("casestudy_collisions", "case-study collisions", "d", "of the paper's five configurations"),
    (
        "secondary_share",
        "secondary share",
        ".3f",
        "share of configurations with a secondary collision (the ego rear-ended, the rider into "
        "another car, ...)",
    ),
    (
        "rear_end_share",
        "rear-end share",
        ".3f",
        "share of configurations in which a vehicle hit the ego from behind",
    ),
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


#: Road layers (sidewalks, lane borders, kerbs) are kept within this margin of the
#: encounter's tracks [m] (a city map holds thousands of lanes).
ROAD_LAYER_MARGIN_M = 60.0


def _road_layers(scenario_dir: Path) -> dict[str, Any]:
    """The map's layers under the report's map and replay, besides the drivable lanes of
    :func:`_roads`: ``sidewalks`` (outlines of the non-drivable lanes: sidewalks, bike
    lanes), ``lines`` (lane borders) and ``kerbs`` (vei.maps.roads.RoadGeometry.kerbs),
    each {x, y} [m] with None between pieces (thinned to <= 80 points a piece), kept within
    ROAD_LAYER_MARGIN_M of the tracks; or ``note`` (why nothing is drawn) without a map."""
    doc = read_json(scenario_dir / "scenario.json")
    name = (doc.get("maps") or {}).get("opendrive")
    if not name or not (scenario_dir / name).is_file():
        from vei.maps.roads import NO_MAP_NOTE

        return {"note": NO_MAP_NOTE}
    from vei.maps import load_roads

    roads = load_roads(scenario_dir / name)
    traj = pd.read_parquet(scenario_dir / "trajectories.parquet", columns=["x_m", "y_m"])
    m = ROAD_LAYER_MARGIN_M
    lo = np.array([traj["x_m"].min() - m, traj["y_m"].min() - m])
    hi = np.array([traj["x_m"].max() + m, traj["y_m"].max() + m])

    def pieces(lines: list[np.ndarray], closed: bool = False) -> dict[str, Any] | None:
        xs: list[float | None] = []
        ys: list[float | None] = []
        for line in lines:
            if len(line) < 2 or np.any(line.max(axis=0) < lo) or np.any(line.min(axis=0) > hi):
                continue
            pts = line[:: max(1, len(line) // 80)]
            if closed or len(pts) < 2 or not np.array_equal(pts[-1], line[-1]):
                pts = np.vstack([pts, line[-1:]])
            xs += [*np.round(pts[:, 0], 2).tolist(), None]
            ys += [*np.round(pts[:, 1], 2).tolist(), None]
        return {"x": xs, "y": ys} if xs else None

    return {
        "sidewalks": pieces([ln.outline for ln in roads.lanes if not ln.drivable], closed=True),
        "lines": pieces(list(roads.lane_borders)),
        "kerbs": pieces(list(roads.kerbs)),
    }


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


#: Overview columns of the risk estimate (issue 23), shown when the catalogue has one.
RISK_COLUMNS: tuple[tuple[str, str, str, str], ...] = (
    ("risk_expected_harm", "expected harm", ".2e",
     "probability x injury risk: the expected injury risk of the rider per encounter under "
     "the variation (the ranking's key)"),
    ("risk_harm_ci", "harm 95 % CI", "s", "95 % confidence interval of the expected harm"),
    ("risk_p_collision", "P(collision)", ".2e",
     "probability of a collision under the variation ('-' with only an upper bound)"),
    ("risk_p_collision_ci", "P 95 % CI", "s",
     "95 % confidence interval of P(collision) ('< x': no collision seen, upper bound)"),
    ("risk_p_collision_recorded_ci", "P(on recorded) 95 % CI", "s",
     "P(collision on the rider's recorded behaviour) with its 95 % interval (the collisions "
     "the recording itself supports; the rest happen on vei's run-in / run-out)"),
    ("risk_n_simulations", "risk sims", "d", "simulations of the risk estimate"),
)  # fmt: skip


def _value_ci_text(rec: dict[str, Any], name: str) -> str:
    """'2.6e-04 [2.2e-04, 3.1e-04]', '< 1.8e-03' with only an upper bound, '-' without."""
    v = rec.get(name)
    if v is None or not np.isfinite(v):
        return _ci_text(rec, name)
    return f"{v:.2e} {_ci_text(rec, name)}"


def _ci_text(rec: dict[str, Any], name: str) -> str:
    lo, hi = rec.get(f"{name}_lo"), rec.get(f"{name}_hi")
    v = rec.get(name)
    if v is None or not np.isfinite(v):
        return f"< {hi:.2e}" if hi is not None and np.isfinite(hi) else "-"
    return f"[{lo:.2e}, {hi:.2e}]"


def _risk_panel(edir: Path) -> tuple[dict[str, Any] | None, dict[str, Any] | None]:
    """(the risk estimate's figures as text, its probability map) of an encounter, from
    its ``risk/`` folder (vei risk); (None, None) without one."""
    path = edir / "risk" / "risk.json"
    if not path.is_file():
        return None, None
    doc = read_json(path)
    planners = []
    for p in doc.get("planners", []):
        figs = {}
        for key, label in (
            ("p_collision", "P(collision)"),
            ("p_injury_relevant_collision", "P(injury-relevant collision)"),
            ("expected_injury_risk", "expected injury risk (harm)"),
            ("p_seen_too_late", "P(seen too late)"),
        ):
            e = p.get(key) or {}
            lo, hi = (e.get("ci95") or [None, None])[:2]
            if e.get("upper_bound_only"):
                figs[label] = (
                    f"< {hi:.2e} (95 % upper bound, none in {e.get('n', 0):,})"
                    if hi is not None
                    else "-"
                )
            elif e.get("value") is not None:
                figs[label] = f"{e['value']:.3e} [{lo:.3e}, {hi:.3e}]"
            else:
                figs[label] = "-"
        modes = p.get("failure_modes") or {}
        planners.append({
            "policy": p.get("policy"), "method": p.get("method"),
            "n_simulations": p.get("n_simulations"), "figures": figs,
            "reliable": (p.get("p_collision") or {}).get("reliable", False),
            "notes": list(p.get("notes", [])),
            "kinds": [f"{k['kind']}: {100 * k['share_of_p_collision']:.0f} %" for k in modes.get("kinds", [])],
            "regions": [f"{r['rule']}: {100 * r['share_of_p_collision']:.0f} % of P(collision), "
                        f"P(collision | region) {r['p_collision_in_region']:.2g}"
                        for r in modes.get("regions", [])[:4]],
        })  # fmt: skip
    risk = {
        "planners": planners,
        "comparisons": [c.get("verdict", "") for c in doc.get("comparisons", [])],
        "variation": [
            f"{v['name']}: {v['distribution']}" for v in doc.get("variation_resolved", [])
        ],
    }
    return risk, probability_map(edir / "risk" / "samples.parquet", doc)


def collect_index(
    catalogue_dir: str | Path,
) -> tuple[dict[str, Any], list[dict[str, Any]], pd.DataFrame]:
    """What the report's index page shows, without the encounters' own data.

    Returns:
        (index, records, rows): ``index`` holds dataset, status, n_rows, settings,
        recordings, failed_encounters, columns, ranked_by and ``catalogue_map``
        (:func:`vei.catalogue.report_maps.catalogue_map`); ``records`` the ranked
        encounters (one mapping each, the overview's columns filled); ``rows``
        catalogue.parquet.
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
    columns = OVERVIEW_COLUMNS
    if "risk_expected_harm" in enc:
        columns = (OVERVIEW_COLUMNS[0], OVERVIEW_COLUMNS[1], OVERVIEW_COLUMNS[2],
                   *RISK_COLUMNS, *OVERVIEW_COLUMNS[3:])  # fmt: skip
    if "recorded_collision_share" not in enc:  # rows written before issue 31
        keep = {"recorded_collision_share", "recorded_share_ci", "collisions_on_recorded"}
        columns = tuple(c for c in columns if c[0] not in keep)
    records = enc.to_dict("records")
    for rec in records:
        if "recorded_collision_share" in rec:
            lo, hi = rec["recorded_collision_share_lo"], rec["recorded_collision_share_hi"]
            rec["recorded_share_ci"] = f"[{lo:.3f}, {hi:.3f}]" if lo == lo else "-"
        if "risk_expected_harm" in rec:
            rec["risk_harm_ci"] = _ci_text(rec, "risk_expected_harm")
            rec["risk_p_collision_ci"] = _ci_text(rec, "risk_p_collision")
            rec["risk_p_collision_recorded_ci"] = _value_ci_text(rec, "risk_p_collision_recorded")
    recs = [
        {"recording": k, **{f: v.get(f) for f in ("status", "reason", "n_riders")},
         "encounters": ", ".join(e.split("__", 1)[-1] for e in v.get("encounters", []))}
        for k, v in sorted(manifest.get("recordings", {}).items())
    ]  # fmt: skip
    index = {
        "dataset": manifest.get("dataset"),
        "status": manifest.get("status"),
        "n_rows": int(len(rows)),
        "settings": manifest.get("settings"),
        "recordings": recs,
        "failed_encounters": manifest.get("failed_encounters", []),
        "columns": [{"key": k, "label": lab, "fmt": f, "title": t} for k, lab, f, t in columns],
        "ranked_by": "expected harm" if "risk_expected_harm" in enc else "criticality",
        "catalogue_map": catalogue_map(rows),
    }
    return index, records, rows


_SUMMARY_KEYS = ("name", "collision", "collision_time_s", "safety_index", "safety_index_rel",
                 "min_gap_m", "min_ttc_s", "peak_decel_mps2", "ego_speed_std_mps",
                 "first_seen_gap_m", "seen_too_late")  # fmt: skip


def encounter_data(
    root: Path, rec: dict[str, Any], rows: pd.DataFrame, columns: list[dict[str, Any]]
) -> dict[str, Any]:
    """One encounter's data (the page loads it when the encounter is opened): its overview
    row, recorded tracks, map layers, replay, case-study summary, risk panel and maps.

    Args:
        root: the catalogue folder; rec: the encounter's record of :func:`collect_index`;
        rows: its catalogue rows; columns: the index's columns.
    """
    eid = rec["encounter_id"]
    edir = encounter_dir(root, eid)
    summary = read_json(edir / "casestudy" / "summary.json")
    mcfg = summary.get("metrics_config", {})
    scen = read_json(edir / "scenario" / "scenario.json")
    dims = {a["agent_id"]: (a["length_m"], a["width_m"]) for a in scen["agents"]}
    risk, probmap = _risk_panel(edir)  # issue 23
    return {
        "id": eid,
        "risk": risk,
        "probmap": probmap,
        "row": {c["key"]: rec.get(c["key"]) for c in columns},
        "rider_id": rec["rider_id"],
        "recording": rec["recording"],
        "tracks": _tracks(edir / "scenario"),
        "roads": _roads(edir / "scenario"),
        "road_layers": _road_layers(edir / "scenario"),
        "replay": _replay(
            edir, rec["rider_id"], dims, mcfg.get("safe_ttc_s", 2.0), mcfg.get("alert_ttc_s", 1.0)
        ),  # fmt: skip
        "summary": [{k: c.get(k) for k in _SUMMARY_KEYS} for c in summary["configs"]],
        "time_shift_s": summary.get("time_shift_s"),
        "riskmap": risk_map(rows),
    }


def _encounters(root: Path, records: list[dict[str, Any]], rows: pd.DataFrame, columns: list):
    """Yield :func:`encounter_data` of each record in rank order (rows grouped once)."""
    groups = rows.groupby("encounter_id", sort=False).indices if len(rows) else {}
    for rec in records:
        idx = groups.get(rec["encounter_id"], [])
        yield encounter_data(root, rec, rows.iloc[idx], columns)


def collect(catalogue_dir: str | Path) -> dict[str, Any]:
    """Everything the report shows, as one JSON-ready mapping: :func:`collect_index`'s
    index with ``encounters``, the :func:`encounter_data` of every encounter in rank order
    (held in memory: for a large catalogue :func:`write_report` streams them instead).

    Raises:
        InputError: not a catalogue folder (no catalogue.json / catalogue.parquet).
    """
    index, records, rows = collect_index(catalogue_dir)
    index["encounters"] = list(_encounters(Path(catalogue_dir), records, rows, index["columns"]))
    return index


def write_report(catalogue_dir: str | Path, out: str | Path | None = None) -> Path:
    """Write the catalogue's report (:mod:`vei.report.html_site`): the index page
    ``report.html`` and beside it ``report_files/`` (plotly.js, one script per encounter),
    streamed encounter by encounter (one encounter's data in memory at a time); returns
    the index page's path.

    Args:
        catalogue_dir: a catalogue folder (vei catalogue --out).
        out: the index page; default ``catalogue_dir/report.html``.
    Raises:
        InputError: not a catalogue folder.
    """
    from vei.report.html_site import write_site

    root = Path(catalogue_dir)
    index, records, rows = collect_index(root)
    path = Path(out) if out is not None else root / "report.html"
    encounters = _encounters(root, records, rows, index["columns"])
    return write_site(index, encounters, path).index
