"""A user policy (``path/file.py:Class``) as a choice of a sweep's ``ego.policy``: the
relative path is resolved against the spec file's folder, the policy runs with its
constructor's defaults, and its rows equal ``vei run --policy`` of the same variant."""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest
import yaml
from typer.testing import CliRunner

from tests.experiments.rerun import same_value
from vei.cli.main import app
from vei.errors import ConfigError
from vei.sweep.params import reach_sim, reach_speed_of
from vei.sweep.run import (
    DEFAULT_METRICS,
    EngineEvaluator,
    read_results,
    run_sweep,
    write_variant_configs,
)
from vei.sweep.spec import load_spec, spec_from_dict

REPO = Path(__file__).resolve().parents[2]
EXAMPLE = REPO / "examples" / "my_policy.py"


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory) -> Path:
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


def _spec_file(folder: Path, policy_choices: list) -> Path:
    path = folder / "spec.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "design": "grid",
                "base": "normal-cap",
                "parameters": {
                    "time_shift_s": -1.0,
                    "ego.cruise_speed_mps": 7.0,
                    "ego.policy": {"choices": policy_choices},
                },
            }
        )
    )
    return path


def test_relative_policy_path_is_resolved_against_the_spec_folder(tmp_path) -> None:
    rel = os.path.relpath(EXAMPLE, tmp_path)
    assert not Path(rel).is_absolute() and rel.startswith("..")
    spec = load_spec(_spec_file(tmp_path, ["none", f"{rel}:MyPolicy"]))
    assert spec.param("ego.policy").choices == ("none", f"{EXAMPLE}:MyPolicy")
    assert spec_from_dict(spec.to_dict()) == spec  # round trip (absolute path)


@pytest.mark.parametrize(
    ("choice", "message"),
    [
        ("nope.py:MyPolicy", "not found"),
        (f"{EXAMPLE}:NoSuchClass", "has no 'NoSuchClass'"),
        ("not a policy", "expected a built-in name"),
    ],
)
def test_bad_user_policy_stops_the_spec(tmp_path, choice, message) -> None:
    path = _spec_file(tmp_path, ["none", choice])
    with pytest.raises(ConfigError) as exc:
        load_spec(path)
    assert str(path) in str(exc.value) and message in str(exc.value)


def test_user_policy_rows_differ_from_none_and_equal_vei_run(
    demo_scenario, tmp_path, monkeypatch
) -> None:
    monkeypatch.chdir(REPO)  # vei run --policy examples/...: relative to the working directory
    rel = os.path.relpath(EXAMPLE, tmp_path)
    spec = load_spec(_spec_file(tmp_path, ["none", f"{rel}:MyPolicy"]))
    res = run_sweep(demo_scenario, spec, tmp_path / "sweep", chunk_size=64, progress=False)
    assert (res.n_variants, res.n_run) == (2, 2)
    df = read_results(tmp_path / "sweep")
    none_row = df[df["ego.policy"] == "none"].iloc[0]
    user_row = df[df["ego.policy"] != "none"].iloc[0]
    # PID cruise at 7 m/s runs into the rider on the demo; the example policy brakes.
    assert bool(none_row["collision"]) and not bool(user_row["collision"])
    assert user_row["peak_decel_mps2"] > 3.0 > none_row["peak_decel_mps2"]

    auto = (
        EngineEvaluator(base="normal-cap", sim=reach_sim(reach_speed_of(spec)))
        .prepare(demo_scenario)
        .auto_shift_s
    )
    cfg_none, cfg_user = write_variant_configs(
        tmp_path / "configs",
        df.set_index("variant_id")
        .loc[[none_row["variant_id"], user_row["variant_id"]]]
        .reset_index(),
        spec,
        auto,
    )
    runner = CliRunner()
    for k, (args, row) in enumerate(
        (
            (["--config", str(cfg_none)], none_row),
            (["--config", str(cfg_user)], user_row),
            (["--config", str(cfg_none), "--policy", "examples/my_policy.py:MyPolicy"], user_row),
        )
    ):
        out = tmp_path / "runs" / f"run{k}"
        r = runner.invoke(
            app, ["run", str(demo_scenario), *args, "--out", str(out), "--no-figures"]
        )
        assert r.exit_code == 0, r.output
        metrics = json.loads((out / "metrics.json").read_text())["metrics"]
        for name in DEFAULT_METRICS:
            assert same_value(row[name], metrics[name]), (args, name, row[name], metrics[name])
