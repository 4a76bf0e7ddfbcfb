"""The catalogue's HTML report: one self-contained file that works offline.

``write_report(catalogue_dir)`` writes ``report.html`` holding, embedded:

- plotly.js (the copy that ships in the ``plotly`` Python wheel; no CDN), the page's own
  script (``report/html/assets/report.js``) and style sheet, and the data as JSON;
- an overview table of the encounters, sortable by any column (criticality rank first),
  the recordings with their status (failed ones with the importer's reason);
- per encounter: the map of all recorded tracks (the encounter's rider highlighted), an
  animated bird's-eye replay of each configuration (play / pause / time slider; ego and
  rider boxes, the other riders, the ego box coloured by the TTC zone, the CAP's state),
  ego and rider speed, the paper's TTC over time (time axes zoomed to the interaction) with its zones, the case-study summary
  table and the sweep's risk map (mean safety index over time-shift offset x cruise speed).

Why Plotly: a maintained library (MIT) whose full JavaScript bundle ships inside the Python
wheel, so the report embeds it and needs no network; it draws interactive maps, time
series and heatmaps with zoom and hover, and its figures are plain JSON that the page's
script updates in place (``Plotly.restyle``) for the replay. The replay is driven by our
own slider and timer rather than Plotly animation frames, which would copy every trace per
frame: the data of one configuration is embedded once and the boxes are computed in the
browser.
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.errors import DependencyError, InputError
from vei.io.atomic import write_text

ASSETS = Path(__file__).parent / "html" / "assets"
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
    ("collision_share", "collision share", ".3f", "share of configurations that collide"),
    ("mean_safety_index", "mean SI", ".3f", "mean safety index over the configurations"),
    ("worst_min_gap_m", "worst gap [m]", ".2f", "smallest simulated box gap"),
    ("casestudy_collisions", "case-study collisions", "d", "of the paper's five configurations"),
)


def _plotly_js() -> str:
    try:
        import plotly
    except ImportError as exc:
        raise DependencyError("the HTML report needs plotly: pip install 'vei[report]'") from exc
    path = Path(plotly.__file__).parent / "package_data" / "plotly.min.js"
    if not path.is_file():
        raise DependencyError(f"plotly.min.js not found in the plotly package ({path})")
    return path.read_text(encoding="utf-8")


def _clean(v: Any) -> Any:
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_clean(x) for x in v]
    if isinstance(v, np.ndarray):
        return [_clean(x) for x in v.tolist()]
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float):
        return round(v, 4) if math.isfinite(v) else None
    if v is pd.NA:
        return None
    return v


def _script_json(obj: Any) -> str:
    """JSON safe inside a <script> element."""
    text = json.dumps(_clean(obj), separators=(",", ":"), allow_nan=False)
    return text.replace("</", "<\\/").replace("<!--", "<\\!--")


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
    xs, ys = sw[x].to_numpy(float), sw[y].to_numpy(float)
    n = int(np.clip(np.sqrt(len(sw) / 6.0), 3, 15))
    xe = np.linspace(xs.min(), xs.max(), n + 1)
    ye = np.linspace(ys.min(), ys.max(), n + 1)
    si = sw["safety_index"].to_numpy(float)
    num, _, _ = np.histogram2d(xs, ys, bins=[xe, ye], weights=si)
    cnt, _, _ = np.histogram2d(xs, ys, bins=[xe, ye])
    col, _, _ = np.histogram2d(
        xs, ys, bins=[xe, ye], weights=sw["collision"].astype(float).to_numpy()
    )
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = np.where(cnt > 0, num / cnt, np.nan)
        share = np.where(cnt > 0, col / cnt, np.nan)
    return {
        "x": 0.5 * (xe[:-1] + xe[1:]),
        "y": 0.5 * (ye[:-1] + ye[1:]),
        "z": mean.T,
        "share": share.T,
        "count": cnt.T,
        "x_label": "time-shift offset to the automatic shift [s]",
        "y_label": "ego cruise speed [m/s]",
        "n": int(len(sw)),
        "points": {"x": xs, "y": ys, "collision": sw["collision"].astype(bool).to_numpy()},
    }


def collect(catalogue_dir: str | Path) -> dict[str, Any]:
    """Everything the report shows, as one JSON-ready mapping (see the module docstring).

    Raises:
        InputError: not a catalogue folder (no catalogue.json / catalogue.parquet).
    """
    from vei.catalogue.store import MANIFEST, TABLE, encounter_dir, read_json

    root = Path(catalogue_dir)
    if not (root / MANIFEST).is_file() or not (root / TABLE).is_file():
        raise InputError(
            "not a catalogue folder (catalogue.json and catalogue.parquet expected; run vei catalogue)",
            path=root,
        )
    manifest = read_json(root / MANIFEST)
    rows = pd.read_parquet(root / TABLE)
    from vei.catalogue.store import encounter_scores

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
                            "min_gap_m",
                            "min_ttc_s",
                            "peak_decel_mps2",
                            "ego_speed_std_mps",
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


def _fmt(v: Any, f: str) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if f == "s":
        return html.escape(str(v))
    if f == "d":
        return str(int(v))
    return format(float(v), f)


def render(data: dict[str, Any]) -> str:
    """The report's HTML text for the data of :func:`collect`."""
    css = (ASSETS / "report.css").read_text(encoding="utf-8")
    js = (ASSETS / "report.js").read_text(encoding="utf-8")
    head = "".join(
        f'<th data-key="{c["key"]}" data-type="{"text" if c["fmt"] == "s" else "num"}" '
        f'title="{html.escape(c["title"])}">{html.escape(c["label"])}</th>'
        for c in data["columns"]
    )
    body = []
    for e in data["encounters"]:
        cells = "".join(
            f'<td data-value="{html.escape(str(e["row"].get(c["key"])))}">{_fmt(e["row"].get(c["key"]), c["fmt"])}</td>'
            for c in data["columns"]
        )
        body.append(f'<tr data-encounter="{html.escape(e["id"])}">{cells}</tr>')
    recs = "".join(
        f'<tr class="{html.escape(str(r["status"]))}"><td>{html.escape(r["recording"])}</td>'
        f"<td>{html.escape(str(r['status']))}</td><td>{html.escape(r['encounters'] or '-')}</td>"
        f"<td>{html.escape(str(r.get('reason') or ''))}</td></tr>"
        for r in data["recordings"]
    )
    failed = "".join(
        f"<li>{html.escape(f['encounter_id'])}: {html.escape(f['reason'])}</li>"
        for f in data["failed_encounters"]
    )
    options = "".join(
        f'<option value="{html.escape(e["id"])}">#{e["row"]["rank"]} {html.escape(e["id"])}</option>'
        for e in data["encounters"]
    )
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>vei risk catalogue</title>
<style>{css}</style>
<script>{_plotly_js()}</script>
</head><body>
<header><h1>vei risk catalogue</h1>
<p>dataset <code>{html.escape(str(data["dataset"]))}</code> &middot; {len(data["encounters"])} encounters &middot;
{data["n_rows"]} rows (encounter &times; configuration) &middot; status {html.escape(str(data["status"]))}</p></header>
<section id="overview-section"><h2>Encounters ranked by criticality</h2>
<p class="note">Click a column header to sort; click a row to open the encounter. Criticality: share of
simulated configurations that collide, then the lowest mean safety index, then the smallest gap.</p>
<table id="overview"><thead><tr>{head}</tr></thead><tbody>{"".join(body)}</tbody></table>
<h3>Recordings</h3>
<table id="recordings"><thead><tr><th>recording</th><th>status</th><th>encounters</th><th>reason</th></tr></thead>
<tbody>{recs}</tbody></table>
{"<h3>Failed encounters</h3><ul>" + failed + "</ul>" if failed else ""}
</section>
<section id="encounter-section">
<h2>Encounter <select id="encounter-select">{options}</select></h2>
<div class="grid">
<div class="panel"><h3>Map: all recorded tracks</h3><div id="map-plot" class="plot"></div></div>
<div class="panel"><h3>Bird's-eye replay</h3>
<div class="controls"><select id="config-select"></select>
<button id="play-button" type="button">play</button>
<input id="time-slider" type="range" min="0" max="0" step="1" value="0">
<span id="time-label"></span> <span id="cap-label" class="badge"></span> <span id="zone-label" class="badge"></span></div>
<div id="replay-plot" class="plot"></div></div>
<div class="panel"><h3>Ego and rider speed</h3><div id="speed-plot" class="plot"></div></div>
<div class="panel"><h3>TTC over time (paper: D / v<sub>ego</sub>)</h3><div id="ttc-plot" class="plot"></div></div>
<div class="panel"><h3>Case study summary</h3><div id="summary-table"></div></div>
<div class="panel"><h3>Risk map of the sweep</h3><div id="risk-plot" class="plot"></div></div>
</div></section>
<script id="vei-data" type="application/json">{_script_json(data)}</script>
<script>{js}</script>
</body></html>
"""


def write_report(catalogue_dir: str | Path, out: str | Path | None = None) -> Path:
    """Write the catalogue's report.html (atomically); returns its path.

    Args:
        catalogue_dir: a catalogue folder (vei catalogue --out).
        out: HTML file; default ``catalogue_dir/report.html``.
    """
    data = collect(catalogue_dir)
    path = Path(out) if out is not None else Path(catalogue_dir) / "report.html"
    return write_text(path, render(data))
