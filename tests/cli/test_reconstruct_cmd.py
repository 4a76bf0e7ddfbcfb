import json

import pandas as pd
import pytest

from tests.helpers_interaction import make_interaction
from vei.cli.main import main
from vei.io.scenario import read_scenario


def test_reconstruct_writes_scenario_figure_and_prints_errors(tmp_path, capsys):
    src = make_interaction(tmp_path)
    out = tmp_path / "scen"
    assert (
        main(
            ["reconstruct", str(src), "--out", str(out), "--rate-hz", "10", "--interp", "smoothing"]
        )
        == 0
    )
    text = capsys.readouterr().out
    assert "RMSE" in text and "escooter_1 *" in text and "cyclist_2" in text
    assert "primary threat (*): escooter_1" in text
    assert "mean RMSE 0.000 m" in text
    for name in ("scenario.json", "trajectories.parquet", "keyframes.parquet", "birdseye.png"):
        assert (out / name).is_file()
    sc = read_scenario(out)
    assert sc.rate_hz == 10.0
    assert sc.extra["reconstruction"]["config"]["interp"] == "smoothing"
    assert sc.extra["reconstruction_error"]["riders"]["max_error_m"] < 1e-3
    traj = pd.read_parquet(out / "trajectories.parquet")
    assert set(traj["agent_id"]) == {"ego", "escooter_1", "cyclist_2"}
    doc = json.loads((out / "scenario.json").read_text())
    assert doc["primary_threat"] == "escooter_1"


def test_without_ground_truth_no_error_columns(tmp_path, capsys):
    src = make_interaction(tmp_path, ground_truth=None)
    assert main(["reconstruct", str(src), "--out", str(tmp_path / "s"), "--no-figure"]) == 0
    text = capsys.readouterr().out
    assert "RMSE" not in text and "primary threat" in text
    assert not (tmp_path / "s" / "birdseye.png").exists()
    assert "reconstruction_error" not in read_scenario(tmp_path / "s").extra


@pytest.mark.parametrize(
    "args",
    [
        ["--interp", "quadratic"],
        ["--rate-hz", "0"],
    ],
)
def test_bad_options_exit_2(tmp_path, args):
    src = make_interaction(tmp_path)
    assert main(["reconstruct", str(src), "--out", str(tmp_path / "s"), *args]) == 2
    assert not (tmp_path / "s").exists()


def test_missing_interaction_exits_2_with_message(tmp_path, capsys):
    assert main(["reconstruct", str(tmp_path / "nope"), "--out", str(tmp_path / "s")]) == 2
    assert "nope" in capsys.readouterr().err
