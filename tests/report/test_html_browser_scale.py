"""A report of 10^4 SYNTHETIC encounters (issue 35.3) in headless Chromium: the index page
opens in under 3 s (the browser's clock, navigation start to the first encounter drawn)
with what it loads under 50 MB and the whole folder under 50 MB (10^6 bytes: packed
encounter scripts, vei.report.packing), loads an encounter's script on demand
from the folder (file://), sorts every row; the catalogue's risk map tells known P = 0
from not known. Set-up and skips: test_html_browser. VEI_SCREENSHOT_DIR=DIR keeps the
screenshot (docs/figures/report_10k_encounters.png) and the measured figures (JSON)."""

from __future__ import annotations

import json
import os
import shutil
import time
from pathlib import Path

import numpy as np
import pytest

from tests.report.synthetic_report import synthetic_site
from tests.report.test_html_browser import browser  # noqa: F401

pytestmark = pytest.mark.slow

N_ENCOUNTERS = 10_000
OPEN_LIMIT_S = 3.0
OPENED_LIMIT_BYTES = 50 * 2**20
#: The whole report (page and folder) of 10^4 encounters [bytes] (issue 35.3: under 50 MB).
TOTAL_LIMIT_BYTES = 50 * 10**6


@pytest.fixture(scope="module")
def site(tmp_path_factory):
    from vei.report.html_site import write_site

    out = tmp_path_factory.mktemp("report10k")
    index, encounters = synthetic_site(N_ENCOUNTERS)
    t0 = time.perf_counter()
    stats = write_site(index, encounters, out / "report.html")
    return stats, time.perf_counter() - t0


@pytest.fixture(scope="module")
def opened(browser, site):  # noqa: F811
    from selenium.webdriver.support.ui import WebDriverWait

    stats, write_s = site
    t0 = time.perf_counter()
    browser.get(stats.index.resolve().as_uri())  # returns after the page's load event
    WebDriverWait(browser, 60, poll_frequency=0.02).until(
        lambda d: d.execute_script("return !!(window.veiReport && window.veiReport.ready)")
    )
    wall = time.perf_counter() - t0
    timing = browser.execute_script("return window.veiReport.timing")
    figures = {
        "encounters": stats.n_encounters,
        "index_bytes": stats.index_bytes,
        "opened_bytes": stats.opened_bytes,
        "total_bytes": stats.total_bytes,
        "write_s": round(write_s, 2),
        "open_wall_s": round(wall, 3),
        "browser_script_start_ms": round(timing["script_start_ms"]),
        "browser_json_parsed_ms": round(timing["json_parsed_ms"]),
        "browser_table_drawn_ms": round(timing["table_ms"]),
        "browser_index_drawn_ms": round(timing["index_ms"]),
        "browser_first_encounter_drawn_ms": round(timing["ready_ms"]),
    }
    # the screenshot of the page as it opens (the docs' figure)
    shot = stats.index.parent / "report_10k_encounters.png"
    browser.save_screenshot(str(shot))
    # opened again (the browser's caches warm, as a reader returning to the page)
    t0 = time.perf_counter()
    browser.refresh()
    WebDriverWait(browser, 60, poll_frequency=0.02).until(
        lambda d: d.execute_script("return !!(window.veiReport && window.veiReport.ready)")
    )
    figures["reopen_wall_s"] = round(time.perf_counter() - t0, 3)
    print("\nreport of 10^4 synthetic encounters:", json.dumps(figures))
    shots = os.environ.get("VEI_SCREENSHOT_DIR")
    if shots:
        Path(shots).mkdir(parents=True, exist_ok=True)
        shutil.copy(shot, Path(shots) / "report_10k_encounters.png")
        (Path(shots) / "report_10k_encounters.json").write_text(
            json.dumps(figures, indent=2) + "\n"
        )
    return browser, figures, shot


def test_report_folder_holds_one_script_per_encounter(site):
    stats, _ = site
    scripts = sorted((stats.files / "enc").glob("*.js"))
    assert len(scripts) == N_ENCOUNTERS == stats.n_encounters
    head = scripts[123].read_bytes()[:40]
    assert head.startswith(b'window.veiReport.receive(123,"')
    # the index holds the rows, not the encounters' data
    assert stats.index_bytes < 10 * 2**20
    assert stats.opened_bytes < OPENED_LIMIT_BYTES
    # the whole folder: packed encounter scripts (vei.report.packing), about 4.3 KB each
    assert stats.total_bytes < TOTAL_LIMIT_BYTES, stats
    # a script decodes (reference decoder) to its encounter
    from vei.report.packing import read_script

    i, enc = read_script(scripts[123].read_bytes())
    assert i == 123 and enc["id"] == "synthetic_00041__cyclist_0"
    assert len(enc["replay"]["configs"]) == 5 and len(enc["replay"]["t"]) == 100


def test_opens_in_under_3_s_without_error(opened):
    drv, figures, _ = opened
    # by the browser's clock from navigation start: the table, then (plotly.js loaded) the
    # catalogue's map and the first encounter drawn (the wall time adds the driver's round trips)
    assert figures["browser_table_drawn_ms"] < 1000 * OPEN_LIMIT_S, figures
    assert figures["browser_first_encounter_drawn_ms"] < 1000 * OPEN_LIMIT_S, figures
    severe = [e for e in drv.get_log("browser") if e["level"] == "SEVERE"]
    assert severe == [], severe
    assert drv.execute_script("return document.querySelectorAll('#overview tbody tr').length") == 25
    label = drv.execute_script("return document.getElementById('page-label').textContent")
    assert "of 10000" in label
    assert (
        drv.execute_script("return document.getElementById('encounter-select').options.length")
        == N_ENCOUNTERS
    )


def test_an_encounter_loads_on_demand_from_the_folder(opened):
    drv, _, _ = opened
    before = drv.execute_script(
        "return document.querySelectorAll('head script[src*=\"/enc/\"]').length"
    )
    drv.find_element("id", "page-next").click()
    drv.find_element("id", "page-next").click()
    row = drv.find_elements("css selector", "#overview tbody tr")[7]
    eid = row.get_attribute("data-encounter")
    t0 = time.perf_counter()
    row.click()
    from selenium.webdriver.support.ui import WebDriverWait

    WebDriverWait(drv, 20, poll_frequency=0.02).until(
        lambda d: d.execute_script("return window.veiReport.state.enc.id") == eid
    )
    took = time.perf_counter() - t0
    assert took < OPEN_LIMIT_S
    assert drv.execute_script("return document.getElementById('replay-plot').data.length") >= 5
    # the script element is removed once loaded: the page does not grow with every click
    assert (
        drv.execute_script("return document.querySelectorAll('head script[src*=\"/enc/\"]').length")
        == before
    )


def test_sorting_orders_all_rows(opened):
    drv, _, _ = opened
    heads = drv.find_elements("css selector", "#overview th")
    i = [h.get_attribute("data-key") for h in heads].index("rec_min_gap_m")
    heads[i].click()
    col = drv.execute_script(
        "return Array.from(document.querySelectorAll("
        f"'#overview tbody tr')).map(r => Number(r.cells[{i}].getAttribute('data-value')))"
    )
    smallest = drv.execute_script(
        "return Math.min.apply(null, window.veiReport.rows.map(e => e.row.rec_min_gap_m))"
    )
    assert col == sorted(col) and col[0] == pytest.approx(smallest)


def test_catalogue_map_tells_known_zero_from_not_known(opened):
    drv, _, _ = opened
    traces = drv.execute_script(
        "return document.getElementById('catalogue-map').data.map(t => [t.name, t.type || 'scatter'])"
    )
    names = [n for n, _ in traces]
    assert {"known: P > 0", "known: P = 0", "not known"} <= set(names)
    prob = drv.execute_script("return window.veiReport.PROB")

    def rgb(h: str) -> np.ndarray:
        return np.array([int(h[k : k + 2], 16) for k in (1, 3, 5)], float)

    # far apart: not two greys (before: white under a grey veil vs the grey veil)
    assert np.linalg.norm(rgb(prob["zero"]) - rgb(prob["unknown"])) > 100
    assert np.linalg.norm(rgb(prob["zero"]) - rgb(prob["scale"][0][1])) > 100
    # the synthetic sweeps never collide at a slow ego and a large offset: known P = 0 cells
    zero = drv.execute_script(
        "return document.getElementById('catalogue-map').data[1].z.flat().filter(v => v === 1).length"
    )
    assert zero > 0


def test_screenshot_is_not_blank(opened):
    from PIL import Image

    _, _, shot = opened
    img = np.asarray(Image.open(shot).convert("L"), dtype=np.float64)
    assert img.shape[0] > 500 and img.std() > 10.0, "screenshot looks blank"
