"""The metrics' settings reach `vei run` from a run configuration (``metrics:``), typos
are errors, and the rider mass of the delta-v is the run's own ``sfm.mass_kg``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from vei.cli.main import main
from vei.experiments.demo_data import demo_interaction
from vei.io.scenario import write_scenario
from vei.recon.pipeline import reconstruct


@pytest.fixture(scope="module")
def scenario_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scen") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


def _run(scenario_dir, cfg_text: str, dest, capsys) -> dict:
    cfg = dest.parent / f"{dest.name}.yaml"
    cfg.write_text(cfg_text)
    args = ["run", str(scenario_dir), "--config", str(cfg), "--out", str(dest)]
    code = main([*args, "--time-shift", "4.5", "--no-figures"])
    out = capsys.readouterr().out
    assert code == 0, out
    return json.loads((dest / "metrics.json").read_text())


def test_run_config_metrics_section_reaches_the_summary(scenario_dir, tmp_path, capsys):
    base = _run(scenario_dir, "case: {preset: normal}\n", tmp_path / "base", capsys)
    m0 = base["metrics"]
    assert m0["collision"] and m0["impact_speed_mps"] > 0
    v_kmh = 3.6 * m0["impact_speed_mps"]
    assert m0["injury_risk"] == pytest.approx(1 / (1 + math.exp(6.9 - 0.09 * v_kmh)))
    # the rider mass of the delta-v is the case's sfm.mass_kg (95 kg)
    assert m0["delta_v_car_mps"] == pytest.approx(95 / 1595 * m0["impact_speed_mps"])
    assert base["metrics_config"]["rider_mass_kg"] is None

    text = (
        "case:\n  preset: normal\n  sfm: {mass_kg: 150}\n"
        "metrics:\n  injury_intercept: 5.0\n  injury_slope_per_kmh: 0.2\n  car_mass_kg: 1000\n"
    )
    doc = _run(scenario_dir, text, tmp_path / "set", capsys)
    m = doc["metrics"]
    assert doc["metrics_config"]["injury_intercept"] == 5.0
    v = m["impact_speed_mps"]
    assert m["injury_risk"] == pytest.approx(1 / (1 + math.exp(5.0 - 0.2 * 3.6 * v)))
    # a sweepable sfm.mass_kg = 150 kg changes the delta-v too: m_r / (m_c + m_r) |v_rel|
    assert m["delta_v_car_mps"] == pytest.approx(150 / 1150 * v)
    assert m["delta_v_rider_mps"] == pytest.approx(1000 / 1150 * v)
    assert np.isclose(m["delta_v_car_mps"] + m["delta_v_rider_mps"], v)


def test_run_config_metrics_typo_is_an_error(scenario_dir, tmp_path, capsys):
    cfg = tmp_path / "typo.yaml"
    cfg.write_text("case: {preset: normal}\nmetrics:\n  injury_intercpt: 5.0\n")
    code = main(["run", str(scenario_dir), "--config", str(cfg), "--out", str(tmp_path / "o")])
    captured = capsys.readouterr()
    assert code == 2
    text = captured.out + captured.err
    assert "injury_intercpt" in text and "Traceback" not in text


def test_a_sweep_over_the_rider_mass_changes_the_delta_v(scenario_dir, tmp_path):
    """A sweep scores each variant with its own sfm.mass_kg (as vei run does)."""
    from vei.sweep.run import read_results, run_sweep
    from vei.sweep.spec import spec_from_dict

    spec = spec_from_dict(
        {
            "design": "grid",
            "base": "normal",
            "parameters": {"sfm.mass_kg": {"choices": [95.0, 150.0]}},
        }
    )
    run_sweep(scenario_dir, spec, tmp_path / "sweep", chunk_size=8, progress=False)
    df = read_results(tmp_path / "sweep").set_index("sfm.mass_kg")
    for m in (95.0, 150.0):
        row = df.loc[m]
        assert bool(row["collision"]) and row["impact_speed_mps"] > 0
        v = row["impact_speed_mps"]
        assert row["delta_v_car_mps"] == pytest.approx(m / (1500.0 + m) * v, rel=1e-12)
        assert row["delta_v_rider_mps"] == pytest.approx(1500.0 / (1500.0 + m) * v, rel=1e-12)
