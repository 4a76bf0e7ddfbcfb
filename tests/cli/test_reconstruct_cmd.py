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
        ["--posterior-std-inflation", "0"],
        ["--posterior-std-inflation", "wide"],
    ],
)
def test_bad_options_exit_2(tmp_path, args):
    src = make_interaction(tmp_path)
    assert main(["reconstruct", str(src), "--out", str(tmp_path / "s"), *args]) == 2
    assert not (tmp_path / "s").exists()


def test_missing_interaction_exits_2_with_message(tmp_path, capsys):
    assert main(["reconstruct", str(tmp_path / "nope"), "--out", str(tmp_path / "s")]) == 2
    assert "nope" in capsys.readouterr().err


def test_map_from_the_real_ingolstadt_network_is_attached_and_aligned(
    trafficmonitoring_root, data_dir, tmp_path, capsys
):
    """`--map FILE`: the real SUMO network of the recorded intersection becomes the
    scenario's OpenDRIVE map in the scenario's own plane; the recorded car lies on it."""
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.report.birdseye import plot_birdseye

    net = data_dir / "maps" / "ingolstadt_research_intersection.net.xml.gz"
    inter = import_scenario(
        trafficmonitoring_root, "klinikum_01_marktkauf_geradeaus", tmp_path / "i"
    )
    out = tmp_path / "scen"
    assert main(["reconstruct", str(inter), "--out", str(out), "--map", str(net)]) == 0
    assert "ego samples on a drivable lane" in capsys.readouterr().out
    sc = read_scenario(out)
    assert sc.maps["opendrive"] == "map.xodr" and (out / "map.xodr").is_file()
    info = sc.extra["map"]
    assert info["schema_valid"] and info["projection"] == sc.projection
    # Measured 0.994 (the car drives its lane through the intersection).
    assert info["ego_on_drivable_share"] >= 0.98
    assert "geoReference" in (out / "map.xodr").read_text()[:5000]
    # Figures of a scenario with a map draw its roads underneath (polygon collections).
    fig_with = plot_birdseye(sc)
    fig_without = plot_birdseye(sc, roads=lambda ax: None)
    assert len(fig_with.axes[0].collections) >= len(fig_without.axes[0].collections) + 2


def test_bad_map_source_is_a_clean_error(tmp_path, capsys):
    src = make_interaction(tmp_path)
    bad = tmp_path / "roads.txt"
    bad.write_text("not a map")
    rc = main(["reconstruct", str(src), "--out", str(tmp_path / "s"), "--map", str(bad)])
    assert rc == 2
    assert not (tmp_path / "s").exists()


def test_kalman_coverage_is_labelled_in_sample_with_the_factor_used(tmp_path, capsys):
    src = make_interaction(tmp_path)
    out = tmp_path / "scen"
    args = ["reconstruct", str(src), "--out", str(out), "--interp", "kalman", "--no-figure"]
    assert main([*args, "--posterior-std-inflation", "2"]) == 0
    text = " ".join(capsys.readouterr().out.split())  # rich wraps long lines
    assert "95 % interval coverage in-sample" in text
    assert "python -m benchmarks recon_accuracy" in text and "posterior std x 2.000" in text
    noise = read_scenario(out).extra["reconstruction"]["noise"]
    assert noise["std_inflation"] == 2.0


def test_default_auto_reports_its_choice_and_cubic_warns_on_dense_tracks(tmp_path, capsys):
    from tests.helpers_interaction import make_curve_interaction

    src = tmp_path / "curve"
    make_curve_interaction(src, 30.0)  # one cyclist at 4 m/s, 30 Hz, 0.2 m noise
    assert main(["reconstruct", str(src), "--out", str(tmp_path / "a"), "--no-figure"]) == 0
    cap = capsys.readouterr()
    assert (
        "interpolation auto" in cap.out and "smoothing for 1 dense track(s) (cyclist_7)" in cap.out
    )
    assert "warning" not in cap.err
    sc = read_scenario(tmp_path / "a")
    rec = sc.extra["reconstruction"]
    assert rec["config"]["interp"] == "auto" and rec["tracks"][0]["method"] == "smoothing"
    assert rec["auto_interp"]["smoothing"] == ["cyclist_7"]
    args = [
        "reconstruct",
        str(src),
        "--out",
        str(tmp_path / "c"),
        "--no-figure",
        "--interp",
        "cubic",
    ]
    assert main(args) == 0  # a warning, not an error
    cap = capsys.readouterr()
    assert "interpolation auto" not in cap.out
    (line,) = [x for x in cap.err.splitlines() if x.startswith("warning:")]
    assert "cyclist_7 (cyclist): reconstructed speed" in line and "--interp auto" in line
    assert len(read_scenario(tmp_path / "c").extra["reconstruction"]["speed_warnings"]) == 1
