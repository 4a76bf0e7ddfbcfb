"""Is the ego's motion drivable? Worst yaw step, yaw rate and lateral acceleration of a run.

From the ego's pose and speed series only (any backend): between steps k and k + 1,
``dpsi_k = wrap(psi_{k+1} - psi_k)``, yaw rate ``r_k = dpsi_k / dt``, lateral acceleration
``a_lat_k = r_k * (v_k + v_{k+1}) / 2`` (a vehicle on a path of curvature kappa at speed v
has r = kappa v and a_lat = kappa v^2). A yaw step of a large fraction of a radian in one
step (a kink in the path) shows here as a yaw rate of tens of rad/s.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.metrics._trace import TraceArrays, arrays
from vei.metrics.config import MetricsConfig
from vei.types import Trace

FloatArray = npt.NDArray[np.float64]


def _yaw_steps(a: TraceArrays) -> FloatArray:
    """[B, T-1] wrapped yaw change between consecutive steps [rad]."""
    yaw = np.atleast_2d(a.ego_yaw)
    d = np.diff(yaw, axis=1)
    return (d + np.pi) % (2.0 * np.pi) - np.pi


def max_yaw_step(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] largest |yaw change| of the ego between two consecutive steps [rad] (0 if T < 2)."""
    d = _yaw_steps(arrays(trace))
    return np.abs(d).max(axis=1) if d.shape[1] else np.zeros(d.shape[0])


def max_yaw_rate(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] largest |yaw rate| of the ego [rad/s] (yaw step / dt)."""
    a = arrays(trace)
    d = _yaw_steps(a)
    if not d.shape[1]:
        return np.zeros(d.shape[0])
    return np.abs(d).max(axis=1) / a.dt_s


def max_lateral_accel(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] largest |lateral acceleration| of the ego, yaw rate x mean speed of the step [m/s^2]."""
    a = arrays(trace)
    d = _yaw_steps(a)
    if not d.shape[1]:
        return np.zeros(d.shape[0])
    v = a.ego_speed
    v_mid = 0.5 * (v[:, 1:] + v[:, :-1])
    return np.abs(d / a.dt_s * v_mid).max(axis=1)
