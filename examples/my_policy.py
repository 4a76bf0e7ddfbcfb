"""An example user policy for vei: brake at a constant deceleration when the time to
reach the nearest road user in the ego's path drops below a threshold.

Run it:  vei run --policy examples/my_policy.py:MyPolicy ...
or in a run config:  case: {ego: {policy: examples/my_policy.py:MyPolicy,
                                  policy_params: {ttc_brake_s: 2.0}}}

Two versions of the same rule: ``MyPolicy`` (vectorised numpy: all B variants at once,
runs at batch speed) and ``MyLoopPolicy`` (a plain per-variant loop: easier to write,
slower). A test checks that both give the same result.
"""

from __future__ import annotations

import numpy as np

from vei.policy.base import PerVariantPolicy, PolicyAction


class MyPolicy:
    """Brake at ``decel_mps2`` while gap / closing speed < ``ttc_brake_s`` or something is
    in the path closer than ``stop_gap_m`` (so it stays stopped behind a standing rider);
    else hold the cruise speed with a proportional speed controller (gain ``k_speed`` 1/s)."""

    def __init__(
        self,
        ttc_brake_s: float = 1.8,
        decel_mps2: float = 6.0,
        k_speed: float = 0.5,
        stop_gap_m: float = 5.0,
    ) -> None:
        self.ttc_brake_s = ttc_brake_s
        self.decel_mps2 = decel_mps2
        self.k_speed = k_speed
        self.stop_gap_m = stop_gap_m

    def init_state(self, batch_size: int) -> None:
        return None  # stateless

    def act(self, obs, state):
        closing = -obs.rel_vx_mps  # [B, N] m/s, > 0 when the object comes closer
        in_path = obs.valid & np.isfinite(obs.path_gap_m) & (closing > 0.1)
        ttc = np.where(in_path, obs.path_gap_m / np.where(in_path, closing, 1.0), np.inf)
        gap = np.where(obs.valid, obs.path_gap_m, np.inf).min(axis=1, initial=np.inf)  # [B] m
        brake = (ttc.min(axis=1, initial=np.inf) < self.ttc_brake_s) | (gap < self.stop_gap_m)
        cruise = self.k_speed * (obs.cruise_speed_mps - obs.ego_speed_mps)
        accel = np.where(brake, -self.decel_mps2, cruise)
        return PolicyAction(accel_mps2=accel, fsm_state=brake.astype(np.int8)), None


class MyLoopPolicy(PerVariantPolicy):
    """The same rule as MyPolicy, one variant at a time."""

    def __init__(
        self,
        ttc_brake_s: float = 1.8,
        decel_mps2: float = 6.0,
        k_speed: float = 0.5,
        stop_gap_m: float = 5.0,
    ) -> None:
        self.ttc_brake_s = ttc_brake_s
        self.decel_mps2 = decel_mps2
        self.k_speed = k_speed
        self.stop_gap_m = stop_gap_m

    def act_one(self, obs) -> float:
        ttc_min = np.inf
        gap_min = np.inf
        for j in range(len(obs.valid)):
            if not obs.valid[j]:
                continue
            gap_min = min(gap_min, obs.path_gap_m[j])
            closing = -obs.rel_vx_mps[j]
            if np.isfinite(obs.path_gap_m[j]) and closing > 0.1:
                ttc_min = min(ttc_min, obs.path_gap_m[j] / closing)
        if ttc_min < self.ttc_brake_s or gap_min < self.stop_gap_m:
            return -self.decel_mps2
        return self.k_speed * (obs.cruise_speed_mps - obs.ego_speed_mps)
