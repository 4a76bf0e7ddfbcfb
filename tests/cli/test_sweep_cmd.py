"""``vei sweep`` through the real CLI entry point."""

from __future__ import annotations

import json

import pandas as pd
import pytest

from vei.cli.main import main


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory):
    """The synthetic demo interaction, reconstructed into a scenario folder."""
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


SPEC = """\
design: grid
base: normal
time_shift_reference: zero
parameters:
  time_shift_s: {min: 1.0, max: 5.0, num: 4}
  ego.cruise_speed_mps: {min: 4.0, max: 8.0, num: 3}
  ego.policy: none
"""


def test_sweep_command_runs_and_resumes(demo_scenario, tmp_path, capsys):
    spec = tmp_path / "sweep.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    args = [
        "sweep",
        str(demo_scenario),
        "--spec",
        str(spec),
        "--out",
        str(out),
        "--chunk-size",
        "5",
    ]
    assert main([*args, "--max-chunks", "1", "--no-progress"]) == 0
    assert "incomplete" in capsys.readouterr().out
    assert main([*args, "--no-progress"]) == 0
    text = capsys.readouterr().out
    assert "variants" in text and "12" in text and "results" in text
    df = pd.read_parquet(out / "results.parquet")
    assert len(df) == 12 and df["variant_id"].is_unique
    assert sorted(df["time_shift_s"].unique()) == pytest.approx([1.0, 7 / 3, 11 / 3, 5.0])
    assert (df["time_shift_applied_s"] == df["time_shift_s"]).all()  # reference: zero
    assert json.loads((out / "sweep.json").read_text())["status"] == "complete"


def test_boundary_option(demo_scenario, tmp_path, capsys):
    spec = tmp_path / "sweep.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "bnd"
    rc = main(
        [
            "sweep",
            str(demo_scenario),
            "--spec",
            str(spec),
            "--out",
            str(out),
            "--x",
            "time_shift_s",
            "--y",
            "ego.cruise_speed_mps",
            "--x-range=0.0,6.0",
            "--coarse",
            "3,3",
            "--levels",
            "1",
            "--critical",
            "3",
            "--no-progress",
        ]
    )
    assert rc == 0
    assert "critical boundary" in capsys.readouterr().out
    doc = json.loads((out / "boundary.json").read_text())
    assert doc["x_range"] == [0.0, 6.0] and doc["y_range"] == [4.0, 8.0]
    assert doc["grid_evaluations"] == 25 and doc["n_evaluations"] <= 25
    assert len(pd.read_csv(out / "critical.csv")) <= 3


@pytest.mark.parametrize(
    ("text", "extra", "needle"),
    [
        (SPEC.replace("design: grid", "desing: grid"), [], "desing"),
        (SPEC, ["--x", "time_shift_s"], "--y"),
        (SPEC, ["--x-range", "0,1"], "--x and --y"),
        (SPEC, ["--engine", "dask"], "engine"),
        (SPEC, ["--x", "time_shift_s", "--y", "ego.cruise_speed_mps", "--coarse", "3"], "--coarse"),
        (
            SPEC.replace("ego.policy: none", "cap.enabled: false"),
            [],
            "sweep parameter 'cap.enabled' was replaced by 'ego.policy'",
        ),
        (
            SPEC + "  cap.T_safe_s: 1.5\n",
            [],
            "sweep.yaml: sweep parameter 'cap.T_safe_s' was renamed 'cap.t_safe_s'",
        ),
        (
            SPEC,
            ["--x", "time_shift_s", "--y", "perception_delay_s", "--y-range", "0,1"],
            "sweep parameter 'perception_delay_s' was renamed 'cap.perception_delay_s'",
        ),
    ],
)
def test_errors_exit_2_with_a_clear_message(demo_scenario, tmp_path, capsys, text, extra, needle):
    spec = tmp_path / "sweep.yaml"
    spec.write_text(text)
    rc = main(
        ["sweep", str(demo_scenario), "--spec", str(spec), "--out", str(tmp_path / "o"), *extra]
    )
    assert rc == 2
    assert needle in capsys.readouterr().err


def test_missing_scenario_exit_2(tmp_path, capsys):
    spec = tmp_path / "sweep.yaml"
    spec.write_text(SPEC)
    rc = main(["sweep", str(tmp_path / "nope"), "--spec", str(spec), "--out", str(tmp_path / "o")])
    assert rc == 2
    assert "no such scenario folder" in capsys.readouterr().err


def test_critical_config_runs_with_vei_run(demo_scenario, tmp_path, capsys):
    spec = tmp_path / "sweep.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "out"
    assert (
        main(["sweep", str(demo_scenario), "--spec", str(spec), "--out", str(out), "--no-progress"])
        == 0
    )
    crit = pd.read_csv(out / "critical.csv")
    for vid in crit["variant_id"][:2]:
        cfg = out / "configs" / f"{vid}.yaml"
        rc = main(
            [
                "run",
                str(demo_scenario),
                "--config",
                str(cfg),
                "--out",
                str(tmp_path / vid),
                "--no-figures",
            ]
        )
        assert rc == 0
        doc = json.loads((tmp_path / vid / "metrics.json").read_text())
        row = crit[crit["variant_id"] == vid].iloc[0]
        assert doc["time_shift_s"] == pytest.approx(row["time_shift_applied_s"], abs=1e-12)
        assert doc["metrics"]["collision"] == bool(row["collision"])
        assert doc["metrics"]["safety_index"] == pytest.approx(row["safety_index"], abs=1e-12)
        assert doc["metrics"]["min_gap_m"] == pytest.approx(row["min_gap_m"], abs=1e-9)
