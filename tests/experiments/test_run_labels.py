"""Labels that say what ran (issue 32.4): the behaviour switches of every run, what V2X did
(and that it changed nothing where it did), 'avoided' only where the reference collided,
the criticality banner about the recorded paths, the bird's-eye figures with every road
user that can hide the rider."""

from __future__ import annotations

import io
import math
from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from vei.config import (
    DecisionConfig,
    PerceptionConfig,
    TrafficConfig,
    V2XConfig,
    case_preset,
)
from vei.experiments.casestudy import NOTHING_TO_AVOID, add_verdicts, run_casestudy
from vei.experiments.run_labels import switches, switches_text
from vei.experiments.v2x_study import PPP_GNSS_STD_M, occluded_crossing, study_case


def test_switches_name_every_behaviour_model_that_ran():
    assert switches_text(case_preset("normal")) == "none"
    case = replace(
        case_preset("normal-cap"),
        decision=DecisionConfig(enabled=True),
        traffic=TrafficConfig(cars_react=True, pedestrians=True),
        v2x=V2XConfig(enabled=True, penetration_rate=0.5),
        perception=PerceptionConfig(enabled=True),
    )
    assert switches(case) == (
        "decisions", "traffic (cars react, pedestrians social force)",
        "V2X (its-g5, 50% equipped)", "perception",
    )  # fmt: skip
    replayed = replace(case_preset("replay"), decision=DecisionConfig(enabled=True))
    assert switches(replayed) == ("decisions (no effect: replayed rider)",)


def test_avoided_only_where_the_reference_collided():
    cases = [case_preset("normal"), case_preset("normal-cap")]
    summary = pd.DataFrame({"name": ["normal", "normal-cap"], "collision": [False, False],
                            "impact_speed_mps": [np.nan, np.nan]})  # fmt: skip
    out = add_verdicts(summary, cases)
    assert list(out["verdict"]) == ["reference", NOTHING_TO_AVOID]
    summary["collision"] = [True, False]
    summary["impact_speed_mps"] = [3.0, np.nan]
    assert list(add_verdicts(summary, cases)["verdict"]) == ["reference", "avoided"]
    from vei.cli.sim_table import _cell

    rec = {"name": "normal-cap", "reference": "normal", "verdict": NOTHING_TO_AVOID}
    assert _cell(rec, "verdict", None) == "nothing to avoid (normal did not collide)"
    assert _cell({**rec, "verdict": "avoided"}, "verdict", None) == "avoided vs normal"


@pytest.fixture(scope="module")
def occluded():
    """The V2X study's occluded crossing at a shift inside the occlusion window: the
    perception alone, perception + V2X (corrected GNSS) and ideal perception + V2X."""
    v2x = V2XConfig(enabled=True, position_error_std_m=PPP_GNSS_STD_M)
    ideal = replace(study_case(v2x, name="ideal + V2X"), perception=None)
    cases = [study_case(None, name="perception alone"),
             study_case(v2x, name="perception + V2X"), ideal]  # fmt: skip
    return run_casestudy(occluded_crossing(), cases=cases, time_shift=-4.05)


def test_the_summary_says_what_v2x_did(occluded):
    s = occluded.summary.set_index("name")
    alone, v2x, ideal = (s.loc[n] for n in ("perception alone", "perception + V2X", "ideal + V2X"))
    assert alone["switches"] == "perception" and math.isnan(alone["v2x_sent"])
    assert alone["v2x_note"] == ""
    assert v2x["switches"] == "V2X (its-g5, 100% equipped), perception"
    # the waiting rider's first VAM at t = 0 (a standing rider then every 5.1 s): the
    # car has its track one step later, long before its sensor sees the rider round the
    # van; it brakes on it, and does not collide where perception alone does
    assert v2x["v2x_sent"] >= 1 and v2x["v2x_delivered"] >= 1
    assert v2x["v2x_delivered"] <= v2x["v2x_sent"]
    assert v2x["v2x_first_track_s"] == pytest.approx(0.05)
    assert v2x["v2x_only_first_s"] == pytest.approx(0.05)
    assert v2x["v2x_acted_s"] > 0 and v2x["v2x_only_s"] > 1.0
    assert bool(alone["collision"]) and not bool(v2x["collision"])
    assert "the car braked on V2X alone at" in v2x["v2x_note"]
    assert v2x["verdict"] == ""  # no no-avoidance run in this study
    # ideal perception sees every rider: V2X told the car nothing new; after the rider
    # left the scene (y = 15 m) the car kept its V2X track (max_track_age_s), said apart
    assert math.isnan(ideal["v2x_only_first_s"]) and math.isnan(ideal["v2x_acted_s"])
    assert "V2X changed nothing: the sensor saw every rider V2X reported" in ideal["v2x_note"]
    assert 0 < ideal["v2x_stale_s"] <= 10.2 + 0.05
    assert "tracks of riders that had left kept" in ideal["v2x_note"]


def test_the_run_table_names_the_switches_and_v2x(occluded, tmp_path):
    from rich.console import Console

    from vei.cli.sim_table import print_summary

    buf = io.StringIO()
    print_summary(occluded, None, console=Console(file=buf, width=400, color_system=None))
    text = buf.getvalue()
    assert "switches" in text and "V2X (its-g5, 100% equipped), perception" in text
    assert "perception + V2X: V2X: " in text and "messages delivered" in text
    assert "ideal + V2X: V2X: " in text and "V2X changed nothing" in text


def test_the_criticality_banner_is_about_the_recorded_paths():
    from rich.console import Console

    from vei.cli.sim_table import print_summary
    from vei.sim.testing import crossing_scenario
    from vei.sim.timeshift import evaluate_time_shift, find_time_shift

    sc = crossing_scenario()
    late = evaluate_time_shift(sc, find_time_shift(sc).time_shift_s + 1.0)
    msg = late.message()
    assert msg.startswith("NOT CRITICAL (the recorded paths, not a run's outcome)")
    # a run that collides although the recorded paths do not meet: the table says so
    summary = pd.DataFrame({"name": ["normal"], "collision": [True], "switches": ["none"]})
    result = SimpleNamespace(
        time_shift_s=late.time_shift_s, time_shift={"mode": "given"},
        scenario=SimpleNamespace(id="x"), backend="builtin", summary=summary,
        criticality={"message": msg, "paths_meet": False},
        paper_outcome=lambda: {"reproduced": None}, cases=(),
    )  # fmt: skip
    buf = io.StringIO()
    print_summary(result, None, console=Console(file=buf, width=300, color_system=None))
    text = " ".join(buf.getvalue().split())
    assert "NOT CRITICAL (the recorded paths, not a run's outcome)" in text
    assert "the line above is about the recorded paths; in the simulation normal collided" in text


def _labels(ax) -> set[str]:
    return {line.get_label() for line in ax.get_lines()}


def test_birdseye_figures_draw_every_road_user_that_can_occlude(occluded):
    from vei.report.birdseye import plot_birdseye
    from vei.report.casestudy_birdseye import plot_birdseye_configs

    sc = occluded.scenario
    fig = plot_birdseye(sc)
    assert "van box" in _labels(fig.axes[0])
    dims = {a.agent_id: (a.length_m, a.width_m) for a in sc.agents}
    fig = plot_birdseye_configs(occluded.frame, other_id=sc.primary_threat, dims=dims)
    panels = [ax for ax in fig.axes if ax.get_title()]
    assert len(panels) == 3
    for ax in panels:
        assert "van box" in _labels(ax)
        box = next(line for line in ax.get_lines() if line.get_label() == "van box")
        xy = np.asarray(box.get_xydata())
        # the parked van: 5.9 x 2.1 m, front at x = 58.95, centre y = -2.5
        assert xy[:, 0].max() == pytest.approx(58.95, abs=1e-6)
        assert xy[:, 0].min() == pytest.approx(58.95 - 5.9, abs=1e-6)
        assert xy[:, 1].min() == pytest.approx(-3.55, abs=1e-6)
