"""The catalogue's HTML report: one self-contained file that works offline.

:func:`render` turns the report data (collected from a catalogue folder by
:func:`vei.catalogue.report_data.collect`) into ``report.html`` holding, embedded:

- plotly.js (the copy that ships in the ``plotly`` Python wheel; no CDN), the page's own
  script (``report/html/assets/report.js``) and style sheet, and the data as JSON;
- an overview table of the encounters, sortable by any column (criticality rank first),
  the recordings with their status (failed ones with the importer's reason);
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
from vei.io.atomic import write_text

ASSETS = Path(__file__).parent / "html" / "assets"


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
    # \u003c etc. are valid JSON escapes: no '</script>' or '<!--' can end the element
    return text.replace("<", "\\u003c").replace(">", "\\u003e").replace("&", "\\u0026")


def _fmt(v: Any, f: str) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "-"
    if f == "s":
        return html.escape(str(v))
    if f == "d":
        return str(int(v))
    return format(float(v), f)


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
<section id="overview-section"><h2>Encounters ranked by {html.escape(data.get("ranked_by", "criticality"))}</h2>
<p class="note">Click a column header to sort; click a row to open the encounter. {_ranking_note(data)}</p>
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
<div class="panel"><h3>Risk map</h3><div id="risk-plot" class="plot"></div></div>
<div class="panel"><h3>Risk: probabilities with 95 % confidence intervals, failure modes</h3><div id="prob-table"></div></div>
</div></section>
<script id="vei-data" type="application/json">{_script_json(data)}</script>
<script>{js}</script>
</body></html>
"""


def write_html(data: dict[str, Any], path: str | Path) -> Path:
    """Write the report page for ``data`` (vei.catalogue.report_data.collect) atomically."""
    return write_text(Path(path), render(data))
