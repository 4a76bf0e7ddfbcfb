"""A sweep variant re-run with ``vei run --config <its yaml>`` gives bit-identical metrics.

The sweep scores the engine's trace, ``vei run`` a trace read back from the run's long
time series (speed and yaw of the rider, no velocity vector). Before the two were
reconciled (vei.metrics.timeseries.as_timeseries_trace) DRAC differed (e.g. 0.0967 vs
0.1294 m/s^2 on the demo, 299.42 vs 296.72 on real data).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest

from tests.experiments.rerun import assert_runs_equal_sweep
from vei.sweep.params import reach_sim, reach_speed_of
from vei.sweep.run import (
    DEFAULT_METRICS,
    EngineEvaluator,
    read_results,
    run_sweep,
    write_variant_configs,
)
from vei.sweep.spec import spec_from_dict


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory) -> Path:
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


@pytest.mark.parametrize(
    "controller",
    [
        {"ego.policy": {"choices": ["none", "paper-cap"]}},
        {"ego.policy": {"choices": ["none", "aeb"]}},
    ],
    ids=["cap", "aeb"],
)
@pytest.mark.slow
def test_vei_run_of_each_variant_equals_the_sweep_row(demo_scenario, tmp_path, controller):
    spec = spec_from_dict(
        {
            "design": "grid",
            "base": "normal",
            "parameters": {
                "time_shift_s": {"min": -1.0, "max": 1.0, "num": 3},
                "ego.cruise_speed_mps": {"min": 4.0, "max": 8.0, "num": 2},
                **controller,
            },
        }
    )
    res = run_sweep(demo_scenario, spec, tmp_path / "sweep", chunk_size=64, progress=False)
    assert (res.n_variants, res.n_run, res.n_skipped) == (12, 12, 0)
    df = read_results(tmp_path / "sweep")
    assert len(df) == 12
    # one severity map per policy, and the comparison with 'none'
    other = next(p for p in controller["ego.policy"]["choices"] if p != "none")
    assert (tmp_path / "sweep" / "severity_map_none.png").is_file()
    assert (tmp_path / "sweep" / f"severity_map_{other}.png").is_file()
    cmp = pd.read_csv(tmp_path / "sweep" / "policy_comparison.csv").set_index("ego.policy")
    assert cmp.loc[other, "variants"] == 6
    assert cmp.loc["none", "collisions"] == df.loc[df["ego.policy"] == "none", "collision"].sum()
    # the sweep's own engine settings: continuations reaching for its largest cruise speed
    auto = EngineEvaluator(sim=reach_sim(reach_speed_of(spec))).prepare(demo_scenario).auto_shift_s
    paths = write_variant_configs(tmp_path / "configs", df, spec, auto)
    assert df["collision"].any() and not df["collision"].all()  # both outcomes compared
    compared = assert_runs_equal_sweep(demo_scenario, paths, df, tmp_path / "runs")
    assert compared == 12 * len(DEFAULT_METRICS)
