"""Secondary collisions as metrics (vei.metrics.secondary): the engine's latches through a
Trace, the kernel's pass of a sweep, and a run's long time series agree on the rear-end
case of tests/sim/test_traffic.py; a trace without them scores nothing."""

from __future__ import annotations

import numpy as np
import pytest

from tests.sim.test_traffic import _case, _scene
from vei.config import SimConfig
from vei.metrics import summarize
from vei.metrics.secondary import SECONDARY_METRICS, secondary_from_timeseries
from vei.metrics.timeseries import as_timeseries_trace, trace_from_timeseries
from vei.sim.engine import simulate, simulate_metrics
from vei.sim.state import VariantParams, prepare_scenario


@pytest.fixture(scope="module")
def arrays():
    return prepare_scenario(_scene(), SimConfig(duration_s=10.0))


@pytest.fixture(scope="module")
def params(arrays):
    return VariantParams.concat(
        [VariantParams.from_case(_case(react), arrays, 1) for react in (True, False)]
    )


def test_engine_trace_metrics(arrays, params) -> None:
    r = simulate(arrays, params, kernel="numpy")
    s = summarize(as_timeseries_trace(r.to_trace()), names=SECONDARY_METRICS)
    assert s["secondary_collision"].tolist() == [True, True]
    assert s["secondary_collisions"].tolist() == [1.0, 1.0]
    assert s["secondary_first"].tolist() == ["car1 -> ego", "car1 -> ego"]
    assert s["rear_end_collision"].tolist() == [True, True]
    assert s["secondary_time_s"][0] == pytest.approx(2.95)
    assert s["secondary_impact_speed_mps"][0] == pytest.approx(3.2, abs=1e-6)
    assert s["secondary_impact_speed_mps"][1] > 9.0  # the replayed car at its 10 m/s


def test_the_kernels_pass_equals_the_summary(arrays, params) -> None:
    """simulate_metrics (the sweep's path; the compiled kernel where numba is installed)
    gives the same secondary columns as summarize on the recorded run."""
    ref = summarize(
        as_timeseries_trace(simulate(arrays, params, kernel="numpy").to_trace()),
        names=SECONDARY_METRICS,
    )
    got = simulate_metrics(arrays, params, names=("collision", *SECONDARY_METRICS))
    for name in SECONDARY_METRICS:
        a, b = got[name].to_numpy(), ref[name].to_numpy()
        if a.dtype.kind == "f":
            np.testing.assert_allclose(a, b, atol=1e-9, err_msg=name)
        else:
            assert a.tolist() == b.tolist(), name


def test_from_a_long_time_series(arrays, params) -> None:
    r = simulate(arrays, params, kernel="numpy")
    frame = r.to_frame()
    trace, runs = trace_from_timeseries(
        frame, other_id="r1", ego_dims_m=(4.7, 1.85), other_dims_m=(1.2, 0.6)
    )
    dims = {"ego": (4.7, 1.85), "car1": (4.7, 1.85), "r1": (1.2, 0.6)}
    sec = secondary_from_timeseries(frame, runs, dims, "r1")
    assert sec["count"].tolist() == [1.0, 1.0]
    assert sec["striker"].tolist() == ["car1", "car1"] and sec["struck"].tolist() == ["ego", "ego"]
    assert sec["rear_end"].tolist() == [True, True]
    np.testing.assert_allclose(sec["first_t_s"], r.final_state.sec_first_t_s, atol=1e-9)
    # the same convention as the engine's: the velocities of the step before the contact
    np.testing.assert_allclose(sec["max_speed_mps"], r.final_state.sec_max_speed_mps, atol=1e-9)
    # a trace without a summary (a backend reporting none): NaN / False / ''
    s = summarize(trace, names=SECONDARY_METRICS)
    assert not s["secondary_collision"].any() and s["secondary_collisions"].isna().all()
    assert (s["secondary_first"] == "").all()
