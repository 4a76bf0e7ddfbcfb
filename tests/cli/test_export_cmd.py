"""`vei export openscenario` and `vei export check` end to end."""

from __future__ import annotations

import numpy as np
import pytest

from tests.sim.backends.conftest import MEETING_SHIFT_S, crossing_scenario, write_straight_xodr
from vei.cli.main import main
from vei.export.openscenario import read_openscenario_trajectories
from vei.export.validate import validate_openscenario
from vei.io.scenario import write_scenario


@pytest.fixture()
def scenario_dir(tmp_path):
    folder = tmp_path / "scenario"
    write_scenario(crossing_scenario(folder), folder, extra_files={"map.xodr": write_straight_xodr})
    return folder


def test_export_replay_then_check(tmp_path, scenario_dir, capsys):
    out = tmp_path / "osc"
    assert main(["export", "openscenario", str(scenario_dir), "--out", str(out)]) == 0
    xosc = out / "crossing.xosc"
    assert xosc.is_file() and (out / "map.xodr").is_file()
    assert validate_openscenario(xosc) == []
    back = read_openscenario_trajectories(xosc)
    assert set(back["agent_id"]) == {"ego", "s7", "c1"}
    # the recorded scooter: 2 s .. 7 s, with its run-in before (from t = 0 on) and its
    # run-out after (issue 22), its recorded span written as a property
    vx = back[(back["agent_id"] == "s7") & (back["kind"] == "vertex")]
    assert vx["t_s"].min() == pytest.approx(0.0) and vx["t_s"].max() > 7.5
    assert 'name="vei:recorded_span_s" value="2 7"' in xosc.read_text()
    assert main(["export", "check", str(xosc), "--no-qc"]) == 0
    assert "0 error(s)" in capsys.readouterr().out


def test_export_simulated_config_passes_xsd_and_checker(tmp_path, scenario_dir, capsys):
    from vei.experiments.casestudy import run_casestudy
    from vei.export.qc import find_qc_openscenario
    from vei.io.scenario import read_scenario

    out = tmp_path / "osc"
    args = ["export", "openscenario", str(scenario_dir), "--out", str(out), "--config", "normal-cap",
            "--time-shift", str(MEETING_SHIFT_S)]  # fmt: skip
    assert main(args) == 0
    xosc = out / "crossing_normal-cap.xosc"
    assert validate_openscenario(xosc) == []
    # round trip against the same run of the engine
    frame = run_casestudy(
        read_scenario(scenario_dir), cases=["normal-cap"], time_shift=MEETING_SHIFT_S
    ).frame
    back = read_openscenario_trajectories(xosc)
    for agent in ("ego", "s7"):
        tr = frame[(frame["agent_id"] == agent) & frame["active"]].sort_values("t_s")
        vx = back[(back["agent_id"] == agent) & (back["kind"] == "vertex")]
        x = np.interp(tr["t_s"], vx["t_s"], vx["x_m"])
        y = np.interp(tr["t_s"], vx["t_s"], vx["y_m"])
        assert np.hypot(x - tr["x_m"], y - tr["y_m"]).max() <= 0.05 + 1e-4
    try:
        find_qc_openscenario()
    except Exception:
        if __import__("os").environ.get("VEI_QC_BIN"):
            raise
        pytest.skip("ASAM quality checker absent and VEI_QC_BIN unset")
    capsys.readouterr()
    assert main(["export", "check", str(xosc)]) == 0
    text = capsys.readouterr().out
    assert "0 issue(s)" in text and "0 error(s)" in text


def test_check_reports_schema_errors_with_exit_code_1(tmp_path, scenario_dir, capsys):
    out = tmp_path / "osc"
    assert (
        main(
            ["export", "openscenario", str(scenario_dir), "--out", str(out), "--osc-version", "1.0"]
        )
        == 0
    )
    xosc = out / "crossing.xosc"
    broken = tmp_path / "broken.xosc"
    broken.write_text(
        xosc.read_text().replace('vehicleCategory="bicycle"', 'vehicleCategory="scooter"')
    )
    assert main(["export", "check", str(broken), "--no-qc"]) == 1
    assert "vehicleCategory" in capsys.readouterr().out


def test_user_errors_exit_2(tmp_path, scenario_dir):
    assert main(["export", "check", str(tmp_path / "missing.xosc")]) == 2
    assert (
        main(
            [
                "export",
                "openscenario",
                str(scenario_dir),
                "--out",
                str(tmp_path / "o"),
                "--osc-version",
                "2.0",
            ]
        )
        == 2
    )
    assert (
        main(["export", "openscenario", str(tmp_path / "nowhere"), "--out", str(tmp_path / "o")])
        == 2
    )


def test_check_plays_in_esmini_and_writes_reports_only_where_told(
    tmp_path, scenario_dir, esmini, capsys, monkeypatch
):
    out = tmp_path / "osc"
    assert main(["export", "openscenario", str(scenario_dir), "--out", str(out)]) == 0
    xosc = out / "crossing.xosc"
    before = sorted(p.name for p in out.iterdir())
    reports = tmp_path / "reports"
    args = ["export", "check", str(xosc), "--no-qc", "--esmini", str(esmini.root),
            "--report-dir", str(reports)]  # fmt: skip
    capsys.readouterr()
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "esmini playback" in text and "0 issue(s)" in text
    assert (reports / "playback.csv").is_file() and (reports / "esmini" / "run.dat").is_file()
    table = __import__("pandas").read_csv(reports / "playback.csv")
    assert set(table["name"]) == {"ego", "s7", "c1"}
    assert (table["outside"] == 0).all() and (table["max_dev_m"] < 0.3).all()
    # without --report-dir: a temporary folder; nothing is ever written beside the input
    monkeypatch.setenv("VEI_ESMINI", str(esmini.root))
    assert main(["export", "check", str(xosc), "--no-qc"]) == 0
    text = capsys.readouterr().out
    assert "esmini playback" in text and "vei-check-" in text
    assert sorted(p.name for p in out.iterdir()) == before
    # --no-play: XSD only
    assert main(["export", "check", str(xosc), "--no-qc", "--no-play"]) == 0
    assert "esmini playback" not in capsys.readouterr().out


def test_check_flags_a_file_that_plays_wrong_and_a_missing_esmini(
    tmp_path, scenario_dir, esmini, capsys
):
    out = tmp_path / "osc"
    assert main(["export", "openscenario", str(scenario_dir), "--out", str(out)]) == 0
    xosc = out / "crossing.xosc"
    # valid XML and XSD, but the ego's trajectory is shifted by 2 s
    shifted = out / "shifted.xosc"
    shifted.write_text(xosc.read_text().replace('offset="0.0"', 'offset="2.0"', 1))
    args = ["export", "check", str(shifted), "--no-qc", "--esmini", str(esmini.root),
            "--report-dir", str(tmp_path / "r")]  # fmt: skip
    capsys.readouterr()
    assert main(args) == 1
    text = capsys.readouterr().out
    assert "0 error(s)" in text and "from the file's trajectory" in text
    # an esmini folder that is given and absent is a user error
    assert main(["export", "check", str(xosc), "--no-qc", "--esmini", str(tmp_path / "no")]) == 2
    assert "esmini not found" in capsys.readouterr().err


def test_a_checker_asked_for_and_missing_is_exit_2(tmp_path, scenario_dir, capsys):
    out = tmp_path / "osc"
    assert main(["export", "openscenario", str(scenario_dir), "--out", str(out)]) == 0
    xosc = out / "crossing.xosc"
    args = ["export", "check", str(xosc), "--no-play", "--qc-bin", str(tmp_path / "nope")]
    assert main(args) == 2
    assert "qc_openscenario" in capsys.readouterr().err
