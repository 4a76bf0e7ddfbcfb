"""CARLA backend: the same scenario, controllers and time series, on a CARLA server.

The built-in engine's pure step (:func:`vei.sim.engine.step`) is the controller: every
tick the ego's pose and speed *measured in CARLA* replace the engine's kinematic ego in
the state, the engine step computes the CAP perception and state machine, the PID /
braking command u in [-1, 1], and the rider's next state (replay or social forces, with
the measured ego box), and the backend applies them:

- ego: ``carla.VehicleControl`` with ``throttle = max(u, 0)``, ``brake = max(-u, 0)``
  and ``steer`` from a pure-pursuit controller on the recorded ego path (look-ahead
  ``max(lookahead_min_m, lookahead_time_s * v)`` from the rear axle; wheelbase and
  maximum steering angle read from the blueprint's physics). CARLA's vehicle physics
  replaces the engine's actuator model (lag, acceleration limits).
- rider (the primary threat): a kinematic actor (physics off) moved each tick with
  ``set_transform`` to the engine's new pose (replay or social force). CARLA has no
  e-scooter: the default blueprint is the bicycle ``vehicle.diamondback.century``
  (:data:`vei.sim.backends.carla_frame.DEFAULT_BLUEPRINTS`, configurable).
- other recorded road users: kinematic actors replayed with ``set_transform``; spawned
  when they appear, destroyed when they leave.
- collisions: a ``sensor.other.collision`` on the ego, plus the engine's oriented-box
  test on the measured poses; either latches the collision, after which the ego brakes
  fully (hand brake) and the rider stays where it is, as in the engine.

The world is generated from the scenario's OpenDRIVE map
(``client.generate_opendrive_world``) and run in synchronous mode with
``fixed_delta_seconds`` = the engine step; the original settings are restored and every
spawned actor destroyed at the end. CARLA is left-handed (y flipped, yaw in degrees
clockwise): poses are converted at the boundary with :mod:`.carla_frame`.

The output is the engine's long time series (:data:`vei.types.TIMESERIES_COLUMNS`), so
metrics, figures and the case study work unchanged.

Connection: ``host``/``port`` (defaults from ``$VEI_CARLA_HOST`` / ``$VEI_CARLA_PORT``,
else 127.0.0.1:2000). Without a server the backend raises :class:`BackendError` naming
host:port within the timeout (a TCP probe fails at once when nothing listens).
"""

from __future__ import annotations

import math
import os
import socket
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from vei.config import CaseConfig, SimConfig, case_preset
from vei.errors import BackendError, ConfigError, DependencyError, InputError
from vei.models import ego as ego_model
from vei.models.geometry import boxes_overlap
from vei.sim.backends.carla_frame import (
    DEFAULT_BLUEPRINTS,
    carla_deg_to_yaw,
    carla_to_world_xy,
    command_to_pedals,
    pure_pursuit_steer,
    world_to_carla_xy,
    yaw_to_carla_deg,
)
from vei.types import EGO_CATEGORY, Scenario

#: Default CARLA RPC port.
DEFAULT_PORT = 2000
#: The client package version this backend is written for.
CLIENT_VERSION = "0.9.16"


@dataclass(frozen=True)
class CarlaSettings:
    """How to reach and drive the CARLA server.

    Attributes:
        host, port: the server's RPC endpoint.
        timeout_s: client timeout [s] for connecting and for every blocking call.
        blueprints: CARLA blueprint per vei category (overrides of DEFAULT_BLUEPRINTS).
        spawn_height_m: actors are placed this high above the road surface [m].
        lookahead_min_m, lookahead_time_s: pure-pursuit look-ahead
            ``max(lookahead_min_m, lookahead_time_s * v)`` [m], [s].
        wheelbase_m, max_steer_deg: the ego's geometry for pure pursuit; None = read from
            the blueprint's physics control (fallback 2.8 m, 70 deg).
        vertex_distance_m, max_road_length_m, wall_height_m, additional_width_m,
        smooth_junctions: ``carla.OpendriveGenerationParameters`` of the generated world
            (no walls by default: riders leave the carriageway).
        generate_world: True = build the world from the scenario's .xodr; False = use the
            server's current world (it must be the same map).
    """

    host: str = "127.0.0.1"
    port: int = DEFAULT_PORT
    timeout_s: float = 10.0
    blueprints: Mapping[str, str] = field(default_factory=dict)
    spawn_height_m: float = 0.3
    lookahead_min_m: float = 4.0
    lookahead_time_s: float = 1.0
    wheelbase_m: float | None = None
    max_steer_deg: float | None = None
    vertex_distance_m: float = 2.0
    max_road_length_m: float = 500.0
    wall_height_m: float = 0.0
    additional_width_m: float = 0.6
    smooth_junctions: bool = True
    generate_world: bool = True

    def __post_init__(self) -> None:
        if not isinstance(self.host, str) or not self.host:
            raise ConfigError(f"host must be a non-empty string, got {self.host!r}")
        if (
            isinstance(self.port, bool)
            or not isinstance(self.port, int)
            or not 0 < self.port < 65536
        ):
            raise ConfigError(f"port must be an integer in 1..65535, got {self.port!r}")
        for name in (
            "timeout_s",
            "lookahead_min_m",
            "lookahead_time_s",
            "vertex_distance_m",
            "max_road_length_m",
        ):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
                raise ConfigError(f"{name} must be a finite number > 0, got {v!r}")
        for name in ("spawn_height_m", "wall_height_m", "additional_width_m"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"{name} must be a finite number >= 0, got {v!r}")
        for name in ("wheelbase_m", "max_steer_deg"):
            v = getattr(self, name)
            if v is not None and (not isinstance(v, int | float) or not math.isfinite(v) or v <= 0):
                raise ConfigError(f"{name} must be None or a number > 0, got {v!r}")
        unknown = set(self.blueprints) - set(DEFAULT_BLUEPRINTS)
        if unknown:
            raise ConfigError(
                f"blueprints for unknown categories {sorted(unknown)}; expected {sorted(DEFAULT_BLUEPRINTS)}"
            )

    @classmethod
    def from_env(cls, **overrides: Any) -> CarlaSettings:
        """Settings with host/port from $VEI_CARLA_HOST / $VEI_CARLA_PORT (then overrides).

        An override of None leaves the value from the environment / the default.
        """
        values: dict[str, Any] = {}
        if os.environ.get("VEI_CARLA_HOST"):
            values["host"] = os.environ["VEI_CARLA_HOST"]
        if os.environ.get("VEI_CARLA_PORT"):
            raw = os.environ["VEI_CARLA_PORT"]
            try:
                values["port"] = int(raw)
            except ValueError as exc:
                raise ConfigError(f"VEI_CARLA_PORT must be an integer, got {raw!r}") from exc
        values.update({k: v for k, v in overrides.items() if v is not None})
        return cls(**values)

    def blueprint(self, category: str) -> str:
        """The blueprint id for a vei category."""
        return dict(DEFAULT_BLUEPRINTS, **dict(self.blueprints))[category]


def _carla():
    try:
        import carla
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise DependencyError(
            f"the CARLA backend needs the CARLA client package: pip install 'vei[carla]' (carla=={CLIENT_VERSION})"
        ) from exc
    return carla


def connect(host: str, port: int, timeout_s: float) -> Any:
    """A connected ``carla.Client``; BackendError naming host:port if no server answers.

    A TCP probe of host:port first (fails at once when nothing listens, else within
    ``timeout_s``), then the client's version handshake with ``client.set_timeout``.
    """
    carla = _carla()
    where = f"{host}:{port}"
    start = time.monotonic()
    try:
        with socket.create_connection((host, port), timeout=timeout_s):
            pass
    except OSError as exc:
        raise BackendError(
            f"no CARLA server at {where}: {exc.strerror or exc} (after {time.monotonic() - start:.2f} s). "
            "Start CARLA (CarlaUE4.sh / CarlaUnreal.sh) or point vei at one with --host/--port "
            "or VEI_CARLA_HOST/VEI_CARLA_PORT."
        ) from exc
    client = carla.Client(host, port)
    remaining = max(0.1, timeout_s - (time.monotonic() - start))
    client.set_timeout(remaining)
    try:
        server = client.get_server_version()
    except RuntimeError as exc:
        raise BackendError(
            f"the CARLA server at {where} did not answer within {timeout_s:g} s: {exc}"
        ) from exc
    client.set_timeout(timeout_s)
    if server.split("-")[0] != CLIENT_VERSION:
        # Mismatched versions usually work for this API subset, but say so.
        import warnings

        warnings.warn(
            f"CARLA server {server} at {where} differs from the client {CLIENT_VERSION}",
            stacklevel=2,
        )
    return client


# --------------------------------------------------------------------------------------
# The closed loop, independent of CARLA's API (tested without a server)
# --------------------------------------------------------------------------------------
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
class TickCommand:
    """What to apply before the next tick: the ego's command u in [-1, 1] and steer
    (CARLA sign), whether to hold it (after a collision), and the rider's next state."""

    u: float
    steer: float
    hold: bool
    rider_x_m: float
    rider_y_m: float
    rider_yaw_rad: float
    rider_vx_mps: float
    rider_vy_mps: float
    rider_active: bool


class ClosedLoop:
    """The engine's step as a controller around a measured ego (one variant, B = 1).

    ``observe(k, measurement, contact)`` puts the measured ego into the state at step k
    (arc length by projection onto the recorded path) and records the time-series
    sample; ``command()`` runs :func:`vei.sim.engine.step` and returns what to apply.
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
        from vei.sim.state import VariantParams, prepare_scenario

        self._engine = engine
        self.case = case
        self.arrays = prepare_scenario(scenario, sim or SimConfig())
        self.params = VariantParams.from_case(case, self.arrays, 1, time_shift_s=time_shift_s)
        self.flags = engine.batch_flags(self.params, self.arrays.dt_s)
        self.state = engine.initial_state(self.arrays, self.params, self.flags)
        self.lookahead_min_m = lookahead_min_m
        self.lookahead_time_s = lookahead_time_s
        self.wheelbase_m = wheelbase_m
        self.max_steer_rad = max_steer_rad
        path = self.arrays.ego_path
        self._path_xy = np.stack([path.x_m, path.y_m], axis=1)
        self._states: list[Any] = []

    @property
    def n_steps(self) -> int:
        """T, the number of recorded steps (t = 0 included)."""
        return self.arrays.n_steps

    @property
    def dt_s(self) -> float:
        """The fixed step [s]."""
        return self.arrays.dt_s

    def observe(self, meas: EgoMeasurement, contact: bool = False) -> None:
        """Replace the state's ego by the measurement at the current step and record it.

        Args:
            meas: the ego measured at t = k dt. contact: the simulator reported an
                ego-rider contact since the previous step (latched with the box test).
        """
        st = self.state
        a = self.arrays
        s, _ = ego_model.project_onto_path(
            a.ego_path, np.array([meas.x_m]), np.array([meas.y_m]), st.ego_s_m
        )
        ex, ey, eyaw = np.array([meas.x_m]), np.array([meas.y_m]), np.array([meas.yaw_rad])
        overlap = st.rider_active & boxes_overlap(
            ex, ey, eyaw, a.ego_length_m, a.ego_width_m,
            st.rider_x_m, st.rider_y_m, st.rider_yaw_rad, a.rider_length_m, a.rider_width_m,
        )  # fmt: skip
        collided = st.collided | overlap | bool(contact)
        new_hit = collided & ~st.collided
        self.state = st._replace(
            ego_s_m=np.maximum(s, st.ego_s_m),
            ego_x_m=ex,
            ego_y_m=ey,
            ego_yaw_rad=eyaw,
            ego_v_mps=np.array([max(meas.speed_mps, 0.0)]),
            ego_a_mps2=np.array([meas.accel_mps2]),
            collided=collided,
            rider_vx_mps=np.where(new_hit, 0.0, st.rider_vx_mps),
            rider_vy_mps=np.where(new_hit, 0.0, st.rider_vy_mps),
            rider_speed_mps=np.where(new_hit, 0.0, st.rider_speed_mps),
        )
        self._record()

    def command(self) -> TickCommand:
        """Run the engine step from the observed state; returns the commands to apply."""
        st = self.state
        new = self._engine.step(st, self.params, self.arrays, self.flags)
        collided = bool(st.collided[0])
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
        )

    def mark_hit_other(self, index: int) -> None:
        """Latch a contact of the ego with replayed other road user ``index``."""
        hit = self.state.hit_other.copy()
        hit[0, index] = True
        self.state = self.state._replace(hit_other=hit)

    def _record(self) -> None:
        self._states.append(self.state)

    def result(self) -> Any:
        """The observed steps as a :class:`vei.sim.engine.SimResult` (B = 1)."""
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
            other_x_m=a.other_x_m[:n],
            other_y_m=a.other_y_m[:n],
            other_yaw_rad=a.other_yaw_rad[:n],
            other_speed_mps=a.other_speed_mps[:n],
            other_active=a.other_active[:n],
            final_state=self._states[-1],
            **series,
        )

    def to_frame(self) -> pd.DataFrame:
        """The observed steps as the engine's long time series (TIMESERIES_COLUMNS)."""
        return self.result().to_frame(self.case.name)


# --------------------------------------------------------------------------------------
# CARLA I/O
# --------------------------------------------------------------------------------------
def _xodr_text(scenario: Scenario) -> str:
    rel = scenario.maps.get("opendrive")
    if not rel:
        raise InputError(
            "the scenario has no OpenDRIVE map (scenario.json 'maps': {'opendrive': ...}); "
            "attach one with `vei reconstruct --map` or `vei map build`",
            path=scenario.root,
            field="maps",
        )
    if scenario.root is None:
        raise InputError("the scenario's folder is unknown: cannot find its map", field="maps")
    path = scenario.root / rel
    if not path.is_file():
        raise InputError("OpenDRIVE map not found", path=path, field="maps")
    return path.read_text(encoding="utf-8")


class _World:
    """Actors and settings of one CARLA session; restores everything on close()."""

    def __init__(self, client: Any, settings: CarlaSettings, dt_s: float, xodr: str | None) -> None:
        carla = _carla()
        self.carla = carla
        self.client = client
        self.cfg = settings
        try:
            if xodr is not None:
                params = carla.OpendriveGenerationParameters(
                    settings.vertex_distance_m,
                    settings.max_road_length_m,
                    settings.wall_height_m,
                    settings.additional_width_m,
                    settings.smooth_junctions,
                    True,
                    False,
                )
                self.world = client.generate_opendrive_world(xodr, params)
            else:
                self.world = client.get_world()
            self.map = self.world.get_map()
            self.original = self.world.get_settings()
            ws = self.world.get_settings()
            ws.synchronous_mode = True
            ws.fixed_delta_seconds = dt_s
            self.world.apply_settings(ws)
        except RuntimeError as exc:
            raise BackendError(f"CARLA server {settings.host}:{settings.port}: {exc}") from exc
        self.library = self.world.get_blueprint_library()
        self.actors: list[Any] = []

    def transform(self, x_m: float, y_m: float, yaw_rad: float, z_extra_m: float = 0.0) -> Any:
        carla = self.carla
        cx, cy = world_to_carla_xy(x_m, y_m)
        loc = carla.Location(x=float(cx), y=float(cy), z=0.0)
        wp = self.map.get_waypoint(loc, project_to_road=True)
        z = (
            (wp.transform.location.z if wp is not None else 0.0)
            + self.cfg.spawn_height_m
            + z_extra_m
        )
        return carla.Transform(
            carla.Location(x=float(cx), y=float(cy), z=float(z)),
            carla.Rotation(yaw=float(yaw_to_carla_deg(yaw_rad))),
        )

    def spawn(self, blueprint_id: str, role: str, transform: Any, *, kinematic: bool) -> Any:
        try:
            bp = self.library.find(blueprint_id)
        except (IndexError, RuntimeError) as exc:
            raise BackendError(f"CARLA has no blueprint {blueprint_id!r}") from exc
        if bp.has_attribute("role_name"):
            bp.set_attribute("role_name", role)
        target = transform
        if kinematic:
            # spawn high above its place (free space: no spawn collision), then teleport
            carla = self.carla
            loc = transform.location
            transform = carla.Transform(
                carla.Location(x=loc.x, y=loc.y, z=loc.z + 200.0), transform.rotation
            )
        actor = self.world.try_spawn_actor(bp, transform)
        if actor is None:
            raise BackendError(
                f"could not spawn {blueprint_id} for {role!r} at x={transform.location.x:.2f}, "
                f"y={transform.location.y:.2f} (CARLA frame): the place is occupied or off the map"
            )
        self.actors.append(actor)
        if kinematic:
            actor.set_simulate_physics(False)
            actor.set_transform(target)
        return actor

    def destroy(self, actor: Any) -> None:
        if actor in self.actors:
            self.actors.remove(actor)
        if actor.is_alive:
            actor.destroy()

    def close(self) -> None:
        for actor in reversed(self.actors):
            try:
                if actor.type_id.startswith("sensor."):
                    actor.stop()
                if actor.is_alive:
                    actor.destroy()
            except RuntimeError:
                pass
        self.actors.clear()
        try:
            self.world.apply_settings(self.original)
        except RuntimeError:
            pass


def _ego_geometry(actor: Any, settings: CarlaSettings) -> tuple[float, float]:
    wheelbase, max_steer = settings.wheelbase_m, settings.max_steer_deg
    if wheelbase is None or max_steer is None:
        try:
            wheels = actor.get_physics_control().wheels
            front = [(w.position.x, w.position.y) for w in wheels[:2]]
            rear = [(w.position.x, w.position.y) for w in wheels[2:4]]
            fx, fy = np.mean(front, axis=0)
            rx, ry = np.mean(rear, axis=0)
            wb = float(np.hypot(fx - rx, fy - ry)) / 100.0  # wheel positions are in cm
            ms = float(wheels[0].max_steer_angle)
        except (RuntimeError, IndexError, AttributeError):
            wb, ms = 2.8, 70.0
        wheelbase = wheelbase or (wb if 1.0 < wb < 6.0 else 2.8)
        max_steer = max_steer or (ms if 5.0 < ms < 90.0 else 70.0)
    return float(wheelbase), math.radians(float(max_steer))


def _measure(actor: Any) -> EgoMeasurement:
    tf = actor.get_transform()
    vel = actor.get_velocity()
    acc = actor.get_acceleration()
    x, y = carla_to_world_xy(tf.location.x, tf.location.y)
    yaw = float(carla_deg_to_yaw(tf.rotation.yaw))
    fwd = tf.get_forward_vector()
    v = vel.x * fwd.x + vel.y * fwd.y + vel.z * fwd.z
    a = acc.x * fwd.x + acc.y * fwd.y + acc.z * fwd.z
    return EgoMeasurement(float(x), float(y), yaw, max(float(v), 0.0), float(a))


def run_carla(
    scenario: Scenario,
    configs: Sequence[str | CaseConfig] | str | CaseConfig,
    *,
    time_shift_s: float = 0.0,
    sim: SimConfig | None = None,
    settings: CarlaSettings | None = None,
    host: str | None = None,
    port: int | None = None,
    timeout_s: float | None = None,
) -> pd.DataFrame:
    """Run configurations on a CARLA server; the engine's long time series.

    Args:
        scenario: the reconstructed scenario (with an OpenDRIVE map in its folder).
        configs: configuration name(s) ('replay', 'normal', ..., see vei.config) or
            CaseConfig(s); each runs once, one after the other, in one generated world.
        time_shift_s: the primary rider's time shift [s] (resolve 'auto' with the
            built-in engine before calling).
        sim: engine settings (the step ``dt_s`` becomes CARLA's fixed_delta_seconds).
        settings: connection and actor settings (default: CarlaSettings.from_env()).
        host, port, timeout_s: shortcuts overriding ``settings``.

    Returns:
        DataFrame with TIMESERIES_COLUMNS: one row per agent per step per configuration.

    Raises:
        BackendError: no server at host:port (within the timeout), a blueprint missing,
        an actor that cannot be spawned. InputError: the scenario has no map.
    """
    settings = settings or CarlaSettings.from_env()
    if host is not None or port is not None or timeout_s is not None:
        settings = CarlaSettings(
            **{
                **{f: getattr(settings, f) for f in settings.__dataclass_fields__},
                **{
                    k: v
                    for k, v in (("host", host), ("port", port), ("timeout_s", timeout_s))
                    if v is not None
                },
            }
        )
    cases = [configs] if isinstance(configs, str | CaseConfig) else list(configs)
    cases = [case_preset(c) if isinstance(c, str) else c for c in cases]
    if not cases:
        raise ConfigError("run_carla needs at least one configuration")
    sim = sim or SimConfig()
    client = connect(settings.host, settings.port, settings.timeout_s)
    xodr = _xodr_text(scenario) if settings.generate_world else None
    frames = []
    world = _World(client, settings, sim.dt_s, xodr)
    try:
        for case in cases:
            frames.append(_run_one(world, scenario, case, sim, time_shift_s, settings))
    finally:
        world.close()
    return pd.concat(frames, ignore_index=True)


def _run_one(
    world: _World,
    scenario: Scenario,
    case: CaseConfig,
    sim: SimConfig,
    shift: float,
    cfg: CarlaSettings,
) -> pd.DataFrame:
    loop = ClosedLoop(scenario, case, sim=sim, time_shift_s=shift)
    a = loop.arrays
    st = loop.state
    carla = world.carla
    ego = world.spawn(
        cfg.blueprint(EGO_CATEGORY), "hero",
        world.transform(float(st.ego_x_m[0]), float(st.ego_y_m[0]), float(st.ego_yaw_rad[0])),
        kinematic=False,
    )  # fmt: skip
    wheelbase, max_steer = _ego_geometry(ego, cfg)
    loop.wheelbase_m, loop.max_steer_rad = wheelbase, max_steer
    contacts: list[int] = []
    bp = world.library.find("sensor.other.collision")
    sensor = world.world.spawn_actor(bp, carla.Transform(), attach_to=ego)
    world.actors.append(sensor)
    sensor.listen(lambda event: contacts.append(int(event.other_actor.id)))
    rider_actor = None
    others: dict[int, Any] = {}
    bar = None
    if sys.stderr.isatty():
        from rich.progress import Progress

        bar = Progress(transient=True)
        bar.start()
    try:
        # initial speed along the heading, then one tick to settle
        yaw0 = float(st.ego_yaw_rad[0])
        v0 = float(loop.params.initial_speed_mps[0])
        vx, vy = world_to_carla_xy(v0 * math.cos(yaw0), v0 * math.sin(yaw0))
        ego.set_target_velocity(carla.Vector3D(float(vx), float(vy), 0.0))
        world.world.tick()
        if bar is not None:
            task = bar.add_task(f"CARLA {case.name}", total=loop.n_steps)
        for k in range(loop.n_steps):
            if bar is not None:
                bar.advance(task)
            # replayed others and the rider at step k
            for j, oid in enumerate(a.other_ids):
                active = bool(a.other_active[k, j])
                if active and j not in others:
                    others[j] = world.spawn(
                        cfg.blueprint(a.other_categories[j]), oid,
                        world.transform(a.other_x_m[k, j], a.other_y_m[k, j], a.other_yaw_rad[k, j]),
                        kinematic=True,
                    )  # fmt: skip
                elif active:
                    others[j].set_transform(
                        world.transform(a.other_x_m[k, j], a.other_y_m[k, j], a.other_yaw_rad[k, j])
                    )
                elif j in others:
                    world.destroy(others.pop(j))
            rs = loop.state
            if bool(rs.rider_active[0]):
                tf = world.transform(
                    float(rs.rider_x_m[0]), float(rs.rider_y_m[0]), float(rs.rider_yaw_rad[0])
                )
                if rider_actor is None:
                    rider_actor = world.spawn(
                        cfg.blueprint(a.rider_category), a.rider_id, tf, kinematic=True
                    )
                else:
                    rider_actor.set_transform(tf)
            elif rider_actor is not None and bool(rs.rider_done[0]):
                world.destroy(rider_actor)
                rider_actor = None
            hit_rider = rider_actor is not None and rider_actor.id in contacts
            for j, actor in others.items():
                if actor.id in contacts:
                    loop.mark_hit_other(j)
            contacts.clear()
            loop.observe(_measure(ego), contact=hit_rider)
            if k == loop.n_steps - 1:
                break
            cmd = loop.command()
            throttle, brake = command_to_pedals(cmd.u)
            ego.apply_control(
                carla.VehicleControl(
                    throttle=float(throttle), brake=float(brake), steer=float(cmd.steer),
                    hand_brake=cmd.hold,
                )
            )  # fmt: skip
            world.world.tick()
    except RuntimeError as exc:
        raise BackendError(
            f"CARLA server {cfg.host}:{cfg.port} failed during the run: {exc}"
        ) from exc
    finally:
        if bar is not None:
            bar.stop()
        sensor.stop()
        for actor in [*others.values(), rider_actor, sensor, ego]:
            if actor is not None:
                world.destroy(actor)
    return loop.to_frame()


def run_cases_frame(
    scenario: Scenario,
    cases: Sequence[CaseConfig],
    time_shift_s: float,
    sim: SimConfig,
    *,
    settings: CarlaSettings | None = None,
    host: str | None = None,
    port: int | None = None,
    timeout_s: float | None = None,
) -> pd.DataFrame:
    """The case study's backend signature (vei.experiments.casestudy.Runner) on CARLA.

    Host/port default to $VEI_CARLA_HOST / $VEI_CARLA_PORT (else 127.0.0.1:2000); see
    :func:`run_carla`.
    """
    return run_carla(
        scenario, list(cases), time_shift_s=time_shift_s, sim=sim, settings=settings,
        host=host, port=port, timeout_s=timeout_s,
    )  # fmt: skip


def carla_runner(
    host: str | None = None,
    port: int | None = None,
    timeout_s: float | None = None,
    **settings: Any,
):
    """A case-study Runner bound to a server: ``run_casestudy(..., backend=carla_runner(h, p))``.

    Arguments left None come from $VEI_CARLA_HOST / $VEI_CARLA_PORT or the defaults;
    ``settings`` are further CarlaSettings fields (blueprints, spawn_height_m, ...).
    The returned function is named 'carla' (the backend name in summaries).
    """
    cfg = CarlaSettings.from_env(host=host, port=port, timeout_s=timeout_s, **settings)

    def carla(
        scenario: Scenario, cases: Sequence[CaseConfig], time_shift_s: float, sim: SimConfig
    ) -> pd.DataFrame:
        return run_cases_frame(scenario, cases, time_shift_s, sim, settings=cfg)

    return carla
