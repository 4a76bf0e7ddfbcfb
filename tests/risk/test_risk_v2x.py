"""`vei risk` with a risk spec's ``v2x`` section: P(collision) of the V2X case study's
occlusion window with perception alone against perception + V2X, each with its interval;
the samples' run configurations carry V2X, so `vei run --config` re-runs one alone."""

from __future__ import annotations

import json

import pandas as pd
import pytest
import yaml
from typer.testing import CliRunner

from vei.cli.main import app
from vei.errors import ConfigError
from vei.risk.variation import parse_variation

SPEC = {
    "base": "replay",
    "time_shift_reference": "zero",
    "variation": {"time_shift_s": {"dist": "uniform", "min": -6.0, "max": -2.15}},
    "fixed": {"ego.policy": "paper-cap"},
    "perception": {"enabled": True},
}
V2X = {"enabled": True, "position_error_std_m": 0.57}


def test_the_risk_spec_takes_a_v2x_section():
    model = parse_variation({**SPEC, "v2x": V2X})
    assert model.v2x.enabled and model.v2x.position_error_std_m == 0.57
    assert model.to_dict()["v2x"]["enabled"] is True
    assert parse_variation(SPEC).v2x is None
    with pytest.raises(ConfigError, match="v2x.pdr_factor need V2X"):
        parse_variation({**SPEC, "fixed": {**SPEC["fixed"], "v2x.pdr_factor": 0.5}})
    with pytest.raises(ConfigError, match="v2x: unknown key"):
        parse_variation({**SPEC, "v2x": {"enabled": True, "latency": 1}})


@pytest.mark.slow
def test_vei_risk_with_v2x_on_the_occluded_crossing(tmp_path):
    runner = CliRunner()
    sc = tmp_path / "occluded"
    assert runner.invoke(app, ["v2x", "scenario", "--out", str(sc)]).exit_code == 0
    est = {}
    for name, spec in (("alone", SPEC), ("v2x", {**SPEC, "v2x": V2X})):
        path = tmp_path / f"{name}.yaml"
        path.write_text(yaml.safe_dump(spec))
        out = tmp_path / name
        res = runner.invoke(app, ["risk", str(sc), "--spec", str(path), "--out", str(out),
                                  "--method", "mc", "--budget", "300", "--sobol", "0"])  # fmt: skip
        assert res.exit_code == 0, res.output
        est[name] = json.loads((out / "risk.json").read_text())
    p = {k: v["planners"][0]["p_collision"] for k, v in est.items()}
    text = {k: json.dumps(v) for k, v in est.items()}
    assert '"v2x"' in text["v2x"] and '"v2x"' not in text["alone"]
    alone = pd.read_parquet(tmp_path / "alone" / "samples.parquet")
    heard = pd.read_parquet(tmp_path / "v2x" / "samples.parquet")
    # Perception alone collides in the whole window; V2X (corrected GNSS) almost never.
    assert alone["collision"].mean() == 1.0
    assert heard["collision"].mean() < 0.05
    # ... and the estimates' 95 % intervals do not overlap.
    assert p["alone"]["ci95"][0] > p["v2x"]["ci95"][1]
    # A sample's run configuration carries V2X and re-runs to the same outcome.
    cfg = next((tmp_path / "v2x" / "configs").glob("*.yaml"))
    assert yaml.safe_load(cfg.read_text())["case"]["v2x"]["enabled"] is True
    row = heard[heard["variant_id"] == cfg.stem].iloc[0]
    run = tmp_path / "rerun"
    res = runner.invoke(app, ["run", str(sc), "--config", str(cfg), "--out", str(run),
                              "--no-figures"])  # fmt: skip
    assert res.exit_code == 0, res.output
    metrics = json.loads((run / "metrics.json").read_text())["metrics"]
    assert metrics["collision"] == bool(row["collision"])
