"""One interface for every world vei drives: load a scenario, step with commands, measure.

A *backend* hosts the world (the built-in kinematics, esmini, a CARLA server); the
*controllers* are vei's own and the same for every backend: :class:`ClosedLoop` wraps the
built-in engine's pure step (:func:`vei.sim.engine.step`: ego PID + CAP, social-force or
replayed rider, box collisions) around what the backend measures. One run is::

    loop = ClosedLoop(scenario, case, sim=sim, time_shift_s=shift)
    meas = backend.load(loop)                # the world at t = 0
    for k in range(loop.n_steps):
        loop.observe(meas)                   # measured ego / rider / others -> the state
        if k == loop.n_steps - 1: break
        cmd = loop.command()                 # controllers -> TickCommand for t = (k + 1) dt
        meas = backend.step(cmd)             # apply, advance dt, measure
    backend.unload()
    frame = loop.to_frame()                  # the engine's long time series

:func:`run_backend` does exactly this for several configurations, so every backend
returns the same :data:`vei.types.TIMESERIES_COLUMNS` and the case study, metrics and
figures work unchanged. What a backend does with a :class:`TickCommand`:

- builtin (:mod:`.builtin`): places the ego and the rider where the engine's kinematics
  put them (an ideal plant; the loop then equals :func:`vei.sim.engine.run_cases`);
- esmini (:mod:`.esmini`): reports the ego's and the social-force rider's poses to esmini,
  which moves the replayed road users (and the replayed rider), and reads every state back;
- CARLA (:mod:`.carla`): applies ``u``/``steer`` as VehicleControl (CARLA's physics
  moves the ego) and teleports the rider.
"""

from __future__ import annotations

import math
import sys
from abc import ABC, abstractmethod
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from vei.boxes import boxes_overlap
from vei.config import CaseConfig, SimConfig, case_preset
from vei.errors import BackendError, ConfigError
from vei.models import ego as ego_model
from vei.sim.backends.carla_frame import pure_pursuit_steer
from vei.types import Scenario


@dataclass(frozen=True)
class EgoMeasurement:
    """The ego as the simulator reports it (vei frame): position [m], yaw [rad], speed
    [m/s] (>= 0, along the heading), longitudinal acceleration [m/s^2]."""

    x_m: float
    y_m: float
    yaw_rad: float
    speed_mps: float
    accel_mps2: float


@dataclass(frozen=True)
class RiderMeasurement:
    """The primary rider as the simulator reports it (vei frame): position [m], yaw
    [rad], velocity [m/s] and speed [m/s]."""

    x_m: float
    y_m: float
    yaw_rad: float
    vx_mps: float
    vy_mps: float
    speed_mps: float


@dataclass(frozen=True)
class Measurement:
    """Everything a backend measured at one step.

    Attributes:
        ego: the ego.
        rider: the rider, or None where the backend does not report it (the controller's
            own rider state stands). Used only while the rider is active and no collision
            has happened (after one, vei's rule freezes both).
        contact_rider: the simulator reported an ego-rider contact since the previous step.
        contact_others: indices (into ``ScenarioArrays.other_ids``) of replayed road users
            the simulator reported in contact with the ego.
        others: [n_o, 4] x [m], y [m], yaw [rad], speed [m/s] of the replayed road users
            as the simulator has them (NaN rows: not measured), or None (not measured).
    """

    ego: EgoMeasurement
    rider: RiderMeasurement | None = None
    contact_rider: bool = False
    contact_others: tuple[int, ...] = ()
    others: np.ndarray | None = None


@dataclass(frozen=True)
class TickCommand:
    """What the controllers want for the next step (t = (k + 1) dt).

    Attributes:
        u: the ego's longitudinal command in [-1, 1] (throttle > 0, brake < 0).
        steer: pure-pursuit steering in [-1, 1] (CARLA sign: positive turns clockwise).
        hold: a collision happened: hold the ego (full brake).
        ego_x_m, ego_y_m, ego_yaw_rad, ego_v_mps, ego_a_mps2: the ego where the engine's
            kinematics (path following, actuator lag) put it at k + 1 [m, rad, m/s,
            m/s^2]; backends that place the ego (builtin, esmini) apply these.
        rider_x_m, rider_y_m, rider_yaw_rad, rider_vx_mps, rider_vy_mps, rider_speed_mps:
            the rider's next state (replay or social force) [m, rad, m/s].
        rider_active: whether the rider is in the scene at k + 1.
        rider_controlled: True where vei's model moves the rider (social force); False
            where the rider replays its (time-shifted) recording, which a backend may play.
    """

    u: float
    steer: float
    hold: bool
    rider_x_m: float
    rider_y_m: float
    rider_yaw_rad: float
    rider_vx_mps: float
    rider_vy_mps: float
    rider_active: bool
    ego_x_m: float = math.nan
    ego_y_m: float = math.nan
    ego_yaw_rad: float = math.nan
    ego_v_mps: float = math.nan
    ego_a_mps2: float = 0.0
    rider_speed_mps: float = math.nan
    rider_controlled: bool = True


class Backend(ABC):
    """A world vei's controllers can drive (see the module doc for one run).

    Subclasses set ``name`` and implement :meth:`load` and :meth:`step`; :meth:`start`
    / :meth:`close` bracket a session (one scenario, several runs), :meth:`unload` ends
    one run. A backend raises :class:`vei.errors.BackendError` for anything the world
    refuses (no server, a file it cannot load, a failed step).
    """

    name: str = "backend"

    def start(self, scenario: Scenario, sim: SimConfig) -> None:  # noqa: B027 - optional hook
        """Open a session for ``scenario`` (connect, load the map). Default: nothing."""

    @abstractmethod
    def load(self, loop: ClosedLoop) -> Measurement:
        """Load one run (the loop's scenario, case, time shift and step) at t = 0.

        Args:
            loop: the run's controller (read its ``arrays``, ``params``, ``state``; a
                backend may set ``wheelbase_m`` / ``max_steer_rad`` from its vehicle).
        Returns:
            The measurement at t = 0.
        """

    @abstractmethod
    def step(self, command: TickCommand) -> Measurement:
        """Apply ``command``, advance the world by one step (dt), return the measurement."""

    def unload(self) -> None:  # noqa: B027 - optional hook
        """End the current run (destroy its actors, close the scenario). Default: nothing."""

    def close(self) -> None:  # noqa: B027 - optional hook
        """End the session (restore the world's settings). Default: nothing."""


# --------------------------------------------------------------------------------------
# The closed loop, independent of any simulator's API
# --------------------------------------------------------------------------------------
class ClosedLoop:
    """The engine's step as a controller around a measured world (one variant, B = 1).

    ``observe(measurement)`` puts the measured ego (arc length by projection onto the
    recorded path), rider and others into the state at step k and records the
    time-series sample; ``command()`` runs :func:`vei.sim.engine.step` and returns what
    to apply for step k + 1.
    """

    def __init__(
        self,
        scenario: Scenario,
        case: CaseConfig,
        *,
        sim: SimConfig | None = None,
        time_shift_s: float = 0.0,
        lookahead_min_m: float = 4.0,
        lookahead_time_s: float = 1.0,
        wheelbase_m: float = 2.8,
        max_steer_rad: float = math.radians(70.0),
    ) -> None:
        from vei.sim import engine
        from vei.sim.observe import PolicyDriver
        from vei.sim.state import VariantParams, prepare_scenario

        self._engine = engine
        self.scenario = scenario
        self.case = case
        self.sim = sim or SimConfig()
        self.time_shift_s = float(time_shift_s)
        self.arrays = prepare_scenario(scenario, self.sim)
        if self.arrays.riders.n:
            raise ConfigError(
                f"this backend drives only the primary rider ({self.arrays.rider_id}) as a "
                f"social-force rider; sfm_riders selects {', '.join(self.arrays.riders.ids)} "
                "too: use the built-in engine (--backend builtin) or --sfm-riders primary"
            )
        self.params = VariantParams.from_case(case, self.arrays, 1, time_shift_s=time_shift_s)
        self.flags = engine.batch_flags(self.params, self.arrays.dt_s)
        self.state = engine.initial_state(self.arrays, self.params, self.flags)
        # A policy on the API (vei.policy: aeb, idm, a user's) decides from the observed state.
        self._driver = (
            PolicyDriver(self.arrays, self.params, self.flags) if self.flags.any_policy else None
        )
        self.lookahead_min_m = lookahead_min_m
        self.lookahead_time_s = lookahead_time_s
        self.wheelbase_m = wheelbase_m
        self.max_steer_rad = max_steer_rad
        #: compute the pure-pursuit steering (a backend that places the ego itself, like
        #: esmini or the ideal plant, switches it off in load(); TickCommand.steer is 0 then)
        self.steering = True
        path = self.arrays.ego_path
        self._path_xy = np.stack([path.x_m, path.y_m], axis=1)
        self._states: list[Any] = []
        self._others: list[np.ndarray | None] = []

    @property
    def n_steps(self) -> int:
        """T, the number of recorded steps (t = 0 included)."""
        return self.arrays.n_steps

    @property
    def dt_s(self) -> float:
        """The fixed step [s]."""
        return self.arrays.dt_s

    @property
    def rider_replayed(self) -> bool:
        """True where the rider replays its (time-shifted) recording (configuration 'replay')."""
        return not bool(self.flags.blocks[0].rider_sfm)

    def observe(self, meas: Measurement | EgoMeasurement, contact: bool = False) -> None:
        """Replace the state's ego (and rider, others) by the measurement at the current step.

        Args:
            meas: what the simulator measured at t = k dt (an EgoMeasurement alone: ego only).
            contact: an ego-rider contact reported since the previous step (or
                ``meas.contact_rider``); it counts only while the rider is active. Latched
                with the oriented-box test of the measured poses.
        """
        if isinstance(meas, EgoMeasurement):
            meas = Measurement(ego=meas, contact_rider=bool(contact))
        elif contact:
            meas = Measurement(
                meas.ego, meas.rider, True, meas.contact_others, meas.others
            )  # fmt: skip
        st = self.state
        a = self.arrays
        em = meas.ego
        # rider: the measured pose while it is active and nothing has collided yet
        rider = {}
        if meas.rider is not None and bool(st.rider_active[0]) and not bool(st.collided[0]):
            r = meas.rider
            rider = {
                "rider_x_m": np.array([r.x_m]),
                "rider_y_m": np.array([r.y_m]),
                "rider_yaw_rad": np.array([r.yaw_rad]),
                "rider_vx_mps": np.array([r.vx_mps]),
                "rider_vy_mps": np.array([r.vy_mps]),
                "rider_speed_mps": np.array([r.speed_mps]),
            }
            if st.hist.shape[1] > 1:  # the perception buffer sees the measured pose
                hist = st.hist.copy()
                slot = st.k % st.hist.shape[1]
                hist[0, slot, 0], hist[1, slot, 0], hist[2, slot, 0] = r.x_m, r.y_m, r.yaw_rad
                rider["hist"] = hist
            st = st._replace(**rider)
        if em.x_m == float(st.ego_x_m[0]) and em.y_m == float(st.ego_y_m[0]):
            s = st.ego_s_m  # the ego is where the step put it: its arc length stands
        else:
            s, _ = ego_model.project_onto_path(
                a.ego_path, np.array([em.x_m]), np.array([em.y_m]), st.ego_s_m
            )
        ex, ey, eyaw = np.array([em.x_m]), np.array([em.y_m]), np.array([em.yaw_rad])
        overlap = st.rider_active & boxes_overlap(
            ex, ey, eyaw, a.ego_length_m, a.ego_width_m,
            st.rider_x_m, st.rider_y_m, st.rider_yaw_rad, a.rider_length_m, a.rider_width_m,
        )  # fmt: skip
        collided = st.collided | overlap | (st.rider_active & bool(meas.contact_rider))
        new_hit = collided & ~st.collided
        hit_other = st.hit_other
        if meas.contact_others or meas.others is not None:
            hit_other = self._others_hits(meas, ex, ey, eyaw, hit_other)
        self.state = st._replace(
            ego_s_m=np.maximum(s, st.ego_s_m),
            ego_x_m=ex,
            ego_y_m=ey,
            ego_yaw_rad=eyaw,
            ego_v_mps=np.array([max(em.speed_mps, 0.0)]),
            ego_a_mps2=np.array([em.accel_mps2]),
            collided=collided,
            hit_other=hit_other,
            rider_vx_mps=np.where(new_hit, 0.0, st.rider_vx_mps),
            rider_vy_mps=np.where(new_hit, 0.0, st.rider_vy_mps),
            rider_speed_mps=np.where(new_hit, 0.0, st.rider_speed_mps),
        )
        self._states.append(self.state)
        self._others.append(None if meas.others is None else np.asarray(meas.others, float))

    def _others_hits(
        self, meas: Measurement, ex: np.ndarray, ey: np.ndarray, eyaw: np.ndarray, hit: np.ndarray
    ) -> np.ndarray:
        a, k = self.arrays, self.state.k
        hit = hit.copy()
        for j in meas.contact_others:
            if 0 <= j < hit.shape[1] and bool(a.other_active[k, j]):
                hit[0, j] = True
        if meas.others is not None:
            reach = 0.5 * (
                np.hypot(a.ego_length_m, a.ego_width_m)
                + np.hypot(a.other_length_m, a.other_width_m)
            )
            near = np.hypot(meas.others[:, 0] - ex[0], meas.others[:, 1] - ey[0]) <= reach
            for j in np.flatnonzero(a.other_active[k] & ~hit[0] & near):
                x, y, yaw = meas.others[j, :3]
                if np.isfinite(x) and bool(
                    boxes_overlap(
                        ex, ey, eyaw, a.ego_length_m, a.ego_width_m,
                        np.array([x]), np.array([y]), np.array([yaw]),
                        a.other_length_m[j], a.other_width_m[j],
                    )[0]
                ):  # fmt: skip
                    hit[0, j] = True
        return hit

    def command(self) -> TickCommand:
        """Run the engine step from the observed state; returns the commands to apply."""
        st = self.state
        action = self._driver.act(st) if self._driver is not None else None
        new = self._engine.step(st, self.params, self.arrays, self.flags, action)
        collided = bool(st.collided[0])
        steer = 0.0
        if self.steering:
            v = float(st.ego_v_mps[0])
            ld = max(self.lookahead_min_m, self.lookahead_time_s * v)
            yaw = float(st.ego_yaw_rad[0])
            rear_x = float(st.ego_x_m[0]) - 0.5 * self.wheelbase_m * math.cos(yaw)
            rear_y = float(st.ego_y_m[0]) - 0.5 * self.wheelbase_m * math.sin(yaw)
            steer = pure_pursuit_steer(
                rear_x, rear_y, yaw, self._path_xy,
                lookahead_m=ld, wheelbase_m=self.wheelbase_m, max_steer_rad=self.max_steer_rad,
            )  # fmt: skip
        self.state = new
        return TickCommand(
            u=-1.0 if collided else float(new.ego_cmd[0]),
            steer=steer,
            hold=collided,
            rider_x_m=float(new.rider_x_m[0]),
            rider_y_m=float(new.rider_y_m[0]),
            rider_yaw_rad=float(new.rider_yaw_rad[0]),
            rider_vx_mps=float(new.rider_vx_mps[0]),
            rider_vy_mps=float(new.rider_vy_mps[0]),
            rider_active=bool(new.rider_active[0]),
            ego_x_m=float(new.ego_x_m[0]),
            ego_y_m=float(new.ego_y_m[0]),
            ego_yaw_rad=float(new.ego_yaw_rad[0]),
            ego_v_mps=float(new.ego_v_mps[0]),
            ego_a_mps2=float(new.ego_a_mps2[0]),
            rider_speed_mps=float(new.rider_speed_mps[0]),
            rider_controlled=not self.rider_replayed,
        )

    def mark_hit_other(self, index: int) -> None:
        """Latch a contact of the ego with replayed other road user ``index``."""
        hit = self.state.hit_other.copy()
        hit[0, index] = True
        self.state = self.state._replace(hit_other=hit)

    def result(self) -> Any:
        """The observed steps as a :class:`vei.sim.engine.SimResult` (B = 1).

        The replayed road users are where the backend measured them (where it did), else
        where the recording has them.
        """
        eng, a = self._engine, self.arrays
        if not self._states:
            raise BackendError("no step was observed")
        series = {
            name: np.stack([getattr(st, attr) for st in self._states], axis=1).astype(dtype)
            for name, attr, dtype in eng._RECORDED
        }
        t = np.array([st.k for st in self._states]) * a.dt_s
        coll = series["collided"][0]
        active = series["rider_active"][0]
        d = np.hypot(
            series["rider_x_m"][0] - series["ego_x_m"][0],
            series["rider_y_m"][0] - series["ego_y_m"][0],
        )
        n = len(self._states)
        others = [a.other_x_m[:n].copy(), a.other_y_m[:n].copy()]
        others += [a.other_yaw_rad[:n].copy(), a.other_speed_mps[:n].copy()]
        for k, m in enumerate(self._others):
            if m is None or m.size == 0:
                continue
            ok = np.isfinite(m[:, 0]) & a.other_active[k]
            for c in range(4):
                others[c][k, ok] = m[ok, c]
        return eng.SimResult(
            t_s=t,
            labels=self.params.labels.copy(),
            params=self.params,
            scenario_id=a.scenario_id,
            rider_id=a.rider_id,
            rider_category=a.rider_category,
            ego_length_m=a.ego_length_m,
            ego_width_m=a.ego_width_m,
            rider_length_m=a.rider_length_m,
            rider_width_m=a.rider_width_m,
            hit_other=np.stack([st.hit_other for st in self._states], axis=1),
            collision_time_s=np.array([t[np.argmax(coll)] if coll.any() else np.nan]),
            min_center_distance_m=np.array([d[active].min() if active.any() else np.inf]),
            other_ids=a.other_ids,
            other_categories=a.other_categories,
            other_length_m=a.other_length_m,
            other_width_m=a.other_width_m,
            other_x_m=others[0],
            other_y_m=others[1],
            other_yaw_rad=others[2],
            other_speed_mps=others[3],
            other_active=a.other_active[:n],
            final_state=self._states[-1],
            **series,
        )

    def to_frame(self) -> pd.DataFrame:
        """The observed steps as the engine's long time series (TIMESERIES_COLUMNS)."""
        return self.result().to_frame(self.case.name)


def resolve_case_list(
    configs: Sequence[str | CaseConfig] | str | CaseConfig,
) -> list[CaseConfig]:
    """Configuration name(s) or CaseConfig(s) -> a non-empty list of CaseConfigs."""
    cases = [configs] if isinstance(configs, str | CaseConfig) else list(configs)
    out = [case_preset(c) if isinstance(c, str) else c for c in cases]
    if not out:
        raise ConfigError("a backend run needs at least one configuration")
    return out


def run_backend(
    backend: Backend,
    scenario: Scenario,
    configs: Sequence[str | CaseConfig] | str | CaseConfig,
    *,
    time_shift_s: float = 0.0,
    sim: SimConfig | None = None,
    progress: bool | None = None,
) -> pd.DataFrame:
    """Run configurations one after the other on ``backend``; the long time series.

    Args:
        backend: the world (builtin, esmini, CARLA, ...).
        scenario: the reconstructed scenario.
        configs: configuration name(s) or CaseConfig(s).
        time_shift_s: the primary rider's time shift [s] ('auto' is resolved before).
        sim: engine settings (its step ``dt_s`` is the backend's step).
        progress: show a progress bar (default: when stderr is a terminal).

    Returns:
        DataFrame with TIMESERIES_COLUMNS: one row per agent per step per configuration.
    """
    cases = resolve_case_list(configs)
    sim = sim or SimConfig()
    show = sys.stderr.isatty() if progress is None else progress
    frames = []
    backend.start(scenario, sim)
    try:
        for case in cases:
            loop = ClosedLoop(scenario, case, sim=sim, time_shift_s=time_shift_s)
            bar = task = None
            if show:
                from rich.progress import Progress

                bar = Progress(transient=True)
                bar.start()
                task = bar.add_task(f"{backend.name} {case.name}", total=loop.n_steps)
            try:
                meas = backend.load(loop)
                for k in range(loop.n_steps):
                    loop.observe(meas)
                    if bar is not None:
                        bar.advance(task)
                    if k == loop.n_steps - 1:
                        break
                    meas = backend.step(loop.command())
            finally:
                if bar is not None:
                    bar.stop()
                backend.unload()
            frames.append(loop.to_frame())
    finally:
        backend.close()
    return pd.concat(frames, ignore_index=True)
