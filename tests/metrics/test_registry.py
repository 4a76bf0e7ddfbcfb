import numpy as np
import pandas as pd
import pytest

from vei.errors import ConfigError, InputError
from vei.metrics import (
    METRICS,
    SCALAR_METRICS,
    get_metric,
    summarize,
    summary_records,
    trace_from_timeseries,
)
from vei.types import TIMESERIES_COLUMNS

from .helpers import make_trace


def _trace():
    return make_trace(
        ego_xy=[0.0, 0.0],
        other_xy=[12.5, 0.0],
        ego_speed=[5.0, 5.0, 5.0],
        ego_accel=[0.0, -1.0, 0.0],
    )


def test_every_metric_has_the_declared_shape():
    tr = _trace()
    for m in METRICS.values():
        out = m.compute(tr)
        assert out.shape == ((1,) if m.kind == "scalar" else (1, 3)), m.name


def test_get_metric_unknown_is_config_error():
    with pytest.raises(ConfigError, match="unknown metric"):
        get_metric("ttc2")


def test_summary_values_and_json_records():
    s = summarize(_trace(), labels=["a"])
    assert list(s.columns) == ["name", *SCALAR_METRICS]
    row = s.iloc[0]
    assert not row["collision"]
    assert row["min_gap_m"] == pytest.approx(10.0)
    assert row["min_ttc_s"] == pytest.approx(2.0)
    assert row["safety_index"] == pytest.approx(1.0)  # TTC 2.0 is attention
    assert row["peak_decel_mps2"] == pytest.approx(1.0)
    rec = summary_records(s)[0]
    assert rec["collision"] is False
    assert rec["collision_time_s"] is None  # NaN -> None
    assert rec["min_ttc_rel_s"] == pytest.approx(2.0)  # standing rider: equals the paper TTC
    fast = make_trace(ego_xy=[0.0, 0.0], other_xy=[12.5, 0.0], ego_speed=5.0, other_vel=(6.0, 0.0))
    assert summary_records(summarize(fast))[0]["min_ttc_rel_s"] is None  # inf -> None


def _frame():
    rows = []
    for cfg, shift in (("a", 0.0), ("b", 1.0)):
        for k in range(4):
            t = 0.5 * k
            rows.append(
                (
                    cfg,
                    0,
                    t,
                    "ego",
                    "ego",
                    5.0 * t,
                    0.0,
                    0.0,
                    5.0,
                    0.0,
                    True,
                    cfg == "b" and k >= 2,
                    "",
                )
            )
            if k >= 1:  # the rider appears at the second step
                rows.append(
                    (
                        cfg,
                        0,
                        t,
                        "s1",
                        "escooter",
                        20.0 + shift,
                        2.0,
                        np.pi / 2,
                        4.0,
                        0.0,
                        True,
                        cfg == "b" and k >= 2,
                        "",
                    )
                )
    return pd.DataFrame(rows, columns=list(TIMESERIES_COLUMNS))


def test_trace_from_timeseries_pivots_runs():
    trace, runs = trace_from_timeseries(
        _frame(), other_id="s1", ego_dims_m=(4.7, 1.85), other_dims_m=(1.2, 0.6)
    )
    assert runs == [("a", 0), ("b", 0)]
    assert np.asarray(trace.t_s).tolist() == [0.0, 0.5, 1.0, 1.5]
    assert trace.other_active.tolist() == [[False, True, True, True]] * 2
    assert trace.collided.tolist() == [[False] * 4, [False, False, True, True]]
    assert trace.ego_xy_m[1, 3].tolist() == [7.5, 0.0]
    assert trace.other_vel_mps[0, 1] == pytest.approx([0.0, 4.0])
    assert np.isnan(trace.other_xy_m[0, 0]).all()
    s = summarize(trace, labels=["a", "b"])
    assert s["collision"].tolist() == [False, True]
    assert s["safety_index"].tolist()[1] == 0.0


def test_trace_from_timeseries_errors():
    f = _frame()
    with pytest.raises(InputError, match="no rows of agent"):
        trace_from_timeseries(f, other_id="zz", ego_dims_m=(4.7, 1.85), other_dims_m=(1.2, 0.6))
    with pytest.raises(InputError, match="no ego row"):
        trace_from_timeseries(
            f.iloc[1:], other_id="s1", ego_dims_m=(4.7, 1.85), other_dims_m=(1.2, 0.6)
        )
