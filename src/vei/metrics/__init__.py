"""Safety metrics of runs: the paper's TTC zones and safety index, plus TTC with relative
velocity, minimum gap, PET, DRAC, peak deceleration, ego speed statistics and what a
collision costs (impact speed, delta-v, impact side, who hit whom, injury risk, verdict).
Definitions and bounds: docs/metrics.md.

Every metric scores a :class:`vei.types.Trace` (ego + one road user, B runs) and never
depends on a simulation backend. Use ``get_metric(name).compute(trace, cfg)`` or
``summarize(trace)``.
"""

from vei.metrics._trace import run_params, sensor_params
from vei.metrics.config import PAPER_METRICS, MetricsConfig
from vei.metrics.registry import METRICS, SCALAR_METRICS, SERIES_METRICS, Metric, get_metric
from vei.metrics.severity import VERDICTS, injury_risk_of_speed, verdict
from vei.metrics.summary import summarize, summary_records
from vei.metrics.timeseries import as_timeseries_trace, trace_from_timeseries
from vei.metrics.ttc import (
    ZONE_ALERT,
    ZONE_ATTENTION,
    ZONE_COLLISION,
    ZONE_INACTIVE,
    ZONE_NAMES,
    ZONE_SAFE,
    paper_ttc,
    relative_ttc,
    safety_index,
    ttc_zones,
)

__all__ = [
    "run_params",
    "sensor_params",
    "METRICS",
    "PAPER_METRICS",
    "SCALAR_METRICS",
    "SERIES_METRICS",
    "VERDICTS",
    "ZONE_ALERT",
    "ZONE_ATTENTION",
    "ZONE_COLLISION",
    "ZONE_INACTIVE",
    "ZONE_NAMES",
    "ZONE_SAFE",
    "Metric",
    "MetricsConfig",
    "as_timeseries_trace",
    "get_metric",
    "injury_risk_of_speed",
    "paper_ttc",
    "relative_ttc",
    "safety_index",
    "summarize",
    "summary_records",
    "trace_from_timeseries",
    "ttc_zones",
    "verdict",
]
