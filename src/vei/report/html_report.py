"""The catalogue's HTML report: an index page that loads each encounter on demand, offline.

:func:`render` turns the index data (collected from a catalogue folder by
:func:`vei.catalogue.report_data.collect_index`) into ``report.html`` holding, embedded,
the page's own script (``report/html/assets/report.js``), its style sheet and the index
as JSON; plotly.js (the copy that ships in the ``plotly`` Python wheel; no CDN) and one
script per encounter lie beside it in ``report_files/`` (:mod:`vei.report.html_site`
writes them). The page shows:

- an overview table of the encounters, sortable by any column (criticality rank first),
  a page of rows at a time, the catalogue's risk map (P(collision | cell) over every
  encounter's sweep; known P = 0, known P > 0 and not known in colours far apart), the
  recordings with their status (failed ones with the importer's reason);
- per encounter: the map of all recorded tracks (the encounter's rider highlighted), an
  animated bird's-eye replay of each configuration (play / pause / time slider; ego and
  rider boxes, the other riders, the ego box coloured by the TTC zone, the CAP's state),
  ego and rider speed, the paper's TTC over time with its zones (time axes zoomed to the
  interaction), the case-study summary table, the risk map (with a risk estimate:
  P(collision | cell) where its 95 % interval is within +-0.1, the rest marked not known;
  else the sweep's mean safety index) and the risk estimate's figures with their 95 %
  intervals, failure kinds and regions (issue 23).

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

from vei.errors import DependencyError

ASSETS = Path(__file__).parent / "html" / "assets"


def plotly_js_path() -> Path:
    """plotly.min.js of the installed ``plotly`` wheel (the report copies it beside the page).

    Raises:
        DependencyError: plotly is not installed or lacks the bundle.
    """
    try:
        import plotly
    except ImportError as exc:
        raise DependencyError("the HTML report needs plotly: pip install 'vei[report]'") from exc
    path = Path(plotly.__file__).parent / "package_data" / "plotly.min.js"
    if not path.is_file():
        raise DependencyError(f"plotly.min.js not found in the plotly package ({path})")
    return path


def _round4(a: np.ndarray) -> np.ndarray:
    """4 decimals, but 4 significant digits below 0.01 (a probability of 2.6e-4 or 4e-7
    must not become 0.0003 or 0: a known 0 is drawn apart from a small P)."""
    with np.errstate(divide="ignore", invalid="ignore"):
        mag = np.abs(a)
        exp = np.floor(np.log10(np.where(mag > 0, mag, 1.0)))
        scale = 10.0 ** (3 - exp)
        small = np.round(a * scale) / scale
    return np.where((mag < 0.01) & (mag > 0), small, np.round(a, 4))


def _clean(v: Any) -> Any:
    if isinstance(v, dict):
        return {str(k): _clean(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_clean(x) for x in v]
    if isinstance(v, np.ndarray) and v.dtype.kind == "f":  # at once: 10^4 encounters' arrays
        a = _round4(v.astype(np.float64))
        bad = ~np.isfinite(a)
        if not bad.any():
            return a.tolist()
        obj = a.astype(object)
        obj[bad] = None
        return obj.tolist()
    if isinstance(v, np.ndarray):
        return [_clean(x) for x in v.tolist()]
    if isinstance(v, np.generic):
        v = v.item()
    if isinstance(v, float):
        return float(_round4(np.float64(v))) if math.isfinite(v) else None
    if v is pd.NA:
        return None
    return v


def _script_json(obj: Any) -> str:
    """JSON safe inside a <script> element."""
    text = json.dumps(_clean(obj), separators=(",", ":"), allow_nan=False)
    # \u003c etc. are valid JSON escapes: no '</script>' or '<!--' can end the element
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _ranking_note(data: dict[str, Any]) -> str:
    if data.get("ranked_by") == "expected harm":
        return (
            "Ranked by expected harm (probability &times; injury risk: the rider's expected injury "
            "risk under the variation, vei risk), then P(collision); encounters with only an upper "
            "bound (no collision seen) after those with an estimate. Intervals are 95 %."
        )
    return (
        "Criticality: share of simulated configurations that collide, then the lowest mean "
        "safety index, then the smallest gap."
    )


def render(data: dict[str, Any], files: str = "report_files") -> str:
    """The index page's HTML text: the ranked table, the catalogue's risk map and the
    encounter panels, for ``data`` = :func:`vei.catalogue.report_data.collect_index`'s
    index with ``encounters`` = :func:`vei.report.html_site.index_rows` (the table; the
    scripts the page loads on demand lie in its ``files`` folder, relative to the page).
    The table is drawn first; plotly.js is then loaded from ``files``/plotly.min.js (the
    maps and plots follow once it is)."""
    css = (ASSETS / "report.css").read_text(encoding="utf-8")
    js = (ASSETS / "report.js").read_text(encoding="utf-8")
    head = "".join(
        f'<th data-key="{c["key"]}" data-type="{"text" if c["fmt"] == "s" else "num"}" '
        f'title="{html.escape(c["title"])}">{html.escape(c["label"])}</th>'
        for c in data["columns"]
    )
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
    data = {**data, "plotly": f"{files}/plotly.min.js"}
    return f"""<!DOCTYPE html>
<html lang="en"><head><meta charset="utf-8">
<meta name="viewport" content="width=device-width, initial-scale=1">
<title>vei risk catalogue</title>
<style>{css}</style>
</head><body>
<header><h1>vei risk catalogue</h1>
<p>dataset <code>{html.escape(str(data["dataset"]))}</code> &middot; {len(data["encounters"]["ids"])} encounters &middot;
{data["n_rows"]} rows (encounter &times; configuration) &middot; status {html.escape(str(data["status"]))}</p></header>
<section id="overview-section"><h2>Encounters ranked by {html.escape(data.get("ranked_by", "criticality"))}</h2>
<p class="note">Click a column header to sort; click a row to open the encounter. {_ranking_note(data)}</p>
<div class="pager"><button id="page-prev" type="button">&lsaquo; previous</button>
<span id="page-label"></span><button id="page-next" type="button">next &rsaquo;</button></div>
<table id="overview"><thead><tr>{head}</tr></thead><tbody></tbody></table>
<div class="grid"><div class="panel"><h3>Risk map of the catalogue</h3><div id="catalogue-map" class="plot"></div></div>
<div class="panel"><h3>Recordings</h3>
<table id="recordings"><thead><tr><th>recording</th><th>status</th><th>encounters</th><th>reason</th></tr></thead>
<tbody>{recs}</tbody></table>
{"<h3>Failed encounters</h3><ul>" + failed + "</ul>" if failed else ""}</div></div>
</section>
<section id="encounter-section">
<h2>Encounter <select id="encounter-select"></select> <span id="encounter-status" class="note"></span></h2>
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
<div class="panel"><h3>Risk map</h3><div id="risk-plot" class="plot"></div></div>
<div class="panel"><h3>Risk: probabilities with 95 % confidence intervals, failure modes</h3><div id="prob-table"></div></div>
</div></section>
<script id="vei-data" type="application/json">{_script_json(data)}</script>
<script>{js}</script>
</body></html>
"""
