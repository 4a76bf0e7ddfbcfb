import json

import numpy as np
import pandas as pd
import pytest

from vei.config import PAPER_CASES, SimConfig
from vei.errors import BackendError, ConfigError, InputError
from vei.experiments.casestudy import (
    get_backend,
    parse_time_shift,
    resolve_cases,
    run_casestudy,
    summary_document,
    write_casestudy,
)
from vei.experiments.demo_data import demo_interaction
from vei.metrics import summarize, trace_from_timeseries
from vei.recon.pipeline import reconstruct
from vei.types import TIMESERIES_COLUMNS


@pytest.fixture(scope="module")
def demo_scenario():
    return reconstruct(demo_interaction())


def _fake_runner(collide: dict[str, bool]):
    """A backend that drives the ego at 5 m/s towards a standing rider 30 m ahead, stopping
    it at contact for the configurations marked as colliding and 10 m short otherwise."""

    def run(scenario, cases, time_shift_s, sim):
        rider = scenario.primary_threat
        rows = []
        for v, case in enumerate(cases):
            x, speed = 0.0, 5.0
            for k in range(101):
                t = 0.1 * k
                stop_at = 30.0 - 2.35 - 0.6 if collide[case.name] else 17.0
                hit = collide[case.name] and x >= stop_at
                rows.append((case.name, v, t, "ego", "ego", x, 0.0, 0.0, speed, 0.0, True, hit, ""))
                rows.append(
                    (case.name, v, t, rider, "escooter", 30.0, 0.0, 0.0, 0.0, 0.0, True, hit, "")
                )
                if x + speed * 0.1 >= stop_at:
                    x, speed = stop_at, 0.0
                else:
                    x += speed * 0.1
        return pd.DataFrame(rows, columns=list(TIMESERIES_COLUMNS))

    return run


PAPER_LIKE = {
    "replay": True,
    "normal": True,
    "aggressive": True,
    "normal-cap": False,
    "aggressive-cap": False,
}


def test_casestudy_with_a_custom_backend_scores_and_writes(tmp_path, demo_scenario):
    res = run_casestudy(demo_scenario, time_shift=1.5, backend=_fake_runner(PAPER_LIKE))
    assert res.summary["name"].tolist() == list(PAPER_CASES)
    assert res.summary["collision"].tolist() == [True, True, True, False, False]
    assert res.summary["safety_index"].tolist()[:3] == [0.0, 0.0, 0.0]
    # no crash: the ego stops with a box gap of 30 - 17 - 2.35 - 0.6 = 10.05 m
    assert res.summary["min_gap_m"].iloc[3] == pytest.approx(10.05)
    assert res.paper_outcome()["reproduced"] is True
    # A given shift is evaluated too: its miss distance and whether the paths meet.
    assert res.time_shift["mode"] == "given" and res.time_shift_s == 1.5
    assert res.time_shift["time_shift_s"] == 1.5 and res.time_shift["miss_distance_m"] >= 0
    assert res.criticality["make_critical"] == "timing"
    assert res.criticality["paths_meet"] == res.time_shift["paths_meet"]
    paths = write_casestudy(res, tmp_path, figures=False)
    doc = json.loads(paths["summary_json"].read_text())
    assert doc["scenario_id"] == demo_scenario.id
    assert doc["time_shift_s"] == 1.5
    assert doc["primary_threat"] == demo_scenario.primary_threat
    assert [c["name"] for c in doc["configs"]] == list(PAPER_CASES)
    first = doc["configs"][0]
    for key in ("collision", "safety_index", "min_gap_m", "min_ttc_s", "ego_speed_std_mps"):
        assert key in first
    assert first["collision"] is True and first["rider"] == "replay" and first["ego_mode"] == "pid"
    assert doc["paper_outcome"]["reproduced"] is True
    csv = pd.read_csv(paths["summary_csv"])
    assert csv["min_gap_m"].iloc[3] == pytest.approx(10.05)
    ts = pd.read_parquet(paths["timeseries"])
    assert list(ts.columns) == [*TIMESERIES_COLUMNS, "continuation"] and len(ts) == 5 * 101 * 2
    # the fake rider stands at (30, 0) from t = 0 to 10 s, its recording spanning 0 - 20 s
    # shifted by 1.5 s: on its run-in until t = 1.5 s (issue 22), the ego never
    rider = ts[ts["agent_id"] == demo_scenario.primary_threat]
    np.testing.assert_array_equal(rider["continuation"], rider["t_s"] < 1.5 - 1e-9)
    assert not ts.loc[ts["agent_id"] == "ego", "continuation"].any()


def test_paper_outcome_flags_a_difference(demo_scenario):
    res = run_casestudy(
        demo_scenario, time_shift=0.0, backend=_fake_runner({**PAPER_LIKE, "normal": False})
    )
    out = res.paper_outcome()
    assert out["reproduced"] is False
    assert out["per_config"]["normal"]["ok"] is False
    assert out["per_config"]["replay"]["ok"] is True
    partial = run_casestudy(
        demo_scenario, cases=["replay"], time_shift=0.0, backend=_fake_runner(PAPER_LIKE)
    )
    assert partial.paper_outcome()["reproduced"] is None


def test_builtin_engine_batch_is_scored_like_the_engines_own_trace(demo_scenario):
    from vei.sim.engine import run_cases

    res = run_casestudy(demo_scenario, time_shift=5.0)
    assert res.backend == "builtin"
    direct = run_cases(demo_scenario, list(PAPER_CASES), time_shift_s=5.0, sim=SimConfig())
    own = summarize(direct.to_trace(), labels=list(PAPER_CASES))
    for col in (
        "collision",
        "collision_time_s",
        "safety_index",
        "min_gap_m",
        "min_ttc_s",
        "ego_speed_std_mps",
        "peak_decel_mps2",
        "pet_s",
    ):
        np.testing.assert_allclose(
            res.summary[col].to_numpy(dtype=float),
            own[col].to_numpy(dtype=float),
            rtol=1e-9,
            atol=1e-9,
            err_msg=col,
        )
    trace, runs = trace_from_timeseries(
        res.frame,
        other_id=demo_scenario.primary_threat,
        ego_dims_m=(4.7, 1.85),
        other_dims_m=(1.2, 0.6),
    )
    assert [r[0] for r in runs] == list(PAPER_CASES)
    assert np.array_equal(trace.collided, direct.collided)


def test_parse_time_shift_and_cases():
    assert parse_time_shift("auto") == "auto" and parse_time_shift(None) == "auto"
    assert parse_time_shift("-2.5") == -2.5 and parse_time_shift(3) == 3.0
    with pytest.raises(InputError, match="time-shift"):
        parse_time_shift("soon")
    with pytest.raises(InputError, match="finite"):
        parse_time_shift(float("nan"))
    assert [c.name for c in resolve_cases(None)] == list(PAPER_CASES)
    with pytest.raises(ConfigError, match="unique"):
        resolve_cases(["replay", "replay"])
    with pytest.raises(ConfigError, match="unknown configuration"):
        resolve_cases(["calm"])


def test_backend_errors(demo_scenario):
    with pytest.raises(ConfigError, match="unknown backend"):
        get_backend("gazebo")

    def bad(scenario, cases, shift, sim):
        return pd.DataFrame({"t_s": [0.0]})

    with pytest.raises(BackendError, match="without column"):
        run_casestudy(demo_scenario, time_shift=0.0, backend=bad)


def test_scenario_without_rider_is_an_input_error(demo_scenario):
    import dataclasses

    lonely = dataclasses.replace(demo_scenario, primary_threat=None)
    with pytest.raises(InputError, match="no primary threat"):
        run_casestudy(lonely, time_shift=0.0)


def test_summary_document_is_strict_json(demo_scenario):
    res = run_casestudy(demo_scenario, time_shift=0.0, backend=_fake_runner(PAPER_LIKE))
    text = json.dumps(summary_document(res), allow_nan=False)
    assert "NaN" not in text
