"""The catalogue's HTML report in a real browser (headless Chromium via Selenium).

Skips with a reason where Debian's chromium / chromedriver are missing; under
VEI_REQUIRE_BROWSER=1 (set by .ci/run) it fails instead.
"""

from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from tests.catalogue.helpers import build_small_catalogue

# the slow tier (docs/testing.md): minutes of real data, players or browsers
pytestmark = pytest.mark.slow

CHROMIUM_CANDIDATES = ("/usr/bin/chromium", "/usr/bin/chromium-browser")
DRIVER = "/usr/bin/chromedriver"


def _require_browser() -> tuple[str, str]:
    chromium = next((c for c in CHROMIUM_CANDIDATES if Path(c).is_file()), None)
    missing = []
    if chromium is None:
        missing.append("chromium (apt-get install chromium)")
    if not Path(DRIVER).is_file():
        missing.append("chromedriver (apt-get install chromium-driver)")
    try:
        import selenium  # noqa: F401
    except ImportError:
        missing.append("selenium (pip install 'vei[report]')")
    if missing:
        msg = "browser test needs " + ", ".join(missing)
        if os.environ.get("VEI_REQUIRE_BROWSER") == "1":
            pytest.fail(msg)
        pytest.skip(msg)
    return chromium, DRIVER


@pytest.fixture(scope="module")
def browser():
    chromium, driver_path = _require_browser()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    profile = tempfile.mkdtemp(prefix="vei-chromium-")
    opts = webdriver.ChromeOptions()
    opts.binary_location = chromium
    for arg in (
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        "--disable-dev-shm-usage",
        f"--user-data-dir={profile}",
        "--window-size=1400,1800",
    ):
        opts.add_argument(arg)
    opts.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    drv = webdriver.Chrome(service=Service(executable_path=driver_path), options=opts)
    try:
        yield drv
    finally:
        drv.quit()
        shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture(scope="module")
def small_catalogue(trafficmonitoring_root):
    """The small real catalogue (built once per session)."""
    return build_small_catalogue(str(trafficmonitoring_root))


@pytest.fixture(scope="module")
def loaded(browser, small_catalogue):
    from selenium.webdriver.support.ui import WebDriverWait

    from vei.catalogue.report_data import write_report

    html = write_report(small_catalogue, small_catalogue / "report.html")
    browser.get(html.resolve().as_uri())
    WebDriverWait(browser, 60).until(
        lambda d: d.execute_script("return !!(window.veiReport && window.veiReport.ready)")
    )
    return browser


def test_report_is_offline(small_catalogue):
    from vei.catalogue.report_data import write_report

    text = write_report(small_catalogue, small_catalogue / "offline.html").read_text()
    import re

    # no element loads anything from elsewhere; the page adds plotly.js and the encounters'
    # scripts itself, from the folder beside it
    assert re.findall(r"<(?:script|link|img|iframe)\b[^>]*\b(?:src|href)\s*=", text, re.I) == []
    assert (small_catalogue / "offline_files" / "plotly.min.js").is_file()
    assert 'id="vei-data"' in text
    data = json.loads(
        re.search(r'id="vei-data" type="application/json">(.*?)</script>', text, re.S).group(1)
    )
    table = data["encounters"]
    assert table["files"] == "offline_files/enc/" and len(table["ids"]) == 3
    assert data["plotly"] == "offline_files/plotly.min.js"
    for i in range(len(table["ids"])):
        assert (small_catalogue / f"{table['files']}{i:05d}.js").is_file()


def test_loads_without_console_error(loaded):
    logs = loaded.get_log("browser")
    severe = [e for e in logs if e["level"] == "SEVERE"]
    assert severe == [], severe
    n_rows = loaded.execute_script("return document.querySelectorAll('#overview tbody tr').length")
    assert n_rows >= 2
    # every plot drew something
    for pid in ("map-plot", "replay-plot", "speed-plot", "ttc-plot"):
        n = loaded.execute_script(f"return document.getElementById('{pid}').data.length")
        assert n >= 2, pid


def _column(driver, idx: int) -> list[float]:
    return driver.execute_script(
        "return Array.from(document.querySelectorAll('#overview tbody tr'))"
        f".map(r => Number(r.cells[{idx}].getAttribute('data-value')))"
    )


def test_table_sorts(loaded):
    from selenium.webdriver.common.by import By

    headers = loaded.find_elements(By.CSS_SELECTOR, "#overview th")
    keys = [h.get_attribute("data-key") for h in headers]
    i = keys.index("rec_min_gap_m")
    headers[i].click()
    asc = _column(loaded, i)
    assert asc == sorted(asc)
    headers[i].click()
    desc = _column(loaded, i)
    assert desc == sorted(desc, reverse=True)
    r = keys.index("rank")
    headers[r].click()
    assert _column(loaded, r) == sorted(_column(loaded, r))


def test_slider_moves_the_ego(loaded):
    get_x = "return document.getElementById('replay-plot').data[0].x.slice()"
    before = loaded.execute_script(get_x)
    n = loaded.execute_script("return Number(document.getElementById('time-slider').max)")
    assert n > 10
    loaded.execute_script(
        "var s = document.getElementById('time-slider'); s.value = String(Math.floor(s.max * 0.6));"
        "s.dispatchEvent(new Event('input'));"
    )
    after = loaded.execute_script(get_x)
    assert len(before) == len(after) == 5  # a closed box
    shift = np.hypot(np.mean(after) - np.mean(before), 0.0) + abs(
        np.mean(loaded.execute_script("return document.getElementById('replay-plot').data[0].y"))
        - np.mean(before)
    )
    assert not np.allclose(before, after), "the ego box did not move"
    assert shift > 0
    label = loaded.execute_script("return document.getElementById('time-label').textContent")
    assert label.startswith("t = ")


def test_play_and_pause(loaded):
    import time

    loaded.execute_script(
        "var s = document.getElementById('time-slider'); s.value = '0'; s.dispatchEvent(new Event('input'));"
    )
    button = loaded.find_element("id", "play-button")
    button.click()
    assert button.text == "pause"
    time.sleep(0.8)  # 10 frames per second
    button.click()
    assert button.text == "play"
    k = loaded.execute_script("return Number(document.getElementById('time-slider').value)")
    assert k >= 2
    time.sleep(0.3)  # paused: it stays
    assert loaded.execute_script("return Number(document.getElementById('time-slider').value)") == k


def test_screenshot_not_blank(loaded, small_catalogue):
    from PIL import Image

    out = small_catalogue / "report_screenshot.png"
    loaded.save_screenshot(str(out))
    img = np.asarray(Image.open(out).convert("L"), dtype=np.float64)
    assert img.shape[0] > 500 and img.shape[1] > 500
    assert img.std() > 10.0, "screenshot looks blank"
    shots = os.environ.get("VEI_SCREENSHOT_DIR")
    if shots:
        Path(shots).mkdir(parents=True, exist_ok=True)
        shutil.copy(out, Path(shots) / "report_overview.png")
        loaded.execute_script("document.getElementById('encounter-section').scrollIntoView()")
        loaded.save_screenshot(str(Path(shots) / "report_encounter.png"))


def test_toolbar_never_covers_a_legend_and_zones_are_named(loaded):
    """Plotly's toolbar (modebar) sits above each plot's legend, not on its first entry;
    the TTC plot's zone bands and the replay's zone-coloured ego are named in the legend."""
    rects = loaded.execute_script(
        """
        var out = {};
        document.querySelectorAll('.js-plotly-plot').forEach(function (el) {
          var bar = el.querySelector('.modebar'), leg = el.querySelector('.legend');
          if (!bar || !leg) { return; }
          var b = bar.getBoundingClientRect(), l = leg.getBoundingClientRect();
          out[el.id] = [b.left, b.top, b.right, b.bottom, l.left, l.top, l.right, l.bottom];
        });
        return out;
        """
    )
    assert {"map-plot", "replay-plot", "speed-plot", "ttc-plot"} <= set(rects), rects
    for pid, (bl, bt, br, bb, ll, lt, lr, lb) in rects.items():
        overlap = min(br, lr) > max(bl, ll) and min(bb, lb) > max(bt, lt)
        assert not overlap, f"{pid}: toolbar {bl, bt, br, bb} covers legend {ll, lt, lr, lb}"
    names = loaded.execute_script(
        "return ['ttc-plot', 'replay-plot'].map(function (id) {"
        " return document.getElementById(id).data.map(function (t) { return t.name; }); })"
    )
    assert {"TTC safe (> 2 s)", "TTC attention (1-2 s]", "TTC alert (0-1 s]"} <= set(names[0])
    assert "collision" in names[1] and "TTC alert (0-1 s]" in names[1]


def test_case_study_summary_fits_its_panel(loaded):
    """The case-study summary table shows every column within its panel (it was cut off on
    the right, behind a scroll bar)."""
    widths = loaded.execute_script(
        "var box = document.getElementById('summary-table');"
        "return [box.scrollWidth, box.clientWidth, box.querySelectorAll('th').length];"
    )
    scroll, client, n_cols = widths
    assert n_cols >= 8
    assert scroll <= client, f"the table needs {scroll} px in a {client} px panel"
