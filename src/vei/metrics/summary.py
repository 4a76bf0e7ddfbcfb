"""Summary of a trace: every scalar metric, one row per run."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.metrics._trace import TraceArrays, arrays
from vei.metrics.config import MetricsConfig
from vei.metrics.registry import SCALAR_METRICS, get_metric
from vei.types import Trace


def summarize(
    trace: Trace | TraceArrays,
    cfg: MetricsConfig | None = None,
    *,
    names: Sequence[str] | None = None,
    labels: Sequence[str] | None = None,
    params: Mapping[str, npt.ArrayLike] | None = None,
) -> pd.DataFrame:
    """Scalar metrics of B runs.

    Args:
        trace: B runs (Trace or its arrays).
        cfg: metric thresholds (paper defaults when None).
        names: scalar metrics to include (default: all, in SCALAR_METRICS order).
        labels: optional B run names, put in a first column 'name'.
        params: optional per-run settings (rider mass, the car's full brake; see
            :func:`vei.metrics._trace.arrays` and :func:`vei.metrics.run_params`).
    Returns:
        DataFrame with B rows; 'collision' is bool, the others float (NaN = undefined,
        inf = never, e.g. a TTC that never becomes finite).
    """
    a = arrays(trace, params)
    cfg = MetricsConfig() if cfg is None else cfg
    cols: dict[str, np.ndarray] = {}
    b = a.ego_speed.shape[0]
    if labels is not None:
        if len(labels) != b:
            raise ValueError(f"{len(labels)} labels for {b} runs")
        cols["name"] = np.asarray(list(labels), dtype=object)
    for name in names or SCALAR_METRICS:
        metric = get_metric(name)
        if metric.kind != "scalar":
            raise ValueError(f"metric {name!r} is a per-step series, not a summary value")
        cols[name] = metric.compute(a, cfg)
    return pd.DataFrame(cols)


def summary_records(frame: pd.DataFrame) -> list[dict]:
    """Rows of a summary as JSON-safe dicts (NaN and inf become None, numpy scalars Python)."""
    records = []
    for row in frame.to_dict(orient="records"):
        clean = {}
        for k, v in row.items():
            if isinstance(v, np.bool_ | bool):
                clean[k] = bool(v)
            elif isinstance(v, np.integer):
                clean[k] = int(v)
            elif isinstance(v, float | np.floating):
                clean[k] = float(v) if np.isfinite(v) else None
            else:
                clean[k] = v
        records.append(clean)
    return records
