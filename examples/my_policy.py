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
        """The policy's own memory at t = 0 for ``batch_size`` variants (B).

        Return anything (e.g. a dict of [B] arrays: an FSM state, a filter's memory); the
        engine passes it to the first :meth:`act` and each later act the state the
        previous one returned. This policy remembers nothing: None.
        """
        return None  # stateless

    def act(self, obs, state):
        """One engine step for B variants at once: the demanded acceleration.

        Args:
            obs: a :class:`vei.policy.observation.Observation` (docs/policy.md), all
                numpy arrays over B variants and N road-user slots:
                ``ego_speed_mps`` [B] (m/s, >= 0), ``ego_accel_mps2`` [B] (m/s^2),
                ``ego_s_m`` [B] (m along the path), ``cruise_speed_mps`` [B] (the
                configured v_d), ``max_accel_mps2`` / ``max_decel_mps2`` [B] (the car's
                limits, both > 0), ``t_s`` [B] (s), ``dt_s`` (float, s); per road user
                [B, N]: ``valid`` (perceived now), ``rel_x_m`` / ``rel_y_m`` (centre in
                the ego frame, x forward, y left, m), ``rel_vx_mps`` / ``rel_vy_mps``
                (relative velocity in the ego frame: < 0 in x = coming closer),
                ``length_m`` / ``width_m``, ``age_s`` (age of the detection, s),
                ``category``, ``path_gap_m`` (free distance from the ego's front along
                its path to the object, m; +inf when not ahead in the path corridor)
                and ``path_lateral_m``. Slots with ``valid`` False hold no information.
            state: what :meth:`init_state` or the previous call returned.
        Returns:
            ``(PolicyAction, new_state)``: ``PolicyAction(accel_mps2=[B] m/s^2)``
            (positive = speed up; the engine clips it to [-max_decel, max_accel]) or
            ``PolicyAction(command=[B] in [-1, 1])`` (throttle / brake), optionally
            ``fsm_state=[B] int8`` (recorded for the figures); and the new state.
        """
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
        """One variant at one step: its demanded acceleration [m/s^2] (a float).

        Args:
            obs: the variant's observation (``Observation.variant(i)``): the same names
                as in :meth:`MyPolicy.act`, the ego quantities as floats
                (``obs.ego_speed_mps``, ``obs.cruise_speed_mps`` in m/s, ...) and the road
                users as [N] arrays (``obs.valid[j]``, ``obs.path_gap_m[j]`` in m,
                ``obs.rel_vx_mps[j]`` in m/s, ...).
        Returns:
            The acceleration [m/s^2] (negative = brake; clipped by the engine to the
            car's limits). A stateful policy (``stateful = True``) takes a second
            argument, its memory (from ``init_one``), and returns ``(accel, memory)``.
        """
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
