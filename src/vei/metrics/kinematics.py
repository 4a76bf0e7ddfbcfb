"""Ego kinematics metrics: peak deceleration and speed standard deviation."""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.metrics._trace import TraceArrays, arrays
from vei.metrics.config import MetricsConfig
from vei.types import Trace

FloatArray = npt.NDArray[np.float64]


def peak_deceleration(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] largest ego deceleration (m/s^2, >= 0; 0 if it never brakes), over the steps
    before any collision (the crash itself stops the car in one step and is not braking)."""
    a = arrays(trace)
    decel = np.where(a.collided, 0.0, -a.ego_accel)
    return np.maximum(decel.max(axis=1), 0.0)


def ego_speed_std(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] population standard deviation (ddof=0) of the ego speed over the whole run (m/s),
    the quantity of the paper's Fig. 6 (a crash's drop to zero included)."""
    return arrays(trace).ego_speed.std(axis=1)


def ego_speed_mean(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] mean ego speed over the whole run (m/s)."""
    return arrays(trace).ego_speed.mean(axis=1)


def ego_speed_min(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] lowest ego speed over the whole run (m/s)."""
    return arrays(trace).ego_speed.min(axis=1)
