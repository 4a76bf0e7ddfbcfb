"""The catalogue report's map layer in a real browser (headless Chromium via Selenium): a
catalogue built with the Ingolstadt map draws the drivable lanes, sidewalks, lane borders
and kerbs under the tracks of the map and of the bird's-eye replay, and the replay still
moves the ego over them. With VEI_SCREENSHOT_DIR set, saves report_roads_map.png and
report_roads_replay.png there."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

from tests.report.test_html_browser import browser  # noqa: F401 - the shared fixture

# the slow tier (docs/testing.md): minutes of real data, players or browsers
pytestmark = pytest.mark.slow

LAYERS = (
    "drivable lanes (map)",
    "sidewalks, bike lanes (map)",
    "lane borders (map)",
    "kerbs (map)",
)


@pytest.fixture(scope="module")
def mapped_catalogue(trafficmonitoring_root):
    from tests.catalogue.helpers import small_config
    from tests.conftest import require_data
    from vei.catalogue import run_catalogue

    net = require_data("maps", "ingolstadt_research_intersection.net.xml.gz")
    out = Path(tempfile.mkdtemp(prefix="vei-mapped-catalogue-"))
    atexit.register(shutil.rmtree, out, True)
    result = run_catalogue(
        str(trafficmonitoring_root), out, small_config(map_source=str(net)),
        recordings=["stadtmitte_12_audi_geradeaus_03"], progress=False,
    )  # fmt: skip
    assert result.complete, result.failed_encounters
    return out


@pytest.fixture(scope="module")
def loaded(browser, mapped_catalogue):  # noqa: F811 - the imported fixture
    from selenium.webdriver.support.ui import WebDriverWait

    from vei.catalogue.report_data import write_report

    html = write_report(mapped_catalogue, mapped_catalogue / "report.html")
    browser.get(html.resolve().as_uri())
    WebDriverWait(browser, 60).until(
        lambda d: d.execute_script("return !!(window.veiReport && window.veiReport.ready)")
    )
    return browser


def _names(driver, plot: str) -> list[str]:
    return driver.execute_script(f"return document.getElementById('{plot}').data.map(t => t.name)")


def test_map_layer_is_drawn(loaded):
    severe = [e for e in loaded.get_log("browser") if e["level"] == "SEVERE"]
    assert severe == [], severe
    for plot in ("map-plot", "replay-plot"):
        names = _names(loaded, plot)
        for layer in LAYERS:
            assert layer in names, (plot, layer, names)
        # the layers come first: drawn under the tracks and the boxes
        first_track = min(i for i, n in enumerate(names) if n not in LAYERS)
        assert all(names.index(layer) < first_track for layer in LAYERS)
        n_pts = loaded.execute_script(
            f"return document.getElementById('{plot}').data.filter(t => t.name === 'kerbs (map)')[0].x.length"
        )
        assert n_pts > 50
    # no 'no road map' note where there is a map
    notes = loaded.execute_script(
        "return (document.getElementById('map-plot').layout.annotations || []).map(a => a.text)"
    )
    assert not any("no road map" in n for n in notes)
    # the drawn lanes are where the ego drives: its track inside the drivable outlines
    import shapely

    xs, ys = loaded.execute_script(
        "var t = document.getElementById('map-plot').data.filter(t => t.name === 'drivable lanes (map)')[0];"
        "return [t.x, t.y];"
    )
    rings, cur = [], []
    for x, y in zip(xs, ys, strict=True):
        if x is None:
            rings.append(cur)
            cur = []
        else:
            cur.append((x, y))
    area = shapely.union_all([shapely.Polygon(r).buffer(0) for r in rings if len(r) >= 4]).buffer(
        0.3
    )
    ex, ey = loaded.execute_script(
        "var t = document.getElementById('map-plot').data.filter(t => t.name === 'ego')[0]; return [t.x, t.y];"
    )
    on = shapely.contains_xy(area, np.array(ex, float), np.array(ey, float))
    assert on.mean() >= 0.95, on.mean()


def test_replay_moves_over_the_map(loaded):
    m = loaded.execute_script(
        "return document.getElementById('replay-plot').data.findIndex(t => t.name === 'ego')"
    )
    assert m >= len(LAYERS)
    get_x = f"return document.getElementById('replay-plot').data[{m}].x.slice()"
    before = loaded.execute_script(get_x)
    loaded.execute_script(
        "var s = document.getElementById('time-slider'); s.value = String(Math.floor(s.max * 0.6));"
        "s.dispatchEvent(new Event('input'));"
    )
    after = loaded.execute_script(get_x)
    assert len(after) == 5 and not np.allclose(before, after)
    # the road layers did not move
    assert _names(loaded, "replay-plot")[: len(LAYERS)] == list(LAYERS[1:]) + [LAYERS[0]]


def test_screenshots(loaded, mapped_catalogue):
    from PIL import Image

    shots = Path(os.environ.get("VEI_SCREENSHOT_DIR") or mapped_catalogue)
    shots.mkdir(parents=True, exist_ok=True)
    loaded.execute_script("document.getElementById('map-plot').scrollIntoView()")
    loaded.save_screenshot(str(shots / "report_roads_map.png"))
    loaded.execute_script("document.getElementById('replay-plot').scrollIntoView()")
    loaded.save_screenshot(str(shots / "report_roads_replay.png"))
    img = np.asarray(Image.open(shots / "report_roads_map.png").convert("L"), dtype=np.float64)
    assert img.std() > 10.0
