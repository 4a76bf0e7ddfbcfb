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
    # the recorded scooter: 2 s .. 7 s
    vx = back[(back["agent_id"] == "s7") & (back["kind"] == "vertex")]
    assert vx["t_s"].min() == pytest.approx(2.0) and vx["t_s"].max() == pytest.approx(7.0)
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
