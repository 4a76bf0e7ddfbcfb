"""`vei reconstruct --interp kalman --ego-path kalman` on a shared recording: the scenario
folder holds the band figure, the terminal reports calibration, noise and the ego path."""

import pytest

from vei.cli.main import main
from vei.io.scenario import read_scenario


def test_reconstruct_kalman_writes_band_and_reports_calibration(
    trafficmonitoring_root, tmp_path, capsys
):
    from vei.datasets.trafficmonitoring import import_scenario

    src = import_scenario(trafficmonitoring_root, "klinikum_01_marktkauf_geradeaus", tmp_path / "i")
    out = tmp_path / "scen"
    args = [
        "reconstruct",
        str(src),
        "--out",
        str(out),
        "--interp",
        "kalman",
        "--ego-path",
        "kalman",
    ]
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "95 % interval coverage" in text and "kalman noise (ml" in text
    assert "ego path (kalman" in text and "max |lateral accel|" in text
    assert (out / "uncertainty.png").stat().st_size > 10_000
    sc = read_scenario(out)
    rec = sc.extra["reconstruction"]
    assert rec["config"]["interp"] == "kalman" and rec["config"]["ego_path"] == "kalman"
    assert rec["noise"]["noise_m"] == pytest.approx(0.217, abs=0.01)  # measured
    # The written scenario is enough to resample the rider (noise and keyframes stored).
    from vei.recon.samples import sample_rider

    assert sample_rider(sc, 3, seed=0).xy_m.shape[0] == 3


def test_reconstruct_refuses_an_unknown_ego_path(tmp_path, capsys):
    from tests.helpers_interaction import make_interaction

    src = make_interaction(tmp_path)
    code = main(["reconstruct", str(src), "--out", str(tmp_path / "s"), "--ego-path", "gps"])
    assert code == 2
    assert "ego_path must be 'spline' or 'kalman'" in capsys.readouterr().err
