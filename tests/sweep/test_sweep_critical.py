"""The sweep's critical variants, and only those, re-run with the full recording
(vei.sweep.critical): the recording scores to the sweep's rows bit for bit, and
equals what ``vei run --config configs/<id>.yaml`` records."""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from typer.testing import CliRunner

from tests.experiments.rerun import same_value
from vei.cli.main import app
from vei.sweep.run import DEFAULT_METRICS, read_results, run_sweep
from vei.sweep.spec import spec_from_dict
from vei.types import TIMESERIES_COLUMNS

K = 3


def _spec():
    return spec_from_dict(
        {
            "design": "grid",
            "base": "normal",
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0, "num": 3},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0, "num": 3},
            },
        }
    )


@pytest.fixture(scope="module")
def swept(tmp_path_factory) -> tuple[Path, Path]:
    """(scenario folder, sweep output folder) of a 3 x 3 demo sweep with k_critical = 3."""
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    root = tmp_path_factory.mktemp("crit")
    scenario = root / "scenario"
    write_scenario(reconstruct(demo_interaction()), scenario)
    out = root / "out"
    run_sweep(scenario, _spec(), out, chunk_size=4, progress=False, k_critical=K)
    return scenario, out


def _scored(frame: pd.DataFrame, scenario: Path, config: Path) -> dict:
    """Metrics of one run's long time series ``frame`` scored as ``vei run`` scores them
    (trace_from_timeseries + summarize, the run config's rider mass and full brake)."""
    from vei.config import RunConfig, SimConfig, load_config
    from vei.io.scenario import read_scenario
    from vei.metrics import run_params, summarize
    from vei.metrics.timeseries import trace_from_timeseries

    scen = read_scenario(scenario)
    sim = SimConfig()
    ego, other = scen.agent("ego"), scen.agent(scen.primary_threat)
    trace, runs = trace_from_timeseries(
        frame,
        other_id=other.agent_id,
        ego_dims_m=(sim.ego_length_m or ego.length_m, sim.ego_width_m or ego.width_m),
        other_dims_m=(sim.rider_length_m or other.length_m, sim.rider_width_m or other.width_m),
    )
    assert len(runs) == 1
    # the secondary collisions, as vei run scores them (vei.experiments.casestudy)
    import dataclasses

    from vei.metrics.secondary import secondary_from_timeseries

    dims = {a.agent_id: (a.length_m, a.width_m) for a in scen.agents}
    dims.update({"ego": (sim.ego_length_m or ego.length_m, sim.ego_width_m or ego.width_m)})
    dims[other.agent_id] = (
        sim.rider_length_m or other.length_m,
        sim.rider_width_m or other.width_m,
    )
    sec = secondary_from_timeseries(frame, runs, dims, other.agent_id)
    run = load_config(config, RunConfig)
    case = run.case
    # where the contacts happened, as vei run labels them (on the continued scenario)
    from vei.continuation import with_continuations
    from vei.continuation.where import where_from_timeseries
    from vei.sim.timeshift import parse_time_shift

    shift = parse_time_shift(run.time_shift)
    assert isinstance(shift, float)  # written as a number of seconds
    where = where_from_timeseries(
        frame, runs, with_continuations(scen, run.sim.continuation), rider_id=other.agent_id,
        time_shift_s=shift, sfm_configs={runs[0][0]} if case.rider == "sfm" else set(),
        secondary=sec,
    )  # fmt: skip
    trace = dataclasses.replace(trace, secondary=sec, where=where)
    summary = summarize(trace, names=DEFAULT_METRICS, params=run_params([case]))
    return {name: summary[name].iloc[0] for name in DEFAULT_METRICS}


def test_only_the_critical_variants_are_recorded(swept):
    _, out = swept
    crit = pd.read_csv(out / "critical.csv")
    ts = pd.read_parquet(out / "critical" / "timeseries.parquet")
    assert len(crit) == K
    assert list(ts.columns) == ["scenario_id", *TIMESERIES_COLUMNS, "continuation"]
    assert (
        ts["continuation"].dtype == bool
        and not ts.loc[ts["agent_id"] == "ego", "continuation"].any()
    )
    assert list(dict.fromkeys(ts["config"])) == list(crit["variant_id"])
    assert len(read_results(out)) == 9  # ... out of 9 variants
    meta = json.loads((out / "critical" / "recorded.json").read_text())
    assert meta["metrics_equal_sweep"] and meta["mismatches"] == []
    assert meta["n_rows"] == len(ts)
    for vid in crit["variant_id"]:
        assert (out / "critical" / f"{vid}_birdseye.png").stat().st_size > 10_000


def test_recording_scores_to_the_sweep_rows(swept):
    scenario, out = swept
    crit = pd.read_csv(out / "critical.csv")
    results = read_results(out).set_index("variant_id")
    ts = pd.read_parquet(out / "critical" / "timeseries.parquet")
    compared = 0
    for vid in crit["variant_id"]:
        frame = ts[ts["config"] == vid].drop(columns="scenario_id")
        got = _scored(frame, scenario, out / "configs" / f"{vid}.yaml")
        for name in DEFAULT_METRICS:
            want = results.at[vid, name]
            assert same_value(want, got[name]), (vid, name, want, got[name])
            compared += 1
    assert compared == K * len(DEFAULT_METRICS)
    # the ranking put a collision first, and the recording shows it
    first = ts[ts["config"] == crit["variant_id"].iloc[0]]
    assert results.at[crit["variant_id"].iloc[0], "collision"]
    assert first["collided"].any()


def test_vei_run_of_a_critical_config_records_the_same_series(swept, tmp_path):
    scenario, out = swept
    crit = pd.read_csv(out / "critical.csv")
    ts = pd.read_parquet(out / "critical" / "timeseries.parquet")
    vid = crit["variant_id"].iloc[0]
    res = CliRunner().invoke(
        app,
        [
            "run",
            str(scenario),
            "--config",
            str(out / "configs" / f"{vid}.yaml"),
            "--out",
            str(tmp_path / "run"),
            "--no-figures",
        ],
    )
    assert res.exit_code == 0, res.output
    run = pd.read_parquet(tmp_path / "run" / "timeseries.parquet")
    mine = ts[ts["config"] == vid].reset_index(drop=True)
    assert len(run) == len(mine)
    for col in TIMESERIES_COLUMNS:
        if col in ("config", "variant"):
            continue
        a, b = run[col].to_numpy(), mine[col].to_numpy()
        if a.dtype.kind == "f":
            assert np.array_equal(a, b, equal_nan=True), col
        else:
            assert (a == b).all(), col


def test_resume_keeps_an_up_to_date_recording(swept):
    scenario, out = swept
    path = out / "critical" / "timeseries.parquet"
    before = path.stat().st_mtime_ns
    time.sleep(0.01)
    run_sweep(scenario, _spec(), out, progress=False, k_critical=K)
    assert path.stat().st_mtime_ns == before  # skipped: same critical ids, no new part
    # an older recording than the parts (e.g. left by an interrupted run) is redone
    old = time.time() - 3600
    os.utime(path, (old, old))
    run_sweep(scenario, _spec(), out, progress=False, k_critical=K)
    assert path.stat().st_mtime > old + 1


def test_no_recording_when_switched_off(swept, tmp_path):
    scenario, _ = swept
    run_sweep(
        scenario, _spec(), tmp_path / "o", progress=False, k_critical=K, record_critical=False
    )
    assert (tmp_path / "o" / "critical.csv").is_file()
    assert not (tmp_path / "o" / "critical").exists()


def test_samples_riders_and_policies_record_their_own_runs(swept, tmp_path):
    """Critical variants on different reconstruction samples, riders and policies: each is
    recorded on its own sample's arrays with its own parameters (the recording's metrics
    equal the sweep's rows, every metric by ==)."""
    scenario, _ = swept
    spec = spec_from_dict(
        {
            "design": "grid",
            "base": "normal-cap",
            "reconstruction": {"samples": 2},
            "rider": {"profile": "calibrated", "sample": 2},
            "parameters": {
                "time_shift_s": {"min": -2.0, "max": 2.0, "num": 2},
                "ego.policy": {"choices": ["paper-cap", "aeb"]},
            },
        }
    )
    out = tmp_path / "o"
    run_sweep(scenario, spec, out, progress=False, k_critical=6)
    crit = pd.read_csv(out / "critical.csv")
    assert crit["reconstruction_sample"].nunique() == 2  # both samples among the critical
    ts = pd.read_parquet(out / "critical" / "timeseries.parquet")
    assert list(dict.fromkeys(ts["config"])) == list(crit["variant_id"])
    meta = json.loads((out / "critical" / "recorded.json").read_text())
    assert meta["metrics_equal_sweep"], meta["mismatches"]
    # the recording depends on the sample: run on the mean trajectory instead, the
    # metrics of some critical variant differ from the sweep's
    from vei.sweep.critical import mismatches, record_variants
    from vei.sweep.evaluator import EngineEvaluator

    ev = EngineEvaluator(base=spec.base)
    prepared = ev.prepare(scenario)
    _, wrong = record_variants(ev, prepared, crit.drop(columns="reconstruction_sample"))
    assert mismatches(wrong, crit, ev.metrics)
