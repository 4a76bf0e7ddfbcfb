"""`vei calibrate riders|validate` on the shared data: outputs, messages, user errors."""

from __future__ import annotations

import json

from vei.cli.main import main


def test_riders_writes_profile_report_and_figure(trafficmonitoring_root, tmp_path, capsys) -> None:
    out = tmp_path / "cal"
    code = main(
        [
            "calibrate",
            "riders",
            "--root",
            str(trafficmonitoring_root),
            "--out",
            str(out),
            "--scenario",
            "stadtmitte_12_audi_geradeaus_03",
            "--category",
            "escooter",
            "--bootstrap",
            "0",
        ]
    )
    text = capsys.readouterr().out
    assert code == 0, text
    assert "fitted 2 rider tracks" in text
    prof = json.loads((out / "riders_profile.json").read_text())
    assert prof["format"] == "vei.rider_profile/1"
    assert {t["category"] for t in prof["tracks"]} == {"escooter"}
    assert set(prof["populations"]) == {"all", "escooter"}
    report = (out / "fit_report.md").read_text()
    assert "## Per-track fits (2 tracks)" in report and "Dropped tracks" in report
    assert (out / "speed_accel_distributions.png").stat().st_size > 10_000
    rep = json.loads((out / "fit_report.json").read_text())
    assert rep["distributions"]["escooter"]["data_speed"]["0.5"] > 0.5


def test_user_errors_exit_2(tmp_path, capsys, trafficmonitoring_root) -> None:
    assert main(["calibrate", "riders", "--root", str(tmp_path), "--out", str(tmp_path / "o")]) == 2
    assert "data/measurements" in capsys.readouterr().err
    args = [
        "calibrate",
        "riders",
        "--root",
        str(trafficmonitoring_root),
        "--out",
        str(tmp_path / "o"),
    ]
    assert main([*args, "--category", "bike"]) == 2
    assert "--category" in capsys.readouterr().err
    assert main([*args, "--horizon-s", "0.1"]) == 2
    # A scenario with no rider at all: nothing to fit, said so.
    assert main([*args, "--scenario", "marktkauf_05_klinikum_geradeaus"]) == 2
    assert "no rider track passes the filter" in capsys.readouterr().err
    assert (
        main(["calibrate", "validate", "--root", str(trafficmonitoring_root), "--horizons", "3,x"])
        == 2
    )
    assert not (tmp_path / "o" / "riders_profile.json").exists()
