"""What `vei import trafficmonitoring` says: time ranges that are times, and a warning when
the car's own camera track sits far from its INS (a sync or calibration problem)."""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

from vei.cli.main import main
from vei.datasets.trafficmonitoring import OWN_TRACK_WARN_M, import_scenario_with_summary

NAME = "stadtmitte_12_audi_geradeaus_03"


def _copy_with_video_late_by(root: Path, dst: Path, late_s: float) -> Path:
    """The dataset with every file linked, but the video start of NAME moved ``late_s``
    later: the camera tracks (the car's own among them) slide against the INS."""
    meas = dst / "data" / "measurements"
    for sub in ("car_data", "videos/trajectory_output", "matching"):
        (meas / sub).mkdir(parents=True)
        for f in (root / "data" / "measurements" / sub).iterdir():
            os.symlink(f, meas / sub / f.name)
    match = meas / "matching" / f"{NAME}_matching.csv"
    lines = Path(os.readlink(match)).read_text().splitlines()
    match.unlink()
    head, row = lines[0], lines[1].split(",")
    import pandas as pd

    row[0] = str(pd.Timestamp(row[0]) + pd.Timedelta(seconds=late_s))
    match.write_text(head + "\n" + ",".join(row) + "\n")
    return dst


def test_summary_prints_times_and_track_lengths(trafficmonitoring_root, tmp_path, capsys):
    code = main(["import", "trafficmonitoring", "--root", str(trafficmonitoring_root),
                 "--scenario", NAME, "--out", str(tmp_path / "inter")])  # fmt: skip
    cap = capsys.readouterr()
    assert code == 0
    cats = [line for line in cap.out.splitlines() if "annotations at 1 Hz" in line]
    assert cats and all("present t = " in c and "each track " in c for c in cats)
    assert "seen 1" not in cap.out  # the old 'seen <duration range>' wording
    assert "warning" not in cap.err  # the car's own track is 0.2-0.4 m from its INS here


def test_a_car_track_far_from_its_ins_is_a_warning(trafficmonitoring_root, tmp_path, capsys):
    """The video shifted by 0.8 s: the car (several m/s) is seen where it was 0.8 s
    earlier, metres from its INS fix; the import says so."""
    root = _copy_with_video_late_by(trafficmonitoring_root, tmp_path / "tm", 0.8)
    s = import_scenario_with_summary(root, NAME, tmp_path / "late")
    assert s.own_track_median_m > OWN_TRACK_WARN_M
    assert s.warnings and "out of sync" in s.warnings[0]
    shutil.rmtree(tmp_path / "late")
    code = main(["import", "trafficmonitoring", "--root", str(root), "--scenario", NAME,
                 "--out", str(tmp_path / "late")])  # fmt: skip
    err = " ".join(capsys.readouterr().err.split())
    assert code == 0
    assert f"warning: the car's own camera track lies {s.own_track_median_m:.2f} m" in err
    good = import_scenario_with_summary(trafficmonitoring_root, NAME, tmp_path / "good")
    assert good.own_track_median_m < OWN_TRACK_WARN_M and good.warnings == ()


@pytest.mark.parametrize(("median", "warns"), [(None, False), (0.42, False), (1.5, True)])
def test_warning_threshold(median, warns, tmp_path):
    from datetime import UTC, datetime

    from vei.datasets.trafficmonitoring import ImportSummary

    now = datetime.now(UTC)
    s = ImportSummary(NAME, tmp_path, now, now, 0.0, 10.0, {}, 0, median, median)
    assert bool(s.warnings) is warns
