/* vei catalogue report: sortable overview, per-encounter plots, bird's-eye replay. */
(function () {
  "use strict";
  var T0 = performance.now();  /* plotly.js and the page are parsed by now */
  var DATA = JSON.parse(document.getElementById("vei-data").textContent);
  var T_JSON = performance.now();
  var COLOURS = { "replay": "#7f7f7f", "normal": "#1f77b4", "aggressive": "#d62728",
                  "normal-cap": "#2ca02c", "aggressive-cap": "#ff7f0e" };
  var PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b"];
  var ZONE_FILL = ["rgba(46,125,50,0.55)", "rgba(251,192,45,0.7)", "rgba(239,108,0,0.75)", "rgba(198,40,40,0.85)"];
  var ZONE_NAME = ["TTC safe (> 2 s)", "TTC attention (1-2 s]", "TTC alert (0-1 s]", "collision"];
  var state = { enc: null, cfg: 0, k: 0, timer: null };
  window.veiReport = { data: DATA, state: state };

  function colour(name, i) { return COLOURS[name] || PALETTE[i % PALETTE.length]; }
  function num(v) { return (v === null || v === undefined || v === "None" || v === "nan" || v === "") ? NaN : Number(v); }

  /* ---------------- overview table (a page of rows at a time) ---------------- */
  var PAGE = 25;
  /* DATA.encounters: {ids [N], values [N][C] in the columns' order, files}: rows as objects */
  var COLS = DATA.columns, INDEX = {};
  var ROWS = DATA.encounters.ids.map(function (id, i) {
    var row = {}, v = DATA.encounters.values[i];
    for (var c = 0; c < COLS.length; c++) { row[COLS[c].key] = v[c]; }
    INDEX[id] = i;
    return { id: id, row: row, file: DATA.encounters.files + String(i).padStart(5, "0") + ".js" };
  });
  window.veiReport.rows = ROWS;
  var view = { order: ROWS.map(function (_, i) { return i; }), page: 0 };
  function fmt(v, f) {
    if (v === null || v === undefined || (typeof v === "number" && !isFinite(v))) { return "-"; }
    if (f === "s") { return String(v); }
    if (f === "d") { return String(Math.trunc(Number(v))); }
    var m = /^\.(\d+)([fe])$/.exec(f);
    if (!m) { return String(v); }
    return m[2] === "e" ? Number(v).toExponential(Number(m[1])) : Number(v).toFixed(Number(m[1]));
  }
  function renderPage() {
    var n = ROWS.length, pages = Math.max(1, Math.ceil(n / PAGE));
    view.page = Math.max(0, Math.min(view.page, pages - 1));
    var lo = view.page * PAGE, hi = Math.min(n, lo + PAGE), h = [];
    for (var k = lo; k < hi; k++) {
      var r = ROWS[view.order[k]];
      var sel = state.enc && state.enc.id === r.id ? " class=\"selected\"" : "";
      h.push("<tr data-encounter=\"" + esc(r.id) + "\"" + sel + ">" + COLS.map(function (c) {
        var v = r.row[c.key];
        return "<td data-value=\"" + esc(v === null || v === undefined ? "None" : v) + "\">" + esc(fmt(v, c.fmt)) + "</td>";
      }).join("") + "</tr>");
    }
    document.querySelector("#overview tbody").innerHTML = h.join("");
    document.getElementById("page-label").textContent = n ? " rows " + (lo + 1) + "-" + hi + " of " + n + " " : " no encounter ";
    document.getElementById("page-prev").disabled = view.page === 0;
    document.getElementById("page-next").disabled = view.page >= pages - 1;
  }
  function sortTable(th) {
    var key = th.getAttribute("data-key"), asc = !th.classList.contains("asc");
    Array.prototype.forEach.call(th.parentNode.children, function (h) { h.classList.remove("asc", "desc"); });
    th.classList.add(asc ? "asc" : "desc");
    var text = th.getAttribute("data-type") === "text";
    view.order.sort(function (a, b) {
      var va = ROWS[a].row[key], vb = ROWS[b].row[key];
      if (text) { va = String(va); vb = String(vb); return asc ? va.localeCompare(vb) : vb.localeCompare(va); }
      var na = num(va), nb = num(vb);
      if (isNaN(na) && isNaN(nb)) { return 0; }
      if (isNaN(na)) { return 1; }
      if (isNaN(nb)) { return -1; }
      return asc ? na - nb : nb - na;
    });
    view.page = 0;
    renderPage();
  }
  Array.prototype.forEach.call(document.querySelectorAll("#overview th"), function (th) {
    th.addEventListener("click", function () { sortTable(th); });
  });
  document.querySelector("#overview tbody").addEventListener("click", function (ev) {
    var tr = ev.target.closest("tr");
    if (tr) { showEncounter(tr.getAttribute("data-encounter")); }
  });
  document.getElementById("page-prev").addEventListener("click", function () { view.page -= 1; renderPage(); });
  document.getElementById("page-next").addEventListener("click", function () { view.page += 1; renderPage(); });

  /* ---------------- encounters, loaded on demand ---------------- */
  /* Each encounter's data is a script beside the page (report_files/enc/NNNNN.js) that
     calls veiReport.receive(i, data): a <script src> loads from a file:// folder, where
     Chromium blocks fetch() of a JSON file. At most CACHE encounters are kept. */
  var CACHE = 20, cache = {}, cached = [], waiting = {};
  /* An encounter's script passes its data packed (vei.report.packing): zlib-deflated
     [uint32 JSON length][JSON {data, arrays: [[n, width, scale, order, origin, nan_runs],
     ...]}, packed array k as {"$a": k}][the arrays' integers one after the other], the bytes as they are in the
     script's string (loaded as x-user-defined text); inflated by the browser
     (DecompressionStream, no fetch: works on file://), arrays rebuilt as plain arrays. */
  function unpackArray(s, dv, off) {
    var n = s[0], w = s[1], scale = s[2], order = s[3], o = s[4], runs = s[5];
    var a = new Array(n), d1 = 0, q = 0, k, d;
    for (k = 0; k < n; k++) {
      d = w === 1 ? dv.getInt8(off + k) : (w === 2 ? dv.getInt16(off + 2 * k, true) : dv.getInt32(off + 4 * k, true));
      if (order === 2) { d1 += d; q += d1; } else if (order === 1) { q += d; } else { q = d; }
      a[k] = (o + q) / scale;
    }
    runs.forEach(function (r) { for (k = r[0]; k < r[0] + r[1]; k++) { a[k] = null; } });
    return a;
  }
  function revive(v, at) {  /* at(k): packed array k */
    if (Array.isArray(v)) { return v.map(function (x) { return revive(x, at); }); }
    if (v === null || typeof v !== "object") { return v; }
    if (typeof v.$a === "number" && Object.keys(v).length === 1) { return at(v.$a); }
    var out = {};
    Object.keys(v).forEach(function (key) { out[key] = revive(v[key], at); });
    return out;
  }
  function unpack(text) {
    /* the script is read as x-user-defined: one character per byte (0x80-0xFF as U+F780-U+F7FF) */
    var u8 = new Uint8Array(text.length);
    for (var k = 0; k < text.length; k++) { u8[k] = text.charCodeAt(k) & 0xFF; }
    var stream = new Blob([u8]).stream().pipeThrough(new DecompressionStream("deflate"));
    return new Response(stream).arrayBuffer().then(function (buf) {
      var dv = new DataView(buf), n = dv.getUint32(0, true);
      var doc = JSON.parse(new TextDecoder().decode(new Uint8Array(buf, 4, n)));
      var offsets = [4 + n];  /* the arrays' bytes one after the other */
      doc.arrays.forEach(function (s, k) { offsets.push(offsets[k] + s[0] * s[1]); });
      var e = revive(doc.data, function (k) { return unpackArray(doc.arrays[k], dv, offsets[k]); });
      ((e.replay || {}).configs || []).forEach(function (c) {
        if (!c.ttc_from_full) { return; }  /* the TTC at the replay's times: from the full series */
        var at = {};
        c.ttc_t.forEach(function (t, j) { at[Math.round(t * 1000)] = c.ttc_full[j]; });
        c.ttc = e.replay.t.map(function (t) { var v = at[Math.round(t * 1000)]; return v === undefined ? null : v; });
        delete c.ttc_from_full;
      });
      return e;
    });
  }
  window.veiReport.unpack = unpack;
  /* A script beside the page, read as x-user-defined (packed bytes: one character each,
     vei.report.packing); removed once run. */
  function addScript(src, failed) {
    var s = document.createElement("script");
    s.charset = "x-user-defined";
    s.src = src;
    s.onload = function () { s.remove(); };
    s.onerror = function () {
      s.remove(); failed();
      document.getElementById("encounter-status").textContent = "could not load " + src + " (is the report_files folder beside the page?)";
    };
    document.head.appendChild(s);
  }
  function failedUnpack(what) {
    return function (err) { document.getElementById("encounter-status").textContent = "could not unpack " + what + ": " + err; };
  }
  /* Map layers (drivable lanes, sidewalks, lane borders, kerbs) are a script of their own
     (enc/map_KEY.js, veiReport.receiveMap), shared by the encounters whose layers are the
     same (those of one recording) and loaded once. */
  var maps = {}, mapWaiting = {};
  function receiveMap(key, text) {
    unpack(text).then(function (m) {
      maps[key] = m;
      var w = mapWaiting[key] || []; delete mapWaiting[key];
      w.forEach(function (f) { f(m); });
    }, failedUnpack("map " + key));
  }
  function withMap(e, then) {
    var attach = function (m) { e.roads = m.roads; e.road_layers = m.road_layers; then(e); };
    if (!e.map) { then(e); return; }
    if (maps[e.map]) { attach(maps[e.map]); return; }
    var first = !mapWaiting[e.map];
    (mapWaiting[e.map] = mapWaiting[e.map] || []).push(attach);
    if (first) { addScript(DATA.encounters.files + "map_" + e.map + ".js", function () { delete mapWaiting[e.map]; }); }
  }
  function receive(i, e) {
    if (typeof e === "string") {
      unpack(e).then(function (d) { receive(i, d); }, function (err) { delete waiting[i]; failedUnpack("encounter " + i)(err); });
      return;
    }
    withMap(e, function (e) {
      cache[i] = e; cached.push(i);
      while (cached.length > CACHE) { delete cache[cached.shift()]; }
      var then = waiting[i]; delete waiting[i];
      if (then) { then(e); }
    });
  }
  function load(i, then) {
    if (cache[i]) { then(cache[i]); return; }
    var first = !waiting[i];
    waiting[i] = then;
    if (!first) { return; }
    addScript(ROWS[i].file, function () { delete waiting[i]; });
  }
  window.veiReport.receiveMap = receiveMap;
  window.veiReport.receive = receive;

  /* ---------------- geometry ---------------- */
  function box(x, y, yaw, L, W) {
    if (x === null || y === null || !isFinite(x) || !isFinite(y)) { return [[], []]; }
    if (yaw === null) { yaw = 0; }
    if (!isFinite(yaw)) { yaw = 0; }
    var c = Math.cos(yaw), s = Math.sin(yaw), hl = L / 2, hw = W / 2;
    var pts = [[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw], [hl, hw]];
    return [pts.map(function (p) { return x + p[0] * c - p[1] * s; }),
            pts.map(function (p) { return y + p[0] * s + p[1] * c; })];
  }
  function clean(a) { return (a || []).map(function (v) { return v === null ? NaN : v; }); }

  /* ---------------- per-encounter plots ---------------- */
  /* t: 40 px above the plotting area hold plotly's toolbar (modebar), which would
     otherwise cover the legend's first entry at the plot's top right */
  var LAYOUT = { margin: { l: 50, r: 10, t: 40, b: 40 }, legend: { font: { size: 10 } } };
  function lay(extra) { return Object.assign({}, LAYOUT, extra); }
  var CONF = { responsive: true, displaylogo: false };

  function roadTrace(e) {
    return { x: e.roads.x, y: e.roads.y, mode: "lines", fill: "toself", name: "drivable lanes (map)",
             fillcolor: "rgba(150,150,150,0.25)", line: { color: "rgba(120,120,120,0.6)", width: 0.5 }, hoverinfo: "skip" };
  }

  /* The map's other layers (issue 26): sidewalks and bike lanes, lane borders, kerbs;
     drawn under the tracks (first in the trace list) or after the replay's moving traces. */
  function roadLayerTraces(e) {
    var L = e.road_layers || {}, out = [];
    if (L.sidewalks) {
      out.push({ x: L.sidewalks.x, y: L.sidewalks.y, mode: "lines", fill: "toself", name: "sidewalks, bike lanes (map)",
                 fillcolor: "rgba(200,200,200,0.35)", line: { color: "rgba(180,180,180,0.5)", width: 0.5 }, hoverinfo: "skip" });
    }
    if (L.lines) {
      out.push({ x: L.lines.x, y: L.lines.y, mode: "lines", name: "lane borders (map)",
                 line: { color: "rgba(255,255,255,0.9)", width: 1 }, hoverinfo: "skip" });
    }
    if (L.kerbs) {
      out.push({ x: L.kerbs.x, y: L.kerbs.y, mode: "lines", name: "kerbs (map)",
                 line: { color: "#555", width: 1.5 }, hoverinfo: "skip" });
    }
    return out;
  }
  function roadTraces(e) { return roadLayerTraces(e).concat(e.roads ? [roadTrace(e)] : []); }
  function noMapNote(e) {
    var note = e.road_layers && e.road_layers.note;
    return note ? [{ text: note, xref: "paper", yref: "paper", x: 0.01, y: 0.01, showarrow: false,
                     font: { size: 10, color: "#666" }, xanchor: "left", yanchor: "bottom" }] : [];
  }

  function drawMap(e) {
    var traces = roadTraces(e);
    Object.keys(e.tracks).forEach(function (aid, i) {
      var tr = e.tracks[aid], ego = aid === "ego", main = aid === e.rider_id;
      traces.push({ x: tr.x, y: tr.y, mode: "lines", name: aid + (main ? " (encounter)" : ""),
        line: { width: ego || main ? 3 : 1.2, color: ego ? "#000" : (main ? "#d62728" : "#999"),
                dash: tr.category === "cyclist" && !main ? "dot" : "solid" },
        text: tr.t.map(function (t) { return "t = " + t.toFixed(1) + " s"; }), hoverinfo: "name+text" });
    });
    var xs = [], ys = [];
    Object.keys(e.tracks).forEach(function (aid) { xs = xs.concat(clean(e.tracks[aid].x)); ys = ys.concat(clean(e.tracks[aid].y)); });
    xs = xs.filter(isFinite); ys = ys.filter(isFinite);
    var pad = 15, rx = [Math.min.apply(null, xs) - pad, Math.max.apply(null, xs) + pad];
    var ry = [Math.min.apply(null, ys) - pad, Math.max.apply(null, ys) + pad];
    Plotly.newPlot("map-plot", traces, lay({ xaxis: { title: { text: "x east [m]" }, range: rx, scaleanchor: "y" },
      yaxis: { title: { text: "y north [m]" }, range: ry }, annotations: noMapNote(e) }), CONF);
  }

  /* legend entries of colours that no trace names: the TTC zones (bands, ego fill) */
  function zoneKeys(fills, withCollision) {
    return ZONE_NAME.slice(0, withCollision ? 4 : 3).map(function (name, z) {
      return { x: [null], y: [null], mode: "markers", name: name, hoverinfo: "skip",
               marker: { symbol: "square", size: 12, color: fills[z], line: { color: "#999", width: 1 } } };
    });
  }

  function replayTraces(e, c, k) {
    var r = e.replay, d = r.dims, egoD = d.ego || [4.7, 1.85], riD = d[e.rider_id] || [1.2, 0.6];
    var eb = box(c.ego.x[k], c.ego.y[k], c.ego.yaw[k], egoD[0], egoD[1]);
    var rb = box(c.rider.x[k], c.rider.y[k], c.rider.yaw[k], riD[0], riD[1]);
    var ox = [], oy = [];
    Object.keys(c.others).forEach(function (aid) { ox.push(c.others[aid].x[k]); oy.push(c.others[aid].y[k]); });
    return { eb: eb, rb: rb, ox: ox, oy: oy, zone: c.zone[k] || 0 };
  }

  function drawReplay() {
    var e = state.enc, c = e.replay.configs[state.cfg], k = state.k, p = replayTraces(e, c, k);
    var xs = clean(c.ego.x).concat(clean(c.rider.x)).filter(isFinite);
    var ys = clean(c.ego.y).concat(clean(c.rider.y)).filter(isFinite);
    var pad = 5, rx = [Math.min.apply(null, xs) - pad, Math.max.apply(null, xs) + pad];
    var ry = [Math.min.apply(null, ys) - pad, Math.max.apply(null, ys) + pad];
    var traces = [
      { x: p.eb[0], y: p.eb[1], fill: "toself", mode: "lines", name: "ego", fillcolor: ZONE_FILL[p.zone], line: { color: "#000" } },
      { x: p.rb[0], y: p.rb[1], fill: "toself", mode: "lines", name: e.rider_id, fillcolor: "rgba(214,39,40,0.8)", line: { color: "#800" } },
      { x: p.ox, y: p.oy, mode: "markers", name: "other riders", marker: { color: "#888", size: 7 } },
      { x: c.ego.x, y: c.ego.y, mode: "lines", name: "ego path", line: { color: "#000", width: 1, dash: "dot" }, hoverinfo: "skip" },
      { x: c.rider.x, y: c.rider.y, mode: "lines", name: "rider path", line: { color: "#d62728", width: 1, dash: "dot" }, hoverinfo: "skip" }
    ];
    var roads = roadTraces(e);
    state.moving0 = roads.length;  /* the road layers first (under the boxes): moving traces after them */
    traces = roads.concat(traces).concat(zoneKeys(ZONE_FILL, true));  /* + what the ego's fill colour means */
    Plotly.newPlot("replay-plot", traces, lay({ xaxis: { title: { text: "x east [m]" }, range: rx, scaleanchor: "y" },
      yaxis: { title: { text: "y north [m]" }, range: ry }, showlegend: true, annotations: noMapNote(e) }), CONF);
    updateLabels();
  }

  function setFrame(k) {
    var e = state.enc, c = e.replay.configs[state.cfg];
    state.k = Math.max(0, Math.min(k, e.replay.t.length - 1));
    var p = replayTraces(e, c, state.k);
    var m = state.moving0 || 0;
    Plotly.restyle("replay-plot", { x: [p.eb[0], p.rb[0], p.ox], y: [p.eb[1], p.rb[1], p.oy] }, [m, m + 1, m + 2]);
    Plotly.restyle("replay-plot", { fillcolor: ZONE_FILL[p.zone] }, [m]);
    var t = e.replay.t[state.k], cursor = [{ type: "line", xref: "x", yref: "paper", x0: t, x1: t, y0: 0, y1: 1, line: { color: "#000", width: 1 } }];
    Plotly.relayout("speed-plot", { shapes: cursor });
    Plotly.relayout("ttc-plot", { shapes: ttcShapes(e).concat(cursor) });
    updateLabels();
  }

  function updateLabels() {
    var e = state.enc, c = e.replay.configs[state.cfg], k = state.k;
    document.getElementById("time-slider").value = String(k);
    document.getElementById("time-label").textContent = "t = " + e.replay.t[k].toFixed(2) + " s";
    var cap = c.cap[k] || "no CAP";
    var capEl = document.getElementById("cap-label");
    capEl.textContent = "CAP: " + cap;
    var z = c.zone[k] || 0, zEl = document.getElementById("zone-label");
    zEl.textContent = ZONE_NAME[z] + (isFinite(c.ttc[k]) && c.ttc[k] !== null ? " (TTC " + Number(c.ttc[k]).toFixed(2) + " s)" : "");
    zEl.className = "badge zone-" + z;
  }

  function drawSpeed(e) {
    var traces = [], t = e.replay.t;
    e.replay.configs.forEach(function (c, i) {
      traces.push({ x: t, y: c.ego.speed, mode: "lines", name: "ego " + c.name, legendgroup: c.name, line: { color: colour(c.name, i), width: 2 } });
      traces.push({ x: t, y: c.rider.speed, mode: "lines", name: "rider " + c.name, legendgroup: c.name, line: { color: colour(c.name, i), width: 1.5, dash: "dash" } });
    });
    Plotly.newPlot("speed-plot", traces, lay({ xaxis: { title: { text: "t [s]" }, range: e.replay.window }, yaxis: { title: { text: "speed [m/s]" }, rangemode: "tozero" } }), CONF);
  }

  var TTC_BAND_FILL = ["rgba(46,125,50,0.10)", "rgba(251,192,45,0.18)", "rgba(239,108,0,0.18)"];
  function ttcShapes(e) {
    var w = e.replay.window, band = function (y0, y1, col) {
      return { type: "rect", xref: "x", yref: "y", x0: w[0], x1: w[1], y0: y0, y1: y1, fillcolor: col, line: { width: 0 }, layer: "below" };
    };
    return [band(0, 1, TTC_BAND_FILL[2]), band(1, 2, TTC_BAND_FILL[1]), band(2, 10, TTC_BAND_FILL[0])];
  }
  function drawTTC(e) {
    var traces = e.replay.configs.map(function (c, i) {
      return { x: c.ttc_t, y: c.ttc_full, mode: "lines", name: c.name, line: { color: colour(c.name, i) } };
    });
    traces = traces.concat(zoneKeys(TTC_BAND_FILL, false));  /* the bands' meaning */
    Plotly.newPlot("ttc-plot", traces, lay({ shapes: ttcShapes(e), xaxis: { title: { text: "t [s]" }, range: e.replay.window },
      yaxis: { title: { text: "TTC [s] (clipped at 10)" }, range: [0, 10] } }), CONF);
  }

  function drawSummary(e) {
    var cols = ["name", "collision", "collision_time_s", "safety_index", "min_gap_m", "min_ttc_s", "peak_decel_mps2", "ego_speed_std_mps"];
    // issue 22 / 28.7: the relative-TTC safety index and whether the rider was seen too late
    cols = cols.concat(["safety_index_rel", "first_seen_gap_m", "seen_too_late"]);
    /* short headers that wrap at their spaces: the table fits its panel (it was cut off) */
    var heads = { name: "config", collision: "collision", collision_time_s: "t collision [s]", safety_index: "safety index",
                  min_gap_m: "min gap [m]", min_ttc_s: "min TTC [s]", peak_decel_mps2: "peak decel [m/s\u00b2]", ego_speed_std_mps: "speed std [m/s]",
                  safety_index_rel: "SI rel", first_seen_gap_m: "first seen gap [m]", seen_too_late: "seen too late" };
    var h = "<table><thead><tr>" + cols.map(function (c) { return "<th title=\"" + c + "\">" + (heads[c] || c) + "</th>"; }).join("") + "</tr></thead><tbody>";
    e.summary.forEach(function (r) {
      h += "<tr>" + cols.map(function (c) {
        var v = r[c];
        if (typeof v === "number") { v = v.toFixed(c === "safety_index" ? 3 : 2); }
        if (v === null || v === undefined) { v = "-"; }
        var span = document.createElement("span"); span.textContent = String(v);
        return "<td>" + span.innerHTML + "</td>";
      }).join("") + "</tr>";
    });
    h += "</tbody></table><p class=\"note\">time shift " + (e.time_shift_s === null ? "-" : e.time_shift_s.toFixed(2)) + " s (automatic)</p>";
    document.getElementById("summary-table").innerHTML = h;
  }

  function esc(v) {
    return String(v).replace(/&/g, "&amp;").replace(/</g, "&lt;").replace(/>/g, "&gt;").replace(/"/g, "&quot;");
  }
  function drawProbabilities(e) {
    var el = document.getElementById("prob-table"), r = e.risk;
    if (!r) { el.textContent = "no risk estimate (catalogue setting risk: null)"; return; }
    var h = "<p class=\"note\">variation: " + r.variation.map(esc).join("; ") + "</p>";
    r.planners.forEach(function (p) {
      h += "<h4>" + esc(p.policy) + " (" + esc(p.method) + ", " + esc(p.n_simulations) + " simulations" + (p.reliable ? "" : ", unreliable") + ")</h4><table><tbody>";
      Object.keys(p.figures).forEach(function (k) { h += "<tr><th>" + esc(k) + "</th><td>" + esc(p.figures[k]) + "</td></tr>"; });
      h += "</tbody></table>";
      if (p.kinds.length) { h += "<p>failure kinds: " + p.kinds.map(esc).join("; ") + "</p>"; }
      if (p.regions.length) { h += "<p>failure regions:</p><ul>" + p.regions.map(function (x) { return "<li>" + esc(x) + "</li>"; }).join("") + "</ul>"; }
      p.notes.forEach(function (n) { h += "<p class=\"note\">" + esc(n) + "</p>"; });
    });
    r.comparisons.forEach(function (c) { h += "<p>" + esc(c) + "</p>"; });
    el.innerHTML = h;
  }
  /* Probability maps: known P > 0 on a red scale, known P = 0 green, not known grey:
     colours far apart (issue 35; known P = 0 was the white end of the scale under a grey veil). */
  var PROB = { scale: [[0, "#fcbba1"], [1, "#67000d"]], zero: "#41ab5d", unknown: "#bdbdbd" };
  function key(name, colour) {
    return { x: [null], y: [null], mode: "markers", name: name, hoverinfo: "skip",
             marker: { symbol: "square", size: 12, color: colour, line: { color: "#666", width: 1 } } };
  }
  function drawProbMap(m, el, note) {
    el.textContent = "";
    var flat = function (c) { return [[0, c], [1, c]]; };
    var traces = [
      { type: "heatmap", x: m.x, y: m.y, z: m.z, zmin: 0, zmax: 1, colorscale: PROB.scale, name: "known: P > 0",
        colorbar: { title: { text: "P(collision | cell)" } }, text: m.text, hovertemplate: "%{x:.2f}, %{y:.2f}<br>%{text}<extra></extra>" },
      { type: "heatmap", x: m.x, y: m.y, z: m.zero, zmin: 0, zmax: 1, showscale: false, colorscale: flat(PROB.zero), name: "known: P = 0",
        text: m.text, hovertemplate: "%{text}<extra>known: P = 0</extra>" },
      { type: "heatmap", x: m.x, y: m.y, z: m.unknown, zmin: 0, zmax: 1, showscale: false, colorscale: flat(PROB.unknown), name: "not known",
        text: m.text, hovertemplate: "%{text}<extra>not known</extra>" },
      key("known: P = 0", PROB.zero), key("not known (95 % CI wider than \u00b10.1)", PROB.unknown)
    ];
    Plotly.newPlot(el, traces, lay({ xaxis: { title: { text: m.x_label } }, yaxis: { title: { text: m.y_label } }, showlegend: true,
      legend: { x: 0, y: -0.2, yanchor: "top", orientation: "h" }, margin: { l: 50, r: 10, t: 30, b: 115 },
      annotations: [{ text: note, xref: "paper", yref: "paper", x: 0, y: -0.33, xanchor: "left", yanchor: "top", showarrow: false, font: { size: 10 } }] }), CONF);
  }
  window.veiReport.PROB = PROB;

  function drawRisk(e) {
    var m = e.riskmap, el = document.getElementById("risk-plot");
    if (e.probmap) { drawProbMap(e.probmap, el, "P(collision | cell) of the risk estimate: " + e.probmap.note); return; }
    if (!m) { Plotly.purge(el); el.textContent = "no sweep over time shift and cruise speed"; return; }
    el.textContent = "";
    var coll = m.points.collision;
    var traces = [
      { type: "heatmap", x: m.x, y: m.y, z: m.z, zmin: 0, zmax: 1, colorscale: [[0, "#c62828"], [0.5, "#fbc02d"], [1, "#2e7d32"]], colorbar: { title: { text: "mean SI" } },
        customdata: m.share, hovertemplate: "offset %{x:.2f} s<br>speed %{y:.2f} m/s<br>mean SI %{z:.3f}<br>collision share %{customdata:.2f}<extra></extra>" },
      { x: m.points.x.filter(function (_, i) { return coll[i]; }), y: m.points.y.filter(function (_, i) { return coll[i]; }),
        mode: "markers", name: "collision", marker: { symbol: "x", color: "#000", size: 5 } }
    ];
    var flag = m.points.flagged;  // runs seen too late: never coloured, marked
    if (flag && m.n_flagged) {
      traces.push({ x: m.points.x.filter(function (_, i) { return flag[i]; }), y: m.points.y.filter(function (_, i) { return flag[i]; }),
        mode: "markers", name: "seen too late (not coloured)", marker: { symbol: "cross-thin-open", color: "#666", size: 7 } });
    }
    Plotly.newPlot(el, traces, lay({ xaxis: { title: { text: m.x_label } }, yaxis: { title: { text: m.y_label } }, showlegend: true,
      legend: { x: 0, y: 1.12, orientation: "h" } }), CONF);
  }

  function stop() {
    if (state.timer !== null) { clearInterval(state.timer); state.timer = null; }
    document.getElementById("play-button").textContent = "play";
  }
  function play() {
    if (state.timer !== null) { stop(); return; }
    var n = state.enc.replay.t.length;
    if (state.k >= n - 1) { state.k = 0; }
    document.getElementById("play-button").textContent = "pause";
    state.timer = setInterval(function () {
      if (state.k >= n - 1) { stop(); return; }
      setFrame(state.k + 1);
    }, 1000 / 10);
  }

  function draw(e) {
    stop();
    state.enc = e; state.k = 0;
    document.getElementById("encounter-status").textContent = "";
    Array.prototype.forEach.call(document.querySelectorAll("#overview tbody tr"), function (tr) {
      tr.classList.toggle("selected", tr.getAttribute("data-encounter") === e.id);
    });
    var sel = document.getElementById("config-select");
    sel.innerHTML = "";
    e.replay.configs.forEach(function (c, i) { var o = document.createElement("option"); o.value = String(i); o.textContent = c.name; sel.appendChild(o); });
    state.cfg = 0;
    var slider = document.getElementById("time-slider");
    slider.max = String(e.replay.t.length - 1); slider.value = "0";
    drawMap(e); drawSpeed(e); drawTTC(e); drawSummary(e); drawRisk(e); drawProbabilities(e); drawReplay();
  }
  function showEncounter(id, then) {
    var i = INDEX[id];
    if (i === undefined) { return; }
    document.getElementById("encounter-select").value = id;
    state.wanted = id;
    document.getElementById("encounter-status").textContent = "loading ...";
    load(i, function (e) {
      if (state.wanted === id) { draw(e); }
      if (then) { then(e); }
    });
  }

  (function () {  /* the select box: every encounter, by rank */
    var sel = document.getElementById("encounter-select"), frag = document.createDocumentFragment();
    ROWS.forEach(function (r) {
      var o = document.createElement("option"); o.value = r.id; o.textContent = "#" + r.row.rank + " " + r.id; frag.appendChild(o);
    });
    sel.appendChild(frag);
  })();
  document.getElementById("encounter-select").addEventListener("change", function (ev) { showEncounter(ev.target.value); });
  document.getElementById("config-select").addEventListener("change", function (ev) { state.cfg = Number(ev.target.value); drawReplay(); setFrame(state.k); });
  document.getElementById("time-slider").addEventListener("input", function (ev) { stop(); setFrame(Number(ev.target.value)); });
  document.getElementById("play-button").addEventListener("click", play);
  window.veiReport.showEncounter = showEncounter;
  window.veiReport.setFrame = setFrame;
  /* the table first; plotly.js (4.6 MB) loads after it, then the maps and the first encounter */
  renderPage();
  window.veiReport.timing = { script_start_ms: T0, json_parsed_ms: T_JSON, table_ms: performance.now() };
  function done() { window.veiReport.timing.ready_ms = performance.now(); window.veiReport.ready = true; }
  function plots() {
    var cmap = document.getElementById("catalogue-map");
    if (DATA.catalogue_map) {
      drawProbMap(DATA.catalogue_map, cmap, "P(collision | cell) over the sweeps: " + DATA.catalogue_map.note);
    } else { cmap.textContent = "no sweep over time shift and cruise speed"; }
    window.veiReport.timing.index_ms = performance.now();
    if (ROWS.length) { showEncounter(ROWS[view.order[0]].id, done); } else { done(); }
  }
  var lib = document.createElement("script");
  lib.src = DATA.plotly;
  lib.onload = plots;
  lib.onerror = function () {
    document.getElementById("catalogue-map").textContent = "could not load " + DATA.plotly + " (is the report_files folder beside the page?)";
  };
  document.head.appendChild(lib);
})();
