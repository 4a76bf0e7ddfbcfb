"""The report of a catalogue with risk estimates (issue 23): encounters ranked by expected
harm with their 95 % intervals, the probabilities and failure modes per encounter, and a
probability map that shows P(collision | cell) only where it is known (headless Chromium
for the page; see test_html_browser for the set-up)."""

from __future__ import annotations

import numpy as np

from tests.report.test_html_browser import browser, loaded, small_catalogue  # noqa: F401


def test_collect_ranks_by_expected_harm_with_intervals(small_catalogue):  # noqa: F811
    from vei.catalogue.report_data import collect

    data = collect(small_catalogue)
    assert data["ranked_by"] == "expected harm"
    keys = [c["key"] for c in data["columns"]]
    assert {"risk_expected_harm", "risk_harm_ci", "risk_p_collision", "risk_p_collision_ci"} <= set(
        keys
    )
    harm = [e["row"]["risk_expected_harm"] for e in data["encounters"]]
    h = np.nan_to_num(np.asarray(harm, dtype=float), nan=0.0)
    assert (np.diff(h) <= 1e-15).all()
    for e in data["encounters"]:
        ci = e["row"]["risk_p_collision_ci"]
        assert ci.startswith("[") or ci.startswith("< ")
        figs = e["risk"]["planners"][0]["figures"]
        assert set(figs) >= {"P(collision)", "P(injury-relevant collision)"}
    maps = [e["probmap"] for e in data["encounters"] if e["probmap"] is not None]
    assert maps, "a probability map from the risk samples"
    m = maps[0]
    z, unknown = np.asarray(m["z"], float), np.asarray(m["unknown"], float)
    zero = np.asarray(m["zero"], float)
    # every cell is exactly one of: known P > 0, known P = 0, not known (issue 35)
    kinds = np.isfinite(z).astype(int) + np.isfinite(zero) + np.isfinite(unknown)
    assert (kinds == 1).all()


def test_page_shows_probabilities_and_marks_the_unknown(loaded):  # noqa: F811
    text = loaded.execute_script("return document.getElementById('prob-table').textContent")
    assert "P(collision)" in text and "expected injury risk" in text and "[" in text
    heads = loaded.execute_script(
        "return Array.from(document.querySelectorAll('#overview th')).map(h => h.textContent)"
    )
    assert "expected harm" in heads and "P 95 % CI" in heads
    has_map = loaded.execute_script("return !!window.veiReport.state.enc.probmap")
    if has_map:
        n = loaded.execute_script("return document.getElementById('risk-plot').data.length")
        # known P > 0, known P = 0, not known, and the legend keys of the last two
        assert n == 5
    severe = [e for e in loaded.get_log("browser") if e["level"] == "SEVERE"]
    assert severe == [], severe
