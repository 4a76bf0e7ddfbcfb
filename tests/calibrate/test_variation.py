"""`vei calibrate variation` (issue 31.2/31.3): the variation model fitted on the shared
recordings, its leave-one-recording-out coverage, and the defaults being today's fit."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from vei.calibrate.variation import (
    EncounterSpeed,
    RiderSpeed,
    calibrate_variation,
    cruise_interval,
    fit_variation,
    leave_one_out,
    predictive_factor,
)
from vei.cli.main import main


def _riders(ratios_by_rec):
    return [
        RiderSpeed(rec, f"{rec}/r{i}", "cyclist", 3.0, 4.0, np.asarray(r, dtype=np.float64))
        for i, (rec, r) in enumerate(ratios_by_rec)
    ]


def test_fit_by_hand():
    # t_0.95(8) = 1.85955, sqrt(1 + 1/9) = 1.05409, z_0.95 = 1.64485 -> 1.19167
    assert predictive_factor(9) == pytest.approx(1.19167, abs=1e-4)
    assert predictive_factor(10_000) == pytest.approx(1.0, abs=1e-3)
    cruise = [EncounterSpeed(f"r{i}", "d", v, v + 2) for i, v in enumerate([8.0, 10.0, 12.0])]
    riders = _riders([("r0", [0.1, -0.1]), ("r1", [0.2, -0.2])])
    fit = fit_variation(cruise, riders)
    # cv: std([0.8, 1, 1.2]) = 0.163299; factor(3) = 2.91999 * 1.15470 / 1.64485 = 2.04985
    assert fit.cruise_cv == pytest.approx(0.163299 * 2.04985, rel=1e-4)
    assert fit.cruise_median_mps == 10.0 and fit.cruise_max_mps == 14.0
    # rms of the log ratios sqrt((0.01 + 0.01 + 0.04 + 0.04) / 4) = 0.158114, factor(2)
    assert fit.rider_sigma_log == pytest.approx(0.158114 * predictive_factor(2), rel=1e-6)
    assert fit.rider_bounds_mps == {"escooter": 5.556, "cyclist": 8.333}
    from scipy.stats import truncnorm

    lo, hi = cruise_interval(fit, 10.0)
    s = 10.0 * round(fit.cruise_cv, 4)  # the spec's cv, truncated to [1, 14] m/s
    ref = truncnorm((1 - 10) / s, (14 - 10) / s, loc=10.0, scale=s).ppf([0.05, 0.95])
    assert (lo, hi) == pytest.approx(tuple(ref), rel=1e-6)


def test_a_rider_faster_than_the_cited_bound_widens_it():
    cruise = [EncounterSpeed(f"r{i}", "d", v, v) for i, v in enumerate([8.0, 10.0])]
    riders = [RiderSpeed("r0", "r0/a", "escooter", 5.0, 6.2, np.array([0.0, 0.1]))]
    assert fit_variation(cruise, riders).rider_bounds_mps["escooter"] == 6.2


def test_leave_one_out_by_hand():
    cruise = [EncounterSpeed(f"r{i}", "d", v, v) for i, v in enumerate([8.0, 8.5, 9.0, 30.0])]
    riders = _riders([("r0", [0.1, -0.1]), ("r1", [0.1, 2.0]), ("r2", [0.0])])
    cov = leave_one_out(cruise, riders)
    # the 30 m/s encounter lies outside the model fitted on the three slow ones
    rows = {(r.recording, r.quantity): (r.inside, r.n) for r in cov.rows}
    assert rows[("r3", "ego cruise speed")] == (0, 1)
    assert rows[("r1", "rider window speed")] == (1, 2)  # log ratio 2.0 is far out
    assert cov.counts("rider window speed") == (4, 5)
    assert math.isclose(cov.rate("rider window speed"), 0.8)


@pytest.mark.slow
def test_shared_recordings_fit_coverage_and_defaults(trafficmonitoring_root):
    from vei.risk.defaults import (
        CRUISE_SPEED_CV,
        CRUISE_SPEED_MAX_MPS,
        DEFAULT_ABOUT,
        RIDER_MAX_SPEED_MPS,
        RIDER_SPEED_SIGMA_LOG,
    )

    fit, cov = calibrate_variation(trafficmonitoring_root)
    assert fit.n_encounters == 9 and fit.n_riders == 15 and fit.n_windows == 44
    # the declared defaults are today's fit of the shared data
    assert fit.cruise_cv == pytest.approx(CRUISE_SPEED_CV, abs=5e-5)
    assert round(fit.cruise_max_mps, 1) == CRUISE_SPEED_MAX_MPS
    assert fit.rider_sigma_log == pytest.approx(RIDER_SPEED_SIGMA_LOG, abs=5e-5)
    assert fit.rider_bounds_mps == RIDER_MAX_SPEED_MPS
    assert cov.counts("ego cruise speed") == (8, 9)
    assert cov.counts("rider window speed") == (37, 44)
    assert DEFAULT_ABOUT["validation"] == cov.summary()


@pytest.mark.slow
def test_cli_writes_a_spec_that_vei_risk_reads(trafficmonitoring_root, tmp_path, capsys):
    from vei.risk.variation import load_variation

    out = tmp_path / "spec.yaml"
    code = main(
        ["calibrate", "variation", "--root", str(trafficmonitoring_root), "--out", str(out)]
    )
    text = capsys.readouterr().out
    assert code == 0, text
    assert "| **all** | ego cruise speed | 9 | 8 | **89 %** |" in text
    model = load_variation(out)
    assert model.rider is not None and model.rider.speed == "recorded"
    assert dict(model.rider.max_speed_mps) == {"cyclist": 8.333, "escooter": 5.556}
    assert "8/9 (89 %)" in model.description()
    spec = out.read_text()
    assert "# Cited sources:" in spec and "eKFV" in spec and "StVO" in spec
    cov = json.loads((tmp_path / "spec.coverage.json").read_text())
    assert cov["rates"]["ego cruise speed"] == pytest.approx(8 / 9)
    assert (tmp_path / "spec.coverage.md").read_text().startswith("| held-out recording")


def test_cli_refuses_a_missing_dataset(tmp_path, capsys):
    code = main(["calibrate", "variation", "--root", str(tmp_path / "nope")])
    err = capsys.readouterr().err
    assert code == 2 and "nope" in err
