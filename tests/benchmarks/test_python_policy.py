"""benchmarks.bench_python_policy: the per-call timing of a Python policy counts one
PolicyDriver call per engine step and leaves the engine's methods as they were."""

from __future__ import annotations

from benchmarks.bench_python_policy import ZeroPolicy, measure


def test_measure_counts_one_call_per_step():
    from vei.sim import observe
    from vei.sim.state import prepare_scenario
    from vei.sim.testing import crossing_scenario

    arrays = prepare_scenario(crossing_scenario(duration_s=3.0))
    before, own = observe.PolicyDriver.act, ZeroPolicy.act
    m = measure(arrays, ZeroPolicy(), b=8)
    assert observe.PolicyDriver.act is before and ZeroPolicy.act is own  # restored
    assert m["steps"] == arrays.n_steps - 1  # one call per step, the whole batch at once
    assert 0.0 <= m["policy"] <= m["driver"] <= m["step"]
    assert abs(m["overhead"] - (m["driver"] - m["policy"])) < 1e-12
