"""CARLA backend: the same scenario, controllers and time series, on a CARLA server.

:class:`CarlaBackend` implements :class:`vei.sim.backends.base.Backend`; the controller
is :class:`~vei.sim.backends.base.ClosedLoop` (the engine's pure step), the same as for
every backend: each tick the ego *measured in CARLA* replaces the engine's kinematic ego,
the step computes the CAP, the command u in [-1, 1] and the rider's next state, and the
backend applies them:

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

Connection: ``host``/``port`` (defaults ``$VEI_CARLA_HOST`` / ``$VEI_CARLA_PORT``, else
127.0.0.1:2000). :func:`connect` asks for the version from Python first
(:mod:`.carla_rpc`): no server, no answer within the timeout, or a port that is not CARLA
is a :class:`BackendError` naming host:port; the C++ client never sees such a port.
"""

from __future__ import annotations

import dataclasses
import math
import os
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import pandas as pd

from vei.config import CaseConfig, SimConfig
from vei.errors import BackendError, ConfigError, DependencyError, InputError
from vei.sim.backends.base import (
    Backend,
    ClosedLoop,
    EgoMeasurement,
    Measurement,
    TickCommand,
    resolve_case_list,
    run_backend,
)
from vei.sim.backends.carla_frame import (
    DEFAULT_BLUEPRINTS,
    carla_deg_to_yaw,
    carla_to_world_xy,
    command_to_pedals,
    world_to_carla_xy,
    yaw_to_carla_deg,
)
from vei.sim.backends.carla_rpc import probe_carla
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
    """A connected ``carla.Client``; BackendError naming host:port if no CARLA answers.

    First a probe from Python (:func:`.carla_rpc.probe_carla`): the TCP connection fails
    at once when nothing listens, and the server must answer CARLA's version request with
    a well-formed msgpack-rpc response within ``timeout_s``. Only then does the C++
    client (which aborts the process on a peer that is not CARLA) get the port.
    """
    carla = _carla()
    where = f"{host}:{port}"
    start = time.monotonic()
    server = probe_carla(host, port, timeout_s)
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


class CarlaBackend(Backend):
    """vei's closed loop on a CARLA server (see the module doc)."""

    name = "carla"

    def __init__(self, settings: CarlaSettings | None = None) -> None:
        self.settings = settings or CarlaSettings.from_env()
        self._world: _World | None = None
        self._run: dict[str, Any] | None = None

    def start(self, scenario: Scenario, sim: SimConfig) -> None:
        """Connect (probe first), generate the world from the map, synchronous mode."""
        cfg = self.settings
        client = connect(cfg.host, cfg.port, cfg.timeout_s)
        xodr = _xodr_text(scenario) if cfg.generate_world else None
        self._world = _World(client, cfg, sim.dt_s, xodr)

    def close(self) -> None:
        """Destroy what is left and restore the world's settings."""
        self.unload()
        if self._world is not None:
            self._world.close()
            self._world = None

    def load(self, loop: ClosedLoop) -> Measurement:
        """Spawn the ego (with a collision sensor) at its start, one tick, measure."""
        world, cfg = self._require_world(), self.settings
        carla = world.carla
        st = loop.state
        try:
            ego = world.spawn(
                cfg.blueprint(EGO_CATEGORY), "hero",
                world.transform(float(st.ego_x_m[0]), float(st.ego_y_m[0]), float(st.ego_yaw_rad[0])),
                kinematic=False,
            )  # fmt: skip
            loop.wheelbase_m, loop.max_steer_rad = _ego_geometry(ego, cfg)
            contacts: list[int] = []
            bp = world.library.find("sensor.other.collision")
            sensor = world.world.spawn_actor(bp, carla.Transform(), attach_to=ego)
            world.actors.append(sensor)
            sensor.listen(lambda event: contacts.append(int(event.other_actor.id)))
            self._run = {"loop": loop, "ego": ego, "sensor": sensor, "contacts": contacts,
                         "rider": None, "others": {}, "k": 0}  # fmt: skip
            yaw0 = float(st.ego_yaw_rad[0])
            v0 = float(loop.params.initial_speed_mps[0])
            vx, vy = world_to_carla_xy(v0 * math.cos(yaw0), v0 * math.sin(yaw0))
            ego.set_target_velocity(carla.Vector3D(float(vx), float(vy), 0.0))
            world.world.tick()
            return self._place_and_measure(
                float(st.rider_x_m[0]), float(st.rider_y_m[0]), float(st.rider_yaw_rad[0]),
                bool(st.rider_active[0]), bool(st.rider_done[0]),
            )  # fmt: skip
        except RuntimeError as exc:
            raise BackendError(f"CARLA server {cfg.host}:{cfg.port} failed: {exc}") from exc

    def step(self, command: TickCommand) -> Measurement:
        """VehicleControl from the command, tick, move others and the rider, measure."""
        world, run = self._require_world(), self._run
        if run is None:
            raise BackendError("CARLA backend: no run loaded")
        carla = world.carla
        try:
            throttle, brake = command_to_pedals(command.u)
            run["ego"].apply_control(
                carla.VehicleControl(
                    throttle=float(throttle), brake=float(brake), steer=float(command.steer),
                    hand_brake=command.hold,
                )
            )  # fmt: skip
            world.world.tick()
            run["k"] += 1
            done = bool(run["loop"].state.rider_done[0])
            return self._place_and_measure(
                command.rider_x_m, command.rider_y_m, command.rider_yaw_rad,
                command.rider_active, done,
            )  # fmt: skip
        except RuntimeError as exc:
            cfg = self.settings
            raise BackendError(
                f"CARLA server {cfg.host}:{cfg.port} failed during the run: {exc}"
            ) from exc

    def unload(self) -> None:
        """Destroy the run's actors."""
        run, world = self._run, self._world
        self._run = None
        if run is None or world is None:
            return
        try:
            run["sensor"].stop()
        except RuntimeError:
            pass
        for actor in [*run["others"].values(), run["rider"], run["sensor"], run["ego"]]:
            if actor is not None:
                try:
                    world.destroy(actor)
                except RuntimeError:
                    pass

    def _require_world(self) -> _World:
        if self._world is None:
            raise BackendError("CARLA backend: start() was not called")
        return self._world

    def _place_and_measure(
        self, rx: float, ry: float, ryaw: float, r_active: bool, r_done: bool
    ) -> Measurement:
        """Replayed others and the rider at the current step, then the ego's measurement."""
        world, run, cfg = self._require_world(), self._run, self.settings
        assert run is not None
        loop, k, others = run["loop"], run["k"], run["others"]
        a = loop.arrays
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
        if r_active:
            tf = world.transform(rx, ry, ryaw)
            if run["rider"] is None:
                run["rider"] = world.spawn(
                    cfg.blueprint(a.rider_category), a.rider_id, tf, kinematic=True
                )
            else:
                run["rider"].set_transform(tf)
        elif run["rider"] is not None and r_done:
            world.destroy(run["rider"])
            run["rider"] = None
        contacts = run["contacts"]
        hit_rider = run["rider"] is not None and run["rider"].id in contacts
        hit_others = tuple(j for j, actor in others.items() if actor.id in contacts)
        contacts.clear()
        return Measurement(
            ego=_measure(run["ego"]), contact_rider=hit_rider, contact_others=hit_others
        )


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
        BackendError: no CARLA server at host:port (within the timeout; a port that
        answers but is not CARLA too), a blueprint missing, an actor that cannot be
        spawned. InputError: the scenario has no map.
    """
    settings = settings or CarlaSettings.from_env()
    overrides = {
        k: v for k, v in (("host", host), ("port", port), ("timeout_s", timeout_s)) if v is not None
    }
    if overrides:
        settings = dataclasses.replace(settings, **overrides)
    cases = resolve_case_list(configs)
    return run_backend(CarlaBackend(settings), scenario, cases, time_shift_s=time_shift_s, sim=sim)


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
