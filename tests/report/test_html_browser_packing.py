"""The page's decoder of packed encounter scripts (report.js ``unpack``, issue 35.3) in
headless Chromium on the small real catalogue: every array of the encounter the page opened
equals the Python reference decoder's (vei.report.packing.read_script) and the collected
data within half a quantization step. Set-up and skips: test_html_browser."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.report.test_html_browser import browser, loaded, small_catalogue  # noqa: F401

pytestmark = pytest.mark.slow


def _same(a, b, path="enc"):
    """a (the page's) equals b (the reference decoder's): numbers to 1e-12, None alike."""
    if isinstance(b, dict):
        assert isinstance(a, dict) and set(a) == set(b), path
        for k in b:
            _same(a[k], b[k], f"{path}.{k}")
    elif isinstance(b, list):
        assert isinstance(a, list) and len(a) == len(b), path
        for k, (x, y) in enumerate(zip(a, b, strict=True)):
            _same(x, y, f"{path}[{k}]")
    elif isinstance(b, float | int) and not isinstance(b, bool):
        assert isinstance(a, float | int) and math.isclose(a, b, abs_tol=1e-12), (path, a, b)
    else:
        assert a == b, (path, a, b)


def _arr(v):
    return np.array([np.nan if x is None else x for x in v], float)


def test_page_decodes_as_the_reference_and_within_the_step(loaded, small_catalogue):  # noqa: F811
    from vei.catalogue.report_data import collect
    from vei.report.packing import read_script

    enc = loaded.execute_script("return window.veiReport.state.enc")
    i = loaded.execute_script(
        "return window.veiReport.rows.findIndex(r => r.id === window.veiReport.state.enc.id)"
    )
    raw = (small_catalogue / "report_files" / "enc" / f"{i:05d}.js").read_bytes()
    j, ref = read_script(raw)
    assert j == i
    _same(enc, ref)
    want = next(e for e in collect(small_catalogue)["encounters"] if e["id"] == enc["id"])
    for aid, tr in want["tracks"].items():
        for k, step in (("x", 0.01), ("y", 0.01), ("t", 0.001)):
            a, b = _arr(tr[k]), _arr(enc["tracks"][aid][k])
            assert np.array_equal(np.isnan(a), np.isnan(b))
            assert np.nanmax(np.abs(a - b)) <= step / 2 + 1e-9, (aid, k)
    for c, g in zip(want["replay"]["configs"], enc["replay"]["configs"], strict=True):
        pairs = [
            (c[w][k], g[w][k], s)
            for w in ("ego", "rider")
            for k, s in (("x", 0.01), ("y", 0.01), ("yaw", 0.001), ("speed", 0.01))
        ]
        pairs += [(c["ttc"], g["ttc"], 0.001), (c["ttc_full"], g["ttc_full"], 0.001),
                  (c["zone"], g["zone"], 1e-9)]  # fmt: skip
        for a, b, step in pairs:
            a, b = _arr(a), _arr(b)
            a = np.where(np.isfinite(a), a, np.nan)  # inf TTC: None in the page, as before
            assert np.array_equal(np.isnan(a), np.isnan(b)), c["name"]
            if np.isfinite(a).any():
                assert np.nanmax(np.abs(a - b)) <= step / 2 + 1e-9, c["name"]
