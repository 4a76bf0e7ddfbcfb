"""Writing the catalogue's report as a small site that works offline from its folder.

``report.html`` (the index page, :func:`vei.report.html_report.render`) and beside it
``report_files/``:

- ``plotly.min.js``: the plotting library (the copy in the ``plotly`` wheel);
- ``enc/00000.js``, ``enc/00001.js``, ...: one script per encounter in rank order, each a
  single call ``window.veiReport.receive(i, "...")`` with that encounter's data packed
  (:mod:`vei.report.packing`: arrays quantized and delta-coded, the whole deflated, the
  bytes as they are in the string; about 5 KB an encounter, a 20th of its JSON);
- ``enc/map_KEY.js``: the map layers (drivable lanes, sidewalks, lane borders, kerbs) of
  the encounters whose layers are the same (those of one recording), packed alike, one
  call ``window.veiReport.receiveMap("KEY", "...")``; an encounter with a map names its
  KEY (``map``) and the page loads that script once.

The page loads an encounter's script when the encounter is opened, by adding a
``<script src>`` element: unlike ``fetch`` or XMLHttpRequest of a JSON file, which Chromium
blocks on ``file://`` pages, a script element loads from the page's own folder, so the
report opens from a local folder, a zip unpacked anywhere or a web server alike. The index
holds only the ranked table and the catalogue's risk map, so its size grows by a row per
encounter (about 300 bytes), not by the encounter's tracks and replay (issue 35: the single
file of a 10^4-encounter catalogue would have held more than a gigabyte).

Encounter scripts are written first, one at a time (:func:`write_site` takes an iterator,
so one encounter's data is in memory at a time), into a fresh folder that replaces
``enc/`` whole once every script is written (a previous report's scripts go with it); the
index page last, atomically.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
import os
import shutil
import tempfile
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from vei.io.atomic import atomic_path, write_text
from vei.report.html_report import plotly_js_path, render
from vei.report.packing import map_script, pack, script

#: Name of an encounter's script in ``<files>/enc/``.
ENCOUNTER_FILE = "{:05d}.js"


@dataclasses.dataclass(frozen=True)
class SiteStats:
    """What :func:`write_site` wrote.

    Attributes:
        index: the index page; files: its folder of scripts.
        n_encounters: encounter scripts written.
        index_bytes: the index page's size [bytes]; opened_bytes: what opening the page
            loads (index + plotly.min.js + the first encounter's script and its map
            layers' script) [bytes];
        total_bytes: the page and its whole folder [bytes].
    """

    index: Path
    files: Path
    n_encounters: int
    index_bytes: int
    opened_bytes: int
    total_bytes: int


def files_dir(index: Path) -> Path:
    """The folder of an index page's scripts: ``<stem>_files`` beside it."""
    return index.parent / f"{index.stem}_files"


#: Name of a map-layers script in ``<files>/enc/`` (named by its content: encounters whose
#: layers are the same, those of one recording, share it).
MAP_FILE = "map_{}.js"
#: The encounter's keys of its map layers (vei.catalogue.report_data.encounter_data).
MAP_KEYS = ("roads", "road_layers")


def split_map(enc: dict[str, Any]) -> tuple[dict[str, Any], str | None, bytes | None]:
    """(the encounter with its map layers replaced by ``map``: their key, the key, their
    script :func:`vei.report.packing.map_script`), or (the encounter, None, None) without
    map geometry (no map: only a note). The key is the first 16 hex digits of the SHA-1 of
    the packed layers."""
    layers = {k: enc.get(k) for k in MAP_KEYS}
    geometry = layers["roads"] is not None or any(
        v is not None for k, v in (layers["road_layers"] or {}).items() if k != "note"
    )
    if not geometry:
        return enc, None, None
    payload = pack(layers)
    key = hashlib.sha1(payload).hexdigest()[:16]
    rest = {k: v for k, v in enc.items() if k not in MAP_KEYS}
    return {**rest, "map": key}, key, map_script(key, payload)


def encounter_script(i: int, enc: dict[str, Any]) -> bytes:
    """Encounter ``i``'s script: one ``window.veiReport.receive`` call with the encounter's
    data packed (:mod:`vei.report.packing`: quantized, delta-coded, deflated; the page
    loads it as ``x-user-defined`` text and unpacks it); its overview row is left out (the
    index page holds it)."""
    return script(i, pack({k: v for k, v in enc.items() if k != "row"}))


def _sig(v: Any) -> Any:
    """A table value for the index: floats to 5 significant digits (1.2346e-07 stays)."""
    if isinstance(v, float | np.floating):
        v = float(v)
        return float(f"{v:.5g}") if math.isfinite(v) else None
    if isinstance(v, np.generic):
        return v.item()
    return v


def index_rows(encounters: list[dict[str, Any]], columns: list[dict[str, Any]]) -> dict[str, Any]:
    """The index page's table in a compact form: {'ids' [N], 'values' [N][C] (the
    ``columns``' values in order, floats to 5 significant digits), 'files' (the scripts'
    folder relative to the page, set by :func:`write_site`)}; encounter i's script is
    ``files`` + ENCOUNTER_FILE.format(i)."""
    keys = [c["key"] for c in columns]
    return {
        "ids": [e["id"] for e in encounters],
        "values": [[_sig(e["row"].get(k)) for k in keys] for e in encounters],
    }


def write_site(
    index: dict[str, Any], encounters: Iterable[dict[str, Any]], path: str | Path
) -> SiteStats:
    """Write the report site (module docstring) atomically, file by file.

    Args:
        index: :func:`vei.catalogue.report_data.collect_index`'s index.
        encounters: the encounters' data in rank order
            (:func:`vei.catalogue.report_data.encounter_data`), consumed one at a time.
        path: the index page (e.g. ``DIR/report.html``).
    Returns:
        :class:`SiteStats`.
    """
    path = Path(path)
    files = files_dir(path)
    files.mkdir(parents=True, exist_ok=True)
    with atomic_path(files / "plotly.min.js") as tmp:
        tmp.write_bytes(plotly_js_path().read_bytes())
    # the scripts go to a fresh folder, swapped in whole once every one is written (one
    # rename instead of a synced rename per file: 10^4 encounters)
    fresh = Path(tempfile.mkdtemp(prefix=".enc.", dir=files))
    listed: list[dict[str, Any]] = []
    first_map = 0  # bytes of the first encounter's map layers
    try:
        for i, enc in enumerate(encounters):
            name = ENCOUNTER_FILE.format(i)
            rest, key, layers = split_map(enc)
            if key is not None and not (fresh / MAP_FILE.format(key)).exists():
                (fresh / MAP_FILE.format(key)).write_bytes(layers)
            if i == 0 and layers is not None:
                first_map = len(layers)
            (fresh / name).write_bytes(encounter_script(i, rest))
            listed.append({"id": enc["id"], "row": enc["row"]})
        fresh.chmod(0o755)
        enc_dir, old = files / "enc", files / f".enc.old.{os.getpid()}"
        if enc_dir.exists():
            enc_dir.rename(old)
        fresh.rename(enc_dir)
        shutil.rmtree(old, ignore_errors=True)
    except BaseException:
        shutil.rmtree(fresh, ignore_errors=True)
        raise
    table = {**index_rows(listed, index["columns"]), "files": f"{files.name}/enc/"}
    write_text(path, render({**index, "encounters": table}, files=files.name))
    size = path.stat().st_size
    first = (files / "enc" / ENCOUNTER_FILE.format(0)).stat().st_size if listed else 0
    total = size + sum(p.stat().st_size for p in files.rglob("*") if p.is_file())
    return SiteStats(
        index=path,
        files=files,
        n_encounters=len(listed),
        index_bytes=size,
        opened_bytes=size + (files / "plotly.min.js").stat().st_size + first + first_map,
        total_bytes=total,
    )
