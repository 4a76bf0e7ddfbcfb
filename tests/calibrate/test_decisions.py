"""The rider's yield / go decision on the recordings (vei.calibrate.decisions,
decision_validate, ``vei calibrate decisions``): the cases the shared data hold, the
Firth-penalised logistic fit (recovers a known model; finite on separated cases), the
leave-one-scenario-out validation."""

from __future__ import annotations

import json

import numpy as np
import pytest

from vei.calibrate.decision_validate import first_stop, validate_decisions
from vei.calibrate.decisions import DecisionCase, extract_cases, fit_gap_acceptance
from vei.cli.main import main
from vei.errors import InputError


def _case(dta: float, outcome: str) -> DecisionCase:
    return DecisionCase("s", "r", "cyclist", "v", False, 0.0, dta, 1.0, 1.0, 3.0, 8.0,
                        outcome, False, 1.0)  # fmt: skip


def test_the_fit_recovers_a_known_logistic() -> None:
    rng = np.random.default_rng(3)
    dta = rng.uniform(-6, 6, 4000)
    go = rng.random(4000) < 1 / (1 + np.exp(-(dta - 1.0) / 0.8))
    fit = fit_gap_acceptance(
        [_case(d, "go" if g else "yield") for d, g in zip(dta, go, strict=True)], bootstrap=0
    )
    assert fit.critical_gap_s == pytest.approx(1.0, abs=0.1)
    assert fit.scale_s == pytest.approx(0.8, rel=0.15)
    assert not fit.separated


def test_separated_cases_give_a_finite_fit_between_them() -> None:
    fit = fit_gap_acceptance(
        [_case(-2.0, "yield"), _case(2.5, "go"), _case(3.5, "go")], bootstrap=50
    )
    assert fit.separated and np.isfinite(fit.scale_s) and fit.scale_s > 0
    assert -2.0 < fit.critical_gap_s < 2.5
    with pytest.raises(InputError, match="at least one go and one yield"):
        fit_gap_acceptance([_case(1.0, "go")])


def test_first_stop_after_riding() -> None:
    sp = np.r_[np.zeros(40), np.full(40, 3.0), np.full(30, 0.2), np.full(10, 3.0)]
    assert first_stop(sp, 0.05) == 80  # the wait at the start is no stop
    assert first_stop(np.zeros(50), 0.05) == -1


def test_cases_of_the_shared_recordings(tm_scenes) -> None:
    """The shared data hold three yield / go cases: the instrumented car's right turn
    (audi_08_..._02) passed in front of by cyclist 2 and let go first by cyclist 5, and
    cyclist 4 crossing in front of vehicle 13 (klinikum_01)."""
    cases = extract_cases(tm_scenes)
    got = {(c.scenario, c.rider, c.vehicle): c for c in cases}
    assert len(cases) == 3
    go1 = got[("audi_08_klinikum_rechtsabbiegen_02", "2", "7")]
    yld = got[("audi_08_klinikum_rechtsabbiegen_02", "5", "9")]
    go2 = got[("klinikum_01_marktkauf_geradeaus", "4#0", "13")]
    assert go1.outcome == "go" and go1.instrumented and go1.dta_s > 3.0
    assert yld.outcome == "yield" and yld.dta_s < -2.0 and not yld.stopped
    assert go2.outcome == "go" and go2.dta_s > 2.0
    assert all(c.pet_s <= 6.0 for c in cases)
    fit = fit_gap_acceptance(cases, bootstrap=0)
    assert fit.separated and yld.dta_s < fit.critical_gap_s < go2.dta_s


@pytest.mark.slow
def test_leave_one_scenario_out_and_the_cli(
    tm_scenes, trafficmonitoring_root, tmp_path, capsys
) -> None:
    val = validate_decisions(tm_scenes)
    assert val.open_loop_correct.all() and val.closed_loop_correct.all()
    assert len(val.cases) == 3
    # riders that do not stop: no worse than the calibrated SFM (the decisions do not act)
    for h in (3.0, 5.0):
        assert val.ade_m["SFM decisions"][h] <= val.ade_m["SFM calibrated"][h] + 1e-9
        assert val.fde_m["SFM decisions"][h] <= val.fde_m["SFM calibrated"][h] + 1e-9
    assert len(val.stops) >= 1
    code = main(
        ["calibrate", "decisions", "--root", str(trafficmonitoring_root), "--out", str(tmp_path)]
    )
    assert code == 0
    text = capsys.readouterr().out
    assert "recorded decisions: 3 (2 go, 1 yield" in text and "closed loop 3/3" in text
    doc = json.loads((tmp_path / "decisions.json").read_text())
    assert len(doc["cases"]) == 3 and doc["fit"]["separated"]
    assert (
        main(["calibrate", "decisions", "--root", str(trafficmonitoring_root), "--horizon-s", "0"])
        == 2
    )


def test_a_deciding_population_spreads_its_critical_gaps() -> None:
    """Riders sampled from a profile for a case that decides get their own critical gaps,
    logistic around the case's (location 0 s, scale 2 s): some never yield."""
    from dataclasses import replace

    from vei.calibrate.population import population_cases, sample_critical_gaps
    from vei.config import DecisionConfig, RiderPopulationConfig, case_preset

    case = replace(case_preset("normal"), decision=DecisionConfig(enabled=True))
    riders = population_cases(case, RiderPopulationConfig(sample=400, seed=5))
    tc = np.array([c.decision.critical_gap_s for c in riders])
    assert np.median(tc) == pytest.approx(0.0, abs=0.4)
    # logistic quantiles: 5 % at -2 ln 19 = -5.9 s, 95 % at +5.9 s
    assert np.quantile(tc, 0.05) == pytest.approx(-5.9, abs=1.0)
    assert np.quantile(tc, 0.95) == pytest.approx(5.9, abs=1.0)
    assert sample_critical_gaps(DecisionConfig(), 3, 0) is None
    same = population_cases(case, RiderPopulationConfig(sample=400, seed=5))
    assert [c.decision.critical_gap_s for c in same] == tc.tolist()  # seeded


def test_a_calibration_that_cannot_fit_says_why() -> None:
    """One usable case (a go): no fit, and the text and decisions.json say why (issue
    32.4: it used to write "fit": null and print nothing about it)."""
    from vei.calibrate.decision_validate import ARRIVE_FIRST_S, DecisionValidation
    from vei.calibrate.decisions import no_fit_reason

    one = [_case(2.5, "go")]
    why = no_fit_reason(one)
    assert why == (
        "the gap-acceptance fit needs at least one go and one yield case; the 1 usable case "
        "is 1 go and 0 yield"
    )
    assert "no recorded yield / go case" in no_fit_reason([])
    assert no_fit_reason([_case(2.5, "go"), _case(-1.0, "yield")]) is None
    with pytest.raises(InputError, match="the 1 usable case is 1 go and 0 yield"):
        fit_gap_acceptance(one)
    val = DecisionValidation(
        tuple(one), None, {"s": ARRIVE_FIRST_S, "t": ARRIVE_FIRST_S}, np.ones(1, bool),
        np.ones(1, bool), (), fit_reason=why, folds_without_fit={"s": no_fit_reason([]), "t": why},
    )  # fmt: skip
    text = val.format()
    assert f"fit: none: {why}" in text
    assert "fold without s: no fit (no recorded yield / go case" in text
    assert "its critical gap is the default +0.00 s" in text
    doc = val.to_dict()
    assert doc["fit"] is None and doc["fit_reason"] == why
    assert doc["folds_without_fit"]["t"] == why


@pytest.mark.slow
def test_one_usable_case_of_the_shared_recordings_is_reported(tm_scenes) -> None:
    """Without audi_08_..._02 the shared data hold one case (cyclist 4's go at
    klinikum_01): the validation runs and says why there is no fit."""
    scenes = [s for s in tm_scenes if s.scenario != "audi_08_klinikum_rechtsabbiegen_02"]
    val = validate_decisions(scenes)
    assert len(val.cases) == 1 and val.fit is None
    assert "1 go and 0 yield" in val.fit_reason
    assert "fit: none: the gap-acceptance fit needs at least one go" in val.format()
    assert val.to_dict()["fit_reason"] == val.fit_reason
