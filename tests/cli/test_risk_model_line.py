"""Every ``vei risk`` answer names the variation model it is conditional on and its
validation (issue 31.2): a console line and risk.json's ``variation.model``; the
time-shift window's basis in risk.json's ``time_shift``."""

from __future__ import annotations

import contextlib
import io
import json

import pytest

from vei.cli.main import main


@pytest.mark.slow
def test_the_answer_names_its_variation_model(tmp_path):
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    scen = tmp_path / "scenario"
    write_scenario(reconstruct(demo_interaction()), scen)
    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(buf):
        code = main(["risk", str(scen), "--out", str(tmp_path / "out"), "--policy", "none",
                     "--method", "mc", "--budget", "2000", "--sobol", "0", "--no-progress"])  # fmt: skip
    text = buf.getvalue()
    assert code == 0, text
    flat = " ".join(text.split())  # the console wraps long lines
    assert "variation model: conditional on the variation model vei default variation" in flat
    doc = json.loads((tmp_path / "out" / "risk.json").read_text())
    model = doc["variation"]["model"]
    assert model["validation"].endswith("rider window speed 37/44 (84 %)")
    assert f"variation model: {model['description']}" in flat
    assert doc["time_shift"]["risk_basis"] in ("recorded behaviour", "continuations")
    assert "rider.speed" in doc["dimensions"]
