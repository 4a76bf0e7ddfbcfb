"""The report data and page, without a browser."""

from __future__ import annotations

import json
import re

import numpy as np
import pandas as pd
import pytest

from tests.catalogue.helpers import build_small_catalogue
from vei.catalogue.report_data import collect
from vei.report.html_report import _script_json, render


@pytest.fixture(scope="module")
def data(trafficmonitoring_root):
    return collect(build_small_catalogue(str(trafficmonitoring_root)))


def test_script_json_cannot_close_the_script_element():
    text = _script_json(
        {"id": "</script><script>alert(1)</script><!--", "x": [np.nan, np.inf, 1.23456]}
    )
    assert "</script" not in text and "<!--" not in text
    assert json.loads(text) == {
        "id": "</script><script>alert(1)</script><!--",
        "x": [None, None, 1.2346],
    }


def test_replay_data_matches_the_case_study(data, trafficmonitoring_root):
    root = build_small_catalogue(str(trafficmonitoring_root))
    enc = {e["id"]: e for e in data["encounters"]}["stadtmitte_12_audi_geradeaus_03__cyclist_60"]
    rep = enc["replay"]
    assert [c["name"] for c in rep["configs"]] == [
        "replay",
        "normal",
        "aggressive",
        "normal-cap",
        "aggressive-cap",
    ]
    t = np.asarray(rep["t"], float)
    assert np.allclose(np.diff(t), 0.1)  # 10 Hz
    lo, hi = rep["window"]
    assert t[0] >= lo - 1e-9 and t[-1] <= hi + 1e-9 and hi - lo < 30.0  # zoomed, not 0-61 s
    ts = pd.read_parquet(root / "encounters" / enc["id"] / "casestudy" / "timeseries.parquet")
    for c in rep["configs"]:
        ego = ts[(ts["config"] == c["name"]) & (ts["agent_id"] == "ego")].set_index("t_s")
        k = len(t) // 2
        assert c["ego"]["x"][k] == pytest.approx(ego["x_m"].loc[t[k]], abs=1e-3)
        zone = np.asarray(c["zone"])
        collided = ego["collided"].reindex(t).to_numpy(bool)
        assert ((zone == 3) == collided).all()  # the collision zone is exactly the collided steps
        assert set(np.unique(zone)) <= {0, 1, 2, 3}
    hit = {c["name"]: bool(np.asarray(c["zone"]).max() == 3) for c in rep["configs"]}
    # Only the replay collides: the default (calibrated) rider misses the car by 3.6 m
    # (normal) / 4.0 m (aggressive) here (docs/riders.md).
    assert hit == {"replay": True, "normal": False, "aggressive": False,
                   "normal-cap": False, "aggressive-cap": False}  # fmt: skip


def test_risk_map_bins_are_the_mean_safety_index(data, trafficmonitoring_root):
    root = build_small_catalogue(str(trafficmonitoring_root))
    rows = pd.read_parquet(root / "catalogue.parquet")
    for enc in data["encounters"]:
        m = enc["riskmap"]
        sw = rows[(rows["encounter_id"] == enc["id"]) & (rows["kind"] == "sweep")]
        assert m["n"] == len(sw) == 24
        z = np.array(m["z"], dtype=float)
        assert np.array(m["count"], dtype=float).sum() == 24
        # the count-weighted mean of the bins is the mean safety index of the variants
        # (variants whose shifted rider never meets the ego have none: NaN, left out)
        count = np.array(m["count_si"], dtype=float)
        ok = count > 0
        n = int(sw["safety_index"].notna().sum())
        assert count.sum() == n
        assert np.sum(z[ok] * count[ok]) / n == pytest.approx(sw["safety_index"].mean(), abs=1e-3)


def test_page_lists_every_encounter_and_recording(data):
    from vei.report.html_site import index_rows

    table = {**index_rows(data["encounters"], data["columns"]), "files": "f/enc/"}
    page = render({**data, "encounters": table}, files="f")
    m = re.search(r'id="vei-data" type="application/json">(.*?)</script>', page, re.S)
    embedded = json.loads(m.group(1))["encounters"]
    assert embedded["ids"] == [e["id"] for e in data["encounters"]] and len(embedded["ids"]) == 3
    keys = [c["key"] for c in data["columns"]]
    # the rows' values in the columns' order, floats to 4-5 significant digits
    first = data["encounters"][0]["row"]
    for k, v in zip(keys, embedded["values"][0], strict=True):
        w = first[k]
        assert v == (pytest.approx(w, rel=1e-3) if isinstance(w, float) and np.isfinite(w) else
                     (None if isinstance(w, float) else w))  # fmt: skip
    for r in data["recordings"]:
        assert r["recording"] in page
    # issue 31: the overview says what the recorded behaviour supports
    assert {"recorded_collision_share", "recorded_share_ci", "collisions_on_recorded"} <= set(keys)
    assert "risk_p_collision_recorded_ci" in keys  # the small catalogue has a risk estimate
    for e in data["encounters"]:
        assert e["row"]["risk_p_collision_recorded_ci"] not in (None, "-")
        share = e["row"]["recorded_collision_share"]
        assert 0.0 <= share <= 1.0 and e["row"]["recorded_share_ci"].startswith("[")


def test_site_writes_one_script_per_encounter_and_drops_stale_ones(data, tmp_path):
    from vei.report.html_site import write_site
    from vei.report.packing import read_script

    index = {k: v for k, v in data.items() if k != "encounters"}
    stats = write_site(index, iter(data["encounters"]), tmp_path / "report.html")
    scripts = sorted(p.name for p in (tmp_path / "report_files" / "enc").iterdir())
    assert scripts == ["00000.js", "00001.js", "00002.js"] and stats.n_encounters == 3
    raw = (tmp_path / "report_files" / "enc" / "00001.js").read_bytes()
    assert raw.startswith(b'window.veiReport.receive(1,"') and raw.rstrip().endswith(b");")
    i, body = read_script(raw)  # the packed data (vei.report.packing), decoded
    assert i == 1 and body["id"] == data["encounters"][1]["id"]
    assert len(body["replay"]["configs"]) == 5
    # the replay's ego to 1 cm of the collected data
    want = np.array(data["encounters"][1]["replay"]["configs"][2]["ego"]["x"], float)
    got = np.array([np.nan if v is None else v for v in body["replay"]["configs"][2]["ego"]["x"]])
    assert np.array_equal(np.isnan(want), np.isnan(got))
    assert np.nanmax(np.abs(want - got)) <= 0.005 + 1e-9
    assert (tmp_path / "report_files" / "plotly.min.js").stat().st_size > 1_000_000
    page = stats.index.read_text()
    assert '"plotly":"report_files/plotly.min.js"' in page  # loaded by the page after its table
    # a smaller report in the same folder replaces the scripts of the larger one
    write_site(index, iter(data["encounters"][:1]), tmp_path / "report.html")
    assert [p.name for p in (tmp_path / "report_files" / "enc").iterdir()] == ["00000.js"]
    assert stats.total_bytes > stats.opened_bytes > stats.index_bytes > 0


def test_probability_cells_are_known_positive_known_zero_or_not_known():
    from vei.catalogue.report_maps import cells

    # by hand: 3 cells; p 0.5 with a narrow interval (known > 0), 0 known, 0.2 of few samples
    grid = {"x_centres": np.array([0.0, 1.0, 2.0]), "y_centres": np.array([5.0]),
            "p": np.array([[0.5, 0.0, 0.2]]), "lo": np.array([[0.45, 0.0, 0.01]]),
            "hi": np.array([[0.55, 0.03, 0.6]]), "known": np.array([[True, True, False]])}  # fmt: skip
    c = cells(grid, "x", "y", "note")
    assert np.isfinite(c["z"]).tolist() == [[True, False, False]]
    assert np.isfinite(c["zero"]).tolist() == [[False, True, False]]
    assert np.isfinite(c["unknown"]).tolist() == [[False, False, True]]
    assert c["text"][0][2].endswith("(not known)") and c["text"][0][1].startswith("P 0.000")
