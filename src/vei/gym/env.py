"""The single Gymnasium environment: one car, the agent, among vei's road users.

Each step runs the built-in engine's own NumPy step (:func:`vei.sim.step.step`) with the
agent's demand in the ego's seat (ego_mode 'policy', vei.policy's API): the same model,
the same numbers as ``vei run`` of the same scenario, configuration, time shift and
actions (a test replays an episode's actions with :class:`vei.policy.replay.ActionReplay`
and finds the states bit for bit). The observation is built from the policy API's
:class:`vei.policy.observation.Observation` (with the configuration's perception delay and
sensor model, if any) by :func:`vei.gym.features.vectorize`.

Spaces:
    action_space: Box([-max_decel], [max_accel], (1,), float32): the demanded longitudinal
        acceleration [m/s^2] of the configuration's actuator (default [-8, 3]); the engine
        applies it through the actuator lag (``ego.actuator_lag_s``) and ``v' = max(0, v +
        a dt)`` along the ego's recorded path. An action outside the Box (or NaN) is an
        InputError.
    observation_space: Box float32 of :mod:`vei.gym.features` (``env.unwrapped.feature_names``).
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt

from vei.errors import InputError
from vei.gym.config import EnvConfig
from vei.gym.features import feature_names, observation_bounds, vectorize
from vei.gym.world import AgentSeat, World, load_world


def check_actions(actions: Any, low: float, high: float, n: int) -> npt.NDArray[np.float64]:
    """The demands as float64 [n]; InputError naming the first action outside [low, high]."""
    a = np.asarray(actions, dtype=np.float64)
    if a.size != n:
        raise InputError(
            f"expected {n} action(s) of shape (1,) each, got an array of shape {a.shape}"
        )
    a = a.reshape(n)
    bad = ~((a >= np.float64(np.float32(low))) & (a <= np.float64(np.float32(high))))
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"action {float(a[i])!r} (environment {i}) is outside the action space: the demanded "
            f"acceleration must lie in [{low:g}, {high:g}] m/s^2",
            field="action",
        )
    return a


def action_limits(world: World) -> tuple[float, float]:
    """(-max_decel, max_accel) [m/s^2] of the configuration (the same in every scenario)."""
    p = world.scenarios[0].params
    return -float(p.max_decel_mps2_ego[0]), float(p.max_accel_mps2_ego[0])


def injury_risk(impact_mps: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """The rider's injury probability of impact speeds [m/s] (NaN -> 0)."""
    from vei.metrics.severity import injury_risk_of_speed

    v = np.asarray(impact_mps, dtype=np.float64)
    return np.where(np.isfinite(v), injury_risk_of_speed(np.nan_to_num(v)), 0.0)


class VeiEnv(gym.Env):
    """One car (the agent) among vei's road users; see the module docstring.

    Args:
        config: an EnvConfig or a mapping of its fields (default: the demo).
        render_mode: None or 'rgb_array' (a bird's-eye picture with the road network).
        **settings: EnvConfig fields (``gymnasium.make("vei/Crossing-v0", source="folder",
            path="scen")``); not together with ``config``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 20}

    def __init__(self, config: Any = None, render_mode: str | None = None, **settings: Any):
        if settings:
            if config is not None:
                raise InputError("give either config or its fields as keywords, not both")
            config = settings
        self.config = EnvConfig.from_mapping(config)
        if render_mode not in (None, "rgb_array"):
            raise InputError(f"render_mode must be None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.seat = AgentSeat()
        self.world = load_world(self.config, self.seat)
        low, high = action_limits(self.world)
        self.action_low, self.action_high = low, high
        self.action_space = gym.spaces.Box(np.float32(low), np.float32(high), (1,), np.float32)
        road = self.config.road_features
        lo, hi = observation_bounds(self.config.max_objects, road, self.config.gap_cap_m)
        self.observation_space = gym.spaces.Box(lo, hi, dtype=np.float32)
        self.feature_names = feature_names(self.config.max_objects, road)
        self.state: Any = None
        self.scenario_index = -1
        self.time_shift_s = float("nan")
        self._driver: Any = None

    # ------------------------------------------------------------------ engine plumbing
    def _observe(self) -> npt.NDArray[np.float32]:
        self._driver.act(self.state)  # builds the Observation (delay, perception) for the seat
        obs = self.seat.last_observation
        ws = self.world.scenarios[self.scenario_index]
        st = self.state
        t_left = (ws.arrays.n_steps - 1 - st.k) * ws.arrays.dt_s
        on = None
        if ws.road is not None:
            on = ws.road.lookup(st.rider_x_m, st.rider_y_m) * obs.valid[:, 0]
        vec = vectorize(
            obs, max_objects=self.config.max_objects, cap_m=self.config.gap_cap_m,
            time_remaining_s=np.array([t_left]), rider_on_road=on,
        )  # fmt: skip
        return vec[0]

    def _info(self) -> dict[str, Any]:
        ws = self.world.scenarios[self.scenario_index]
        return {
            "scenario": ws.name,
            "scenario_index": self.scenario_index,
            "time_shift_s": self.time_shift_s,
            "step": int(self.state.k),
            "t_s": float(self.state.k * ws.arrays.dt_s),
        }

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        """Start an episode: a scenario drawn uniformly, its automatic time shift plus a
        uniform draw in [-spread, spread] (``options={'time_shift_s': x}`` fixes the shift,
        ``options={'scenario_index': i}`` the scenario)."""
        from vei.sim.batch import batch_flags
        from vei.sim.observe import PolicyDriver
        from vei.sim.step import initial_state

        super().reset(seed=seed)
        options = dict(options or {})
        unknown = set(options) - {"time_shift_s", "scenario_index"}
        if unknown:
            raise InputError(
                f"unknown reset option(s) {sorted(unknown)}; known: scenario_index, time_shift_s"
            )
        rng = self.np_random
        i = int(rng.integers(self.world.n))
        j = rng.uniform(-1.0, 1.0)
        if "scenario_index" in options:
            i = int(options["scenario_index"])
            if not 0 <= i < self.world.n:
                raise InputError(f"scenario_index {i} outside [0, {self.world.n - 1}]")
        ws = self.world.scenarios[i]
        shift = ws.base_shift_s + self.config.time_shift_spread_s * j
        if "time_shift_s" in options:
            shift = float(options["time_shift_s"])
        self.scenario_index, self.time_shift_s = i, float(shift)
        self._params = ws.params.with_values(time_shift_s=shift)
        self._flags = batch_flags(self._params, ws.arrays.dt_s)
        self._driver = PolicyDriver(ws.arrays, self._params, self._flags)
        self.state = initial_state(ws.arrays, self._params, self._flags)
        self._steps = 0
        return self._observe(), self._info()

    def step(
        self, action: Any
    ) -> tuple[npt.NDArray[np.float32], float, bool, bool, dict[str, Any]]:
        """Apply the demanded acceleration for one engine step (see the module docstring)."""
        from vei.sim.observe import Demand
        from vei.sim.step import step

        if self.state is None:
            raise InputError("call reset() before step()")
        a = check_actions(action, self.action_low, self.action_high, 1)
        ws = self.world.scenarios[self.scenario_index]
        st = self.state
        demand = Demand(a, np.full(1, np.nan), np.zeros(1, dtype=np.int8))
        new = step(st, self._params, ws.arrays, self._flags, demand)
        contact = bool(new.collided[0] and not st.collided[0])
        hits = int(np.count_nonzero(new.hit_other[0] & ~st.hit_other[0]))
        hits += int(np.count_nonzero(new.extra_hit[0] & ~st.extra_hit[0]))  # extra riders
        impact = np.nan
        if contact and st.rider_active[0]:
            v, yaw = st.ego_v_mps[0], st.ego_yaw_rad[0]
            impact = float(
                np.hypot(v * np.cos(yaw) - st.rider_vx_mps[0], v * np.sin(yaw) - st.rider_vy_mps[0])
            )
        terms = {
            "collision": float(contact) + hits,
            "injury_risk": float(injury_risk(impact)),
            "progress": float(
                np.minimum(
                    new.ego_s_m - st.ego_s_m, self._params.cruise_speed_mps * ws.arrays.dt_s
                )[0]
            ),
            "comfort": float(new.ego_a_mps2[0] ** 2 * ws.arrays.dt_s),
        }
        w = self.config.reward
        reward = sum(getattr(w, name) * val for name, val in terms.items())
        self.state = new
        self._steps += 1
        terminated = contact or hits > 0
        limit = self.config.max_episode_steps
        truncated = new.k >= ws.arrays.n_steps - 1 or (limit is not None and self._steps >= limit)
        info = self._info()
        info["reward_terms"] = terms
        return self._observe(), float(reward), terminated, bool(truncated), info

    def render(self) -> npt.NDArray[np.uint8] | None:
        """rgb_array: the scene from above (road network, ego box, road users) at this step."""
        if self.render_mode is None or self.state is None:
            return None
        from vei.gym.render import render_state

        ws = self.world.scenarios[self.scenario_index]
        return render_state(ws, self.state, 0)


__all__ = ["VeiEnv", "action_limits", "check_actions", "injury_risk"]
