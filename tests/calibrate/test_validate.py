"""Leave-one-scenario-out validation on the shared data: the must-show of issue 11."""

from __future__ import annotations

import pytest

from vei.calibrate.validate import MODELS, ValidationTable, validate_loso
from vei.errors import InputError


@pytest.fixture(scope="session")
def table(tm_scenes) -> ValidationTable:
    # The one expensive test of the package (~40 s CPU: four leave-one-out fits).
    return validate_loso(tm_scenes, (3.0, 5.0))


@pytest.mark.slow
def test_calibrated_sfm_beats_cv_by_20_percent_and_the_paper(table) -> None:
    assert table.folds == (
        "audi_08_klinikum_rechtsabbiegen_02",
        "audi_10_marktkauf_linksabbiegen",
        "klinikum_01_marktkauf_geradeaus",
        "stadtmitte_12_audi_geradeaus_03",
    )
    assert table.n_windows[3.0] >= 200 and table.n_windows[5.0] >= 150
    # Must-show: ADE at 3 s at least 20 % below constant velocity, and below the paper's SFM.
    assert table.gain("SFM calibrated", "CV", 3.0) >= 0.20
    assert table.ade_m["SFM calibrated"][3.0] < table.ade_m["SFM paper"][3.0]
    for h in (3.0, 5.0):
        assert table.ade_m["SFM calibrated"][h] < table.ade_m["CV"][h]
        assert table.fde_m["SFM calibrated"][h] < table.fde_m["SFM paper"][h]
        # Constant acceleration extrapolates the smoothed acceleration: worst of all.
        assert table.ade_m["CA"][h] == max(table.ade_m[m][h] for m in MODELS)
    # Knowing only the start speed (what CV knows) the calibrated SFM still beats the
    # route-aware constant-speed baseline at 3 s (reported, not claimed for 'calibrated').
    assert table.ade_m["SFM start-speed"][3.0] < table.ade_m["CS-path"][3.0]
    # Plausibility: errors of riders at 1-5 m/s over 3 s are metres, not tens of metres.
    assert 0.2 < table.ade_m["SFM calibrated"][3.0] < 2.0
    text = table.format()
    assert "SFM calibrated" in text and "held-out scenarios: 4" in text


def test_per_category_lines_and_json(table) -> None:
    n = table.n_windows_by_category
    assert n["escooter"][3.0] + n["cyclist"][3.0] == table.n_windows[3.0]
    assert n["escooter"][3.0] > 0
    assert "ADE escooter: 3 s" in table.format()
    doc = table.to_dict()
    assert doc["n_windows"]["3"] == table.n_windows[3.0]
    assert doc["ade_m"]["SFM calibrated"]["5"] == table.ade_m["SFM calibrated"][5.0]


def test_needs_two_scenarios_with_riders(tm_scenes) -> None:
    one = [s for s in tm_scenes if s.scenario == "stadtmitte_12_audi_geradeaus_03"]
    with pytest.raises(InputError, match=">= 2 scenarios"):
        validate_loso(one)
