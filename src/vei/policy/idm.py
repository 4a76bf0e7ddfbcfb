"""``idm``: Treiber's Intelligent Driver Model following the nearest object in the path.

Treiber, M., Hennecke, A., Helbing, D. (2000): "Congested traffic states in empirical
observations and microscopic simulations", Phys. Rev. E 62, 1805-1824 (model equations
also at https://traffic-simulation.de/info/info_IDM.html)::

    a_IDM = a [1 - (v / v0)^delta - (s*(v, dv) / s)^2],
    s*(v, dv) = s0 + max(0, v T + v dv / (2 sqrt(a b))),

with v0 = the cruise speed v_d, s = the leader's ``path_gap_m`` (free distance along the
ego path), dv = v - v_leader the approaching rate, v_leader = v + rel_vx (the leader's
speed along the ego's heading). The leader is the valid object ahead in the path corridor
with the smallest gap (the rider whenever it is in the corridor); none = free road,
``a [1 - (v / v0)^delta]``. The engine clips the demand to the ego's actuator limits.

Defaults (Treiber & Kesting, "Traffic Flow Dynamics", city traffic): a = 1.0 m/s^2,
b = 1.5 m/s^2, T = 1.0 s, s0 = 2 m, delta = 4. With a leader at constant speed v_l the
steady state is v = v_l and gap s_e = s*(v_l, 0) / sqrt(1 - (v_l / v0)^delta).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.errors import ConfigError
from vei.policy.base import PolicyAction
from vei.policy.builtin import ConfiguredPolicy
from vei.policy.observation import Observation

FloatArray = npt.NDArray[np.float64]
#: Gaps are floored at this [m] (the IDM's interaction term diverges at s = 0).
MIN_GAP_M = 0.01


@dataclass(frozen=True)
class IDMConfig:
    """Parameters of the ``idm`` policy (sweepable as ``ego.policy_params.<name>``).

    ``max_accel_mps2`` is the IDM's own acceleration parameter a (its comfortable
    acceleration, 1.0 m/s^2), not the car's full-throttle ``ego.max_accel_mps2``
    (3.0 m/s^2), which still clips every demand.

    Attributes:
        max_accel_mps2: a, maximum acceleration [m/s^2] (> 0).
        comfort_decel_mps2: b, comfortable deceleration [m/s^2] (> 0).
        time_headway_s: T, desired time headway [s] (>= 0).
        min_gap_m: s0, jam distance [m] (>= 0).
        delta: acceleration exponent [-] (> 0; 4 in the original).
    """

    max_accel_mps2: float = 1.0
    comfort_decel_mps2: float = 1.5
    time_headway_s: float = 1.0
    min_gap_m: float = 2.0
    delta: float = 4.0

    def __post_init__(self) -> None:
        for name in (
            "max_accel_mps2",
            "comfort_decel_mps2",
            "time_headway_s",
            "min_gap_m",
            "delta",
        ):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ConfigError(f"idm.{name} must be a finite number, got {v!r}")
            positive = name in ("max_accel_mps2", "comfort_decel_mps2", "delta")
            if v < 0 or (positive and v == 0):
                raise ConfigError(f"idm.{name} must be {'> 0' if positive else '>= 0'}, got {v!r}")


#: IDMConfig field -> VariantParams field.
IDM_PARAM_FIELDS: dict[str, str] = {
    "max_accel_mps2": "idm_max_accel_mps2",
    "comfort_decel_mps2": "idm_comfort_decel_mps2",
    "time_headway_s": "idm_time_headway_s",
    "min_gap_m": "idm_min_gap_m",
    "delta": "idm_delta",
}


def idm_accel(
    v_mps: FloatArray,
    v0_mps: Any,
    gap_m: FloatArray,
    dv_mps: FloatArray,
    max_accel_mps2: Any,
    comfort_decel_mps2: Any,
    time_headway_s: Any,
    min_gap_m: Any,
    delta: Any,
) -> FloatArray:
    """IDM acceleration [m/s^2], [B] (pure); gap +inf = free road.

    Args:
        v_mps: [B] own speed. v0_mps: desired speed. gap_m: [B] gap to the leader (+inf:
            none). dv_mps: [B] approaching rate v - v_leader. The rest: IDMConfig, [B] or
            scalars.
    """
    a = np.asarray(max_accel_mps2, dtype=np.float64)
    free = 1.0 - np.power(v_mps / v0_mps, delta)
    s_star = min_gap_m + np.maximum(
        0.0, v_mps * time_headway_s + v_mps * dv_mps / (2.0 * np.sqrt(a * comfort_decel_mps2))
    )
    lead = np.isfinite(gap_m)
    s = np.maximum(np.where(lead, gap_m, 1.0), MIN_GAP_M)
    inter = np.where(lead, (s_star / s) ** 2, 0.0)
    return a * (free - inter)


class IDM(ConfiguredPolicy):
    """Intelligent Driver Model on the nearest object ahead in the path (module docstring).

    Args:
        config: IDMConfig, or its fields as keyword arguments.
    """

    name = "idm"
    CONFIG = IDMConfig
    PARAM_FIELDS = IDM_PARAM_FIELDS

    def init_state(self, batch_size: int) -> None:
        """Stateless."""
        return None

    def act(self, obs: Observation, state: None) -> tuple[PolicyAction, None]:
        """IDM acceleration behind the nearest in-path object (free road if none)."""
        gaps = np.where(obs.valid, obs.path_gap_m, np.inf)
        b = obs.batch_size
        if gaps.shape[1]:
            j = np.argmin(gaps, axis=1)
            rows = np.arange(b)
            gap = gaps[rows, j]
            v_lead = obs.ego_speed_mps + obs.rel_vx_mps[rows, j]
        else:
            gap = np.full(b, np.inf)
            v_lead = np.zeros(b)
        v = obs.ego_speed_mps
        dv = np.where(np.isfinite(gap), v - v_lead, 0.0)
        p = self.p
        acc = idm_accel(
            v, obs.cruise_speed_mps, gap, dv, p["max_accel_mps2"], p["comfort_decel_mps2"],
            p["time_headway_s"], p["min_gap_m"], p["delta"],
        )  # fmt: skip
        return PolicyAction(accel_mps2=acc), None


__all__ = ["IDM", "IDMConfig", "IDM_PARAM_FIELDS", "MIN_GAP_M", "idm_accel"]
