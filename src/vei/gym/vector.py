"""The batched Gymnasium vector environment: B environments stepped by one call.

``gymnasium.make_vec("vei/Crossing-v0", num_envs=B)`` gives a :class:`VeiVectorEnv`: the
engine's state of B environments as arrays ``[B]`` (each at its own step: autoreset puts
them out of step), one compiled call per step (:mod:`vei.gym.kernel`, backend 'numba') or
the engine's NumPy step per group of environments at the same step and scenario (backend
'numpy', the reference). Spaces, reward and termination are the single env's
(:class:`vei.gym.env.VeiEnv`); environment i after ``reset(seed=s)`` draws its episodes
like a single env reset with seed s + i, and so equals it step for step.

Autoreset (``metadata['autoreset_mode']`` = Gymnasium's NEXT_STEP): the step after an
environment's episode ended (terminated or truncated) resets it, ignores its action and
returns its first observation with reward 0 and both flags False.

The vector env models the primary rider (replayed or social-force, with obstacle braking
and its yield / go decision), the extra social-force riders (``sim.sfm_riders``) and
replays every other road user or drives the reacting cars (``traffic.cars_react``,
:mod:`vei.gym.cars`), observing them (the cars where the engine put them) with the
configuration's perception delay. A configuration with a sensor model, walking
pedestrians or V2X runs in the single env (or ``gymnasium.make_vec(...,
vectorization_mode='sync')``); the vector env refuses it, naming the feature and that way
out (:func:`unsupported_features`).
"""

from __future__ import annotations

import sys
from typing import Any

import gymnasium as gym
import numpy as np
import numpy.typing as npt
from gymnasium.vector import AutoresetMode
from gymnasium.vector.utils import batch_space

from vei.errors import ConfigError, InputError
from vei.gym.cars import CAR_STATE_ORDER, CarTables, car_state_arrays, reacting_cars
from vei.gym.config import EnvConfig
from vei.gym.env import action_limits, check_actions, injury_risk
from vei.gym.features import feature_names, observation_bounds, vectorize
from vei.gym.kernel import F_RVX, F_RVY, F_RX, F_RY, F_RYAW, N_BS, N_FS, N_PREV
from vei.gym.packed import Packed
from vei.gym.world import AgentSeat, World, load_world
from vei.sim.riders import EXTRA_BOOL_FIELDS, EXTRA_FLOAT_FIELDS
from vei.sim.state import SimState

#: SimState fields of the packed float rows (vei.gym.kernel F_* order) and bool rows.
_FLOAT_STATE = (
    "ego_s_m", "ego_x_m", "ego_y_m", "ego_yaw_rad", "ego_v_mps", "ego_a_mps2", "ego_act_mps2",
    "rider_x_m", "rider_y_m", "rider_yaw_rad", "rider_vx_mps", "rider_vy_mps",
    "rider_speed_mps", "rider_a_mps2", "rider_prog_m",
)  # fmt: skip
_BOOL_STATE = ("rider_active", "rider_started", "rider_done", "collided", "rider_decision")
assert len(_FLOAT_STATE) == N_FS and len(_BOOL_STATE) == N_BS


#: The way out named by every refusal of a feature the vector env does not model.
_WAY_OUT = (
    "run single environments side by side instead: gymnasium.make_vec(..., "
    "vectorization_mode='sync'), which runs the engine's own step with every feature "
    "(docs/gym.md)"
)


def unsupported_features(world: World) -> list[str]:
    """The configuration's features the vector env does not model, named with the setting
    that turns them on (empty: it models them all). The vector env models: the agent's
    actuator, a replayed or social-force primary rider with its ego repulsion, obstacle
    braking (sfm.obstacle_braking) and yield / go decision (decision.enabled), the extra
    social-force riders (sim.sfm_riders), replayed other road users, the perception delay
    (cap.perception_delay_s), reacting cars (traffic.cars_react, vei.gym.cars); not the
    features listed here."""
    p = world.scenarios[0].params
    out = []
    if p.perception[0] is not None:
        out.append("a sensor model (case.perception)")
    if bool(p.peds_sfm[0]):
        out.append("walking pedestrians (traffic.pedestrians)")
    if p.v2x[0] is not None:
        out.append("V2X (case.v2x)")
    return out


def refuse_features(features: list[str]) -> None:
    """ConfigError naming every feature in ``features`` and the way out (none: return)."""
    if features:
        raise ConfigError(f"the vector env does not model {'; '.join(features)}: {_WAY_OUT}")


def kernel_notice() -> Any:
    """A context for the first calls of vei.gym.kernel: flushes its on-disk machine code
    when a module compiled into it changed (numba checks only the kernel's own file:
    vei.sim.kernel.cache.drop_stale), and announces the compilation (vei.io.progress) when
    there is no machine code for the current sources (tens of seconds to minutes)."""
    import contextlib

    from vei.gym import cars_kernel as ck
    from vei.gym import kernel as gk
    from vei.gym import riders_kernel as rk
    from vei.io.progress import activity
    from vei.sim.kernel.cache import cache_dir, drop_stale, sources_digest

    fns = (gk.step_envs, gk.observe_envs)
    if all(f.signatures for f in fns) and rk.step_riders.signatures and ck.step_cars.signatures:
        return contextlib.nullcontext()
    folder = cache_dir(gk.step_envs)
    stamp = None if folder is None else folder / "loop.sources.sha256"
    fresh = stamp is not None and stamp.is_file() and stamp.read_text().strip() == sources_digest()
    drop_stale(*fns, gk.sat, rk.step_riders, ck.step_cars)  # one folder: vei/gym/__pycache__
    if fresh and folder is not None:
        index = [folder / f"kernel.{f.__name__}-{f.py_func.__code__.co_firstlineno}.py"
                 f"{sys.version_info[0]}{sys.version_info[1]}.nbi" for f in fns]  # fmt: skip
        if all(p.is_file() for p in index):  # numba's index of this source's functions
            return contextlib.nullcontext()
    return activity(
        "compiling vei.gym's vector-env kernel for this machine (once per installation "
        "and update, about 30-120 s; later runs load it in about a second)"
    )


class VeiVectorEnv(gym.vector.VectorEnv):
    """B environments of :class:`vei.gym.env.VeiEnv` in one batched state (module docstring).

    Args:
        num_envs: B (>= 1).
        config: an EnvConfig or a mapping of its fields; or its fields as keywords.
    """

    metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(self, num_envs: int = 1, config: Any = None, **settings: Any) -> None:
        if settings:
            if config is not None:
                raise InputError("give either config or its fields as keywords, not both")
            config = settings
        if isinstance(num_envs, bool) or not isinstance(num_envs, int) or num_envs < 1:
            raise ConfigError(f"num_envs must be an integer >= 1, got {num_envs!r}")
        self.config = EnvConfig.from_mapping(config)
        self.seat = AgentSeat()
        self.world = load_world(self.config, self.seat)
        refuse_features(unsupported_features(self.world))
        from vei.sim import kernel as compiled

        backend = self.config.backend
        self._cars = reacting_cars(self.world)
        self.backend = (
            "numba"
            if backend == "numba" or (backend == "auto" and compiled.available())
            else "numpy"
        )
        self.num_envs = num_envs
        low, high = action_limits(self.world)
        self.action_low, self.action_high = low, high
        self.single_action_space = gym.spaces.Box(
            np.float32(low), np.float32(high), (1,), np.float32
        )
        road = self.config.road_features
        lo, hi = observation_bounds(self.config.max_objects, road, self.config.gap_cap_m)
        self.single_observation_space = gym.spaces.Box(lo, hi, dtype=np.float32)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.feature_names = feature_names(self.config.max_objects, road)
        self.pk = Packed(self.world)
        b, no = num_envs, max(1, self.world.max_others)
        self.FS = np.zeros((N_FS, b))
        self.BS = np.zeros((N_BS, b), np.uint8)
        self.HIT = np.zeros((b, no), np.uint8)
        self.K = np.zeros(b, np.int64)
        self.SC = np.zeros(b, np.int64)
        self.SHIFT = np.zeros(b)
        self.steps = np.zeros(b, np.int64)
        self.TERMS = np.zeros((b, 4))
        self.OBS = np.zeros((b, lo.shape[0]), np.float32)
        # the perception delay (vei.sim.observe.PolicyDriver's ring of the rider's truth)
        self.delay = int(self.world.scenarios[0].params.delay_steps(self.pk.dt)[0])
        self.RING = np.zeros((self.delay + 1, 6, b))
        self.RD = np.zeros((6, b))
        # the extra riders (vei.sim.riders' fields; R_max columns, a scenario uses its own R)
        r = 0 if self.pk.xr is None else self.pk.xr.r_max
        self.XS = np.zeros((b, len(EXTRA_FLOAT_FIELDS), r))
        self.XB = np.zeros((b, len(EXTRA_BOOL_FIELDS), r), np.bool_)
        self.XRING = np.zeros((self.delay + 1, b, 6, r))
        self.XD = np.zeros((b, 6, r))
        xr = self.pk.xr
        self._xr: tuple[Any, ...] | None = None  # the kernel's extra-rider groups (or None)
        self._xo: tuple[Any, ...] | None = None
        if xr is not None:
            nf = len(EXTRA_FLOAT_FIELDS)
            scratch = (np.zeros((nf, r)), np.zeros((len(EXTRA_BOOL_FIELDS), r), np.bool_))
            self._xr = (*xr.group(), self.XS, self.XB, *scratch)
            self._xo = (self.XD, xr.xL, xr.xW, xr.XCAT, xr.n)
        # the reacting cars' and contact latches' SimState fields per environment (padded
        # columns past a scenario's own cars / others: never read); empty without them
        self.CARS: dict[str, np.ndarray] = car_state_arrays(self.world, b) if self._cars else {}
        self.PREV = np.zeros((N_PREV, b))  # the step-k state the post-passes read
        self._oact = self.pk.OACT  # the others' presence for step_envs' ego contact test
        self._co: tuple[Any, ...] | None = None  # the cars as perceived (observe_envs)
        if self._cars:
            self._car_tables(b)
        self._needs_reset = np.ones(b, dtype=bool)
        self._rngs: list[np.random.Generator] = []
        self.weights = np.array(
            [self.config.reward.collision, self.config.reward.progress, self.config.reward.comfort]
        )
        if self.backend == "numba":  # load (or compile, saying so) both kernels now
            with kernel_notice():
                self._step_numba(np.zeros(b, dtype=bool), np.zeros(b))  # steps no env
                self._observe()

    def _car_tables(self, b: int) -> None:
        """The cars' tables and the ring of their perceived poses (the perception delay);
        for the compiled backend the car step's state, scratch and the others' presence
        without the cars (vei.gym.cars_kernel)."""
        pk = self.pk
        ct = CarTables(self.world, pk.OX.shape[2], pk.OX.shape[1])
        self._ctab = ct
        self.CP = np.zeros((b, 5, ct.tidx.shape[1]))  # x y yaw vx vy as perceived
        self.CRING = np.zeros((self.delay + 1, *self.CP.shape))
        self._co = (ct.tci, self.CP)
        if self.backend != "numba":  # the NumPy step keeps its own (self.CARS)
            return
        self._ct = ct.group()
        self._cs = tuple(self.CARS[name] for name in CAR_STATE_ORDER)
        c = ct.tidx.shape[1]
        self._cscr = (np.zeros((6, c)), np.zeros(c, np.int64), np.zeros(6))
        self._oact = pk.OACT.copy()  # the cars' columns: tested by step_cars at their poses
        for s, n in enumerate(ct.n):
            self._oact[s][:, ct.tidx[s, :n]] = False
        self.HIT0 = np.zeros_like(self.HIT)
        self._xk: tuple[Any, ...] | None = None
        if self._xr is not None:
            r = self.XS.shape[2]
            self.XV = np.zeros((b, 2, r))
            self.XH0 = np.zeros((b, r), np.bool_)
            self._xk = (self.XS, self.XB, self.XV, self.XH0)

    # ------------------------------------------------------------------ episodes
    def _draw(self, envs: np.ndarray) -> None:
        """New scenario and time shift for ``envs`` (their own generators), initial state."""
        from vei.sim.step import initial_state

        spread = self.config.time_shift_spread_s
        n = self.world.n
        for e in envs:
            rng = self._rngs[e]
            i = int(rng.integers(n))
            j = rng.uniform(-1.0, 1.0)
            self.SC[e] = i
            self.SHIFT[e] = self.world.scenarios[i].base_shift_s + spread * j
        for i in np.unique(self.SC[envs]):
            sel = envs[self.SC[envs] == i]
            ws = self.world.scenarios[i]
            params = ws.params.take(np.zeros(sel.size, np.intp)).with_values(
                time_shift_s=self.SHIFT[sel]
            )
            st = initial_state(ws.arrays, params)
            self._write(sel, st)
        self.K[envs] = 0
        self.steps[envs] = 0

    def _write(self, envs: np.ndarray, st: SimState) -> None:
        for r, name in enumerate(_FLOAT_STATE):
            self.FS[r, envs] = getattr(st, name)
        for r, name in enumerate(_BOOL_STATE):
            self.BS[r, envs] = getattr(st, name)
        self.HIT[envs] = 0
        self.HIT[envs, : st.hit_other.shape[1]] = st.hit_other
        r = st.extra_x_m.shape[1]
        self.XS[envs] = 0.0  # the columns past the scenario's R: inert padding riders
        self.XB[envs] = False
        for f, name in enumerate(EXTRA_FLOAT_FIELDS):
            self.XS[envs, f, :r] = getattr(st, name)
        for f, name in enumerate(EXTRA_BOOL_FIELDS):
            self.XB[envs, f, :r] = getattr(st, name)
        self._write_cars(envs, st)

    def _write_cars(self, envs: np.ndarray, st: Any) -> None:
        for name, arr in self.CARS.items():
            v = np.asarray(getattr(st, name))
            arr[(envs, *(slice(0, d) for d in v.shape[1:]))] = v

    def state_of(self, envs: npt.ArrayLike) -> SimState:
        """The engine's SimState of environments ``envs`` (all at the same step and scenario)."""
        envs = np.asarray(envs)
        ks, scs = np.unique(self.K[envs]), np.unique(self.SC[envs])
        if ks.size != 1 or scs.size != 1:
            raise InputError("state_of needs environments at the same step of the same scenario")
        arrays = self.world.scenarios[int(scs[0])].arrays
        n, no = envs.size, len(arrays.other_ids)
        z = np.zeros(n)
        fields: dict[str, Any] = {
            name: self.FS[r, envs].copy() for r, name in enumerate(_FLOAT_STATE)
        }
        fields.update({name: self.BS[r, envs] > 0 for r, name in enumerate(_BOOL_STATE[:4])})
        fields["rider_decision"] = self.BS[4, envs].astype(np.int8)
        fields.update(
            k=int(ks[0]), ego_cmd=z.copy(), pid_integral_m=z.copy(), pid_prev_error_mps=z.copy(),
            cap_state=np.zeros(n, np.int8), hit_other=self.HIT[envs, :no] > 0,
            hist=np.zeros((4, 1, n)),
        )  # fmt: skip
        r = arrays.riders.n
        for f, name in enumerate(EXTRA_FLOAT_FIELDS):
            fields[name] = self.XS[envs, f, :r].copy()
        fields["extra_decision"] = fields["extra_decision"].astype(np.int8)
        for f, name in enumerate(EXTRA_BOOL_FIELDS):
            fields[name] = self.XB[envs, f, :r].copy()
        # issue 24's state (no pedestrians walk: the env refuses them): as at k = 0, but
        # with reacting cars their state and the contact latches (self.CARS), kept
        from vei.sim.contacts import initial_contact_state
        from vei.sim.pedestrians import initial_pedestrian_state
        from vei.sim.traffic import initial_traffic_state

        fields.update(initial_traffic_state(arrays, n))
        fields.update(initial_contact_state(n, no, arrays.traffic.n))
        fields.update(initial_pedestrian_state(arrays, n))
        for name, arr in self.CARS.items():  # reacting cars: their own state, kept
            shape = fields[name].shape
            fields[name] = arr[(envs, *(slice(0, d) for d in shape[1:]))].copy()
        return SimState(**fields)

    def reset(
        self, *, seed: int | list[int] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[npt.NDArray[np.float32], dict[str, Any]]:
        """Reset every environment; environment i draws with the generator of seed + i
        (a list gives each its seed; None: fresh entropy)."""
        from gymnasium.utils import seeding

        if options:
            raise InputError("the vector env takes no reset options")
        b = self.num_envs
        if seed is None:
            seeds: list[int | None] = [None] * b
        elif isinstance(seed, int):
            seeds = [seed + i for i in range(b)]
        else:
            if len(seed) != b:
                raise InputError(f"reset got {len(seed)} seeds for {b} environments")
            seeds = list(seed)
        self._rngs = [seeding.np_random(s)[0] for s in seeds]
        self.HIT[:] = 0
        self._draw(np.arange(b))
        self._needs_reset[:] = False
        return self._observe(), {
            "time_shift_s": self.SHIFT.copy(),
            "scenario_index": self.SC.copy(),
        }

    # ------------------------------------------------------------------ stepping
    def _step_numba(self, run: np.ndarray, a: np.ndarray) -> None:
        from vei.gym.kernel import step_envs

        pk = self.pk
        cars = self._cars
        if cars:  # the state of step k the cars' contacts read (vei.gym.cars_kernel)
            self.HIT0[:] = self.HIT
            if self._xk is not None:
                self.XV[:, 0], self.XV[:, 1] = self.XS[:, 5], self.XS[:, 2]
                self.XH0[:] = self.XB[:, 3]
        step_envs(
            run, a, pk.dt, self.FS, self.BS, self.HIT, self.K, self.SC, self.SHIFT,
            pk.P, pk.ALPHA, pk.DIM, pk.EP, pk.ep_s0, pk.ep_ds, pk.ep_n,
            pk.RT, pk.rt_t0, pk.rt_dt, pk.rt_tend, pk.rt_n, pk.rt_sfm0,
            pk.RP, pk.rp_s0, pk.rp_ds, pk.rp_n, pk.rp_len, pk.rp_ex, pk.rp_ey,
            pk.OX, pk.OY, pk.OYAW, self._oact, pk.OL, pk.OW, pk.n_o, pk.CF, pk.cf_n, self._xr,
            self.PREV, self.TERMS,
        )  # fmt: skip
        if self._xr is not None:  # the extra riders (vei.gym.riders_kernel)
            from vei.gym.riders_kernel import step_riders

            step_riders(run, pk.dt, self.K, self.SC, self.PREV, self.FS, pk.DIM, pk.P,
                        pk.OX, pk.OY, pk.OYAW, pk.OACT, self._xr, self.TERMS)  # fmt: skip
        if cars:  # the reacting cars (vei.gym.cars_kernel)
            from vei.gym.cars_kernel import step_cars

            step_cars(run, pk.dt, self.K, self.SC, self.PREV, self.FS, self.BS, self.HIT0,
                      self.HIT, pk.DIM, pk.P, pk.OX, pk.OY, pk.OYAW, pk.OSP, pk.OACT, pk.OL,
                      pk.OW, pk.n_o, self._ct, self._cs, self._xk, self._cscr, self.TERMS)  # fmt: skip

    def _groups(self, envs: np.ndarray) -> list[np.ndarray]:
        key = self.SC[envs] * (1 << 32) + self.K[envs]
        return [envs[key == u] for u in np.unique(key)]

    def _step_numpy(self, run: np.ndarray, a: np.ndarray) -> None:
        from vei.sim.observe import Demand
        from vei.sim.step import step

        for sel in self._groups(np.flatnonzero(run)):
            ws = self.world.scenarios[int(self.SC[sel[0]])]
            params = ws.params.take(np.zeros(sel.size, np.intp)).with_values(
                time_shift_s=self.SHIFT[sel]
            )
            st = self.state_of(sel)
            n = sel.size
            new = step(
                st,
                params,
                ws.arrays,
                None,
                Demand(a[sel], np.full(n, np.nan), np.zeros(n, np.int8)),
            )
            v, yaw = st.ego_v_mps, st.ego_yaw_rad
            contact = new.collided & ~st.collided
            impact = np.hypot(v * np.cos(yaw) - st.rider_vx_mps, v * np.sin(yaw) - st.rider_vy_mps)
            self.TERMS[sel, 0] = (
                contact
                + np.count_nonzero(new.hit_other & ~st.hit_other, axis=1)
                + np.count_nonzero(new.extra_hit & ~st.extra_hit, axis=1)
            )
            self.TERMS[sel, 1] = np.where(contact & st.rider_active, impact, np.nan)
            self.TERMS[sel, 2] = np.minimum(
                new.ego_s_m - st.ego_s_m, params.cruise_speed_mps * ws.arrays.dt_s
            )
            self.TERMS[sel, 3] = new.ego_a_mps2**2 * ws.arrays.dt_s
            for r, name in enumerate(_FLOAT_STATE):
                self.FS[r, sel] = getattr(new, name)
            for r, name in enumerate(_BOOL_STATE):
                self.BS[r, sel] = getattr(new, name)
            self.HIT[sel, : new.hit_other.shape[1]] = new.hit_other
            r = new.extra_x_m.shape[1]
            for f, name in enumerate(EXTRA_FLOAT_FIELDS):
                self.XS[sel, f, :r] = getattr(new, name)
            for f, name in enumerate(EXTRA_BOOL_FIELDS):
                self.XB[sel, f, :r] = getattr(new, name)
            self._write_cars(sel, new)
            self.K[sel] = new.k

    def _perceive(self) -> None:
        """Store every environment's rider truth (x y yaw vx vy active) of its step k in
        the ring and set RD to the one of step k - delay (stale where k < delay: the
        observation then shows nothing, as the engine's PolicyDriver)."""
        h = self.delay + 1
        cols = np.arange(self.num_envs)
        now = self.K % h
        for r, row in enumerate((F_RX, F_RY, F_RYAW, F_RVX, F_RVY)):
            self.RING[now, r, cols] = self.FS[row]
        self.RING[now, 5, cols] = self.BS[0]
        if self.delay == 0:
            self.RD[:] = self.RING[0]
        else:
            self.RD[:] = self.RING[(self.K - self.delay) % h, :, cols].T
        if self.XS.shape[2] and self.delay == 0:  # the extra riders' truth (x y yaw vx vy
            self.XD[:, :5] = self.XS[:, :5]  # active), the same way
            self.XD[:, 5] = self.XB[:, 0]
        elif self.XS.shape[2]:
            self.XRING[now, cols, :5] = self.XS[:, :5]
            self.XRING[now, cols, 5] = self.XB[:, 0]
            self.XD[:] = self.XRING[(self.K - self.delay) % h, cols]
        if self._cars:  # the reacting cars' pose and velocity (vei.sim.contacts.others_now)
            from vei.models.traffic_core import REACTING

            c = self.CARS
            rec = self.pk.OSP[self.SC[:, None], self.K[:, None], self._ctab.tidx[self.SC]]
            sp = np.where(c["car_mode"] > REACTING, c["car_v_mps"], rec)
            yaw = c["car_yaw_rad"]
            cp = np.stack((c["car_x_m"], c["car_y_m"], yaw, sp * np.cos(yaw), sp * np.sin(yaw)), 1)
            if self.delay:
                self.CRING[now, cols] = cp
                self.CP[:] = self.CRING[(self.K - self.delay) % h, cols]
            else:
                self.CP[:] = cp

    def _observe(self) -> npt.NDArray[np.float32]:
        cfg = self.config
        self._perceive()
        if self.backend == "numba":
            from vei.gym.kernel import observe_envs

            pk = self.pk
            observe_envs(
                pk.dt, self.FS, self.BS, self.K, self.SC, pk.P, pk.DIM, pk.T_n, pk.path_end,
                pk.cat_r, self.RD, self.delay, pk.EP, pk.ep_s0, pk.ep_ds, pk.ep_n, pk.OX, pk.OY, pk.OYAW, pk.OSP,
                pk.OACT, pk.OL, pk.OW, pk.OCAT, pk.n_o, pk.ROAD, pk.rd_x0, pk.rd_y0, pk.rd_cell,
                pk.rd_nx, pk.rd_ny, pk.road_on, cfg.max_objects, cfg.gap_cap_m, self._xo,
                self._co, self.OBS,
            )  # fmt: skip
            return self.OBS.copy()
        from vei.sim.batch import batch_flags
        from vei.sim.observe import build_observation, ground_truth, object_table

        for sel in self._groups(np.arange(self.num_envs)):
            ws = self.world.scenarios[int(self.SC[sel[0]])]
            params = ws.params.take(np.zeros(sel.size, np.intp)).with_values(
                time_shift_s=self.SHIFT[sel]
            )
            st = self.state_of(sel)
            blk = batch_flags(params, ws.arrays.dt_s).blocks[0]
            truth = ground_truth(st, ws.arrays, slice(None))
            kd = st.k - self.delay
            a, j0 = ws.arrays, 1 + ws.arrays.riders.n  # the replayed others' columns
            if self.delay:  # the truth of step k - delay (PolicyDriver's ring)
                truth[:, :, 0] = self.RD[:, sel]
                truth[:, :, 1:j0] = self.XD[sel, :, : j0 - 1].transpose(1, 0, 2)
                if kd >= 0 and len(a.other_ids):
                    yaw, sp = a.other_yaw_rad[kd], a.other_speed_mps[kd]
                    rows = (a.other_x_m[kd], a.other_y_m[kd], yaw, sp * np.cos(yaw),
                            sp * np.sin(yaw), a.other_active[kd].astype(np.float64))  # fmt: skip
                    for r, row in enumerate(rows):
                        truth[r, :, j0:] = row
            if self._cars and a.traffic.n:  # the cars as perceived (self.CP)
                tr = a.traffic
                truth[:5, :, j0 + tr.idx] = self.CP[sel, :, : tr.n].transpose(1, 0, 2)
            valid = (truth[5] > 0.5) & (kd >= 0)
            age = np.full(valid.shape, self.delay * ws.arrays.dt_s)
            obs = build_observation(st, ws.arrays, blk, truth, valid, age, object_table(ws.arrays))
            t_left = (ws.arrays.n_steps - 1 - st.k) * ws.arrays.dt_s
            on = None
            if ws.road is not None:
                on = ws.road.lookup(st.rider_x_m, st.rider_y_m) * valid[:, 0]
            self.OBS[sel] = vectorize(
                obs, max_objects=cfg.max_objects, cap_m=cfg.gap_cap_m,
                time_remaining_s=np.full(sel.size, t_left), rider_on_road=on,
            )  # fmt: skip
        return self.OBS.copy()

    def step(
        self, actions: Any
    ) -> tuple[npt.NDArray[np.float32], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """One step of every environment (NEXT_STEP autoreset; see the module docstring)."""
        if not self._rngs:
            raise InputError("call reset() before step()")
        b = self.num_envs
        a = check_actions(actions, self.action_low, self.action_high, b)
        resetting = self._needs_reset
        run = ~resetting
        self.TERMS[:] = 0.0
        if run.any():
            if self.backend == "numba":
                self._step_numba(run, a)
            else:
                self._step_numpy(run, a)
        self.steps[run] += 1
        if resetting.any():
            self._draw(np.flatnonzero(resetting))
        w = self.config.reward
        rewards = (
            w.collision * self.TERMS[:, 0]
            + w.injury_risk * injury_risk(self.TERMS[:, 1])
            + w.progress * self.TERMS[:, 2]
            + w.comfort * self.TERMS[:, 3]
        )
        terminated = run & (self.TERMS[:, 0] > 0)
        limit = self.config.max_episode_steps
        truncated = run & (self.K >= self.pk.T_n[self.SC] - 1)
        if limit is not None:
            truncated |= run & (self.steps >= limit)
        self._needs_reset = terminated | truncated
        rewards = np.where(run, rewards, 0.0)
        return self._observe(), rewards, terminated, truncated, {}

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release (no subprocesses)."""
        return None


__all__ = ["VeiVectorEnv", "refuse_features", "unsupported_features"]
