"""A sweep spec's ``variation:`` section (issue 23): parameters drawn from distributions
(vei.config.distributions) instead of uniformly; a random design is a Monte Carlo sample
of them, and every variant still re-runs alone with ``vei run``."""

from __future__ import annotations

import numpy as np
import pytest
from scipy import stats

from tests.experiments.rerun import assert_runs_equal_sweep
from vei.errors import ConfigError
from vei.sweep.spec import spec_from_dict, variants_table

SPEC = {
    "design": "lhs",
    "n_samples": 4000,
    "seed": 5,
    "base": "normal-cap",
    "parameters": {"time_shift_s": {"min": -1.0, "max": 1.0}},
    "variation": {
        "ego.cruise_speed_mps": {"dist": "normal", "mean": 6.0, "std": 1.0, "min": 2.0},
        "cap.t_safe_s": {"dist": "lognormal", "median": 2.0, "sigma_log": 0.2, "max": 5.0},
    },
}


def test_variation_draws_follow_their_distributions():
    spec = spec_from_dict(SPEC)
    assert spec.names == ("time_shift_s", "ego.cruise_speed_mps", "cap.t_safe_s")
    table = variants_table(spec, "s")
    v = table["ego.cruise_speed_mps"].to_numpy()
    ref = stats.truncnorm((2.0 - 6.0) / 1.0, np.inf, loc=6.0, scale=1.0)
    assert stats.kstest(v, ref.cdf).pvalue > 0.01 and v.min() >= 2.0
    t = table["cap.t_safe_s"].to_numpy()
    assert t.max() <= 5.0 and np.median(t) == pytest.approx(2.0, rel=0.02)
    assert spec_from_dict(spec.to_dict()).digest() == spec.digest()
    assert "variation" in spec.to_dict()


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"design": "grid", "n_samples": None,
          "parameters": {"time_shift_s": {"min": -1.0, "max": 1.0, "num": 3}}}, "random or lhs"),
        ({"variation": {"time_shift_s": {"dist": "uniform", "min": 0, "max": 1}}}, "in parameters too"),
        ({"variation": {"cap.a_min_mps2": {"dist": "normal", "mean": -6, "std": 1}}}, "give the distribution"),
        ({"variation": {"ego.policy": {"dist": "uniform", "min": 0, "max": 1}}}, "float parameter"),
        ({"variation": {"cap.t_safe_s": {"dist": "normal", "mean": 2, "std": 0}}}, "std must be > 0"),
    ],
)  # fmt: skip
def test_bad_variation_sections_are_refused(change, message):
    raw = {**SPEC, **change}
    raw = {k: v for k, v in raw.items() if v is not None}
    with pytest.raises(ConfigError, match=message):
        spec_from_dict(raw, source="sweep.yaml")


def test_variation_sweep_reruns_with_vei_run(tmp_path):
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct
    from vei.sweep.run import read_results, run_sweep

    scen = tmp_path / "scenario"
    write_scenario(reconstruct(demo_interaction()), scen)
    spec = spec_from_dict({**SPEC, "n_samples": 12})
    run_sweep(scen, spec, tmp_path / "out", progress=False, k_critical=3, record_critical=False)
    res = read_results(tmp_path / "out")
    assert {"ego.cruise_speed_mps", "cap.t_safe_s"} <= set(res.columns)
    configs = sorted((tmp_path / "out" / "configs").glob("*.yaml"))
    assert len(configs) == 3
    assert assert_runs_equal_sweep(scen, configs, res, tmp_path / "rerun") > 0
    assert (tmp_path / "out" / "probability_map.png").is_file()


def test_a_drawn_cruise_speed_sets_the_continuations_reach():
    """Issue 22: the run-ins reach beyond the car at the 99.9 % quantile of a drawn
    cruise speed (truncated normal 6 +- 1 m/s cut at 2 m/s: 6 + 3.0902 m/s by hand), the
    same in the sweep and in each variant's run configuration."""
    from vei.sweep.params import reach_speed_of, variant_config

    spec = spec_from_dict(SPEC)
    assert reach_speed_of(spec) == pytest.approx(6.0 + 3.0902, abs=1e-3)
    cfg = variant_config({"time_shift_s": 0.0, "ego.cruise_speed_mps": 5.0}, spec,
                         auto_shift_s=1.0)  # fmt: skip
    assert cfg.sim.continuation.ego_speed_mps == pytest.approx(6.0 + 3.0902, abs=1e-3)
