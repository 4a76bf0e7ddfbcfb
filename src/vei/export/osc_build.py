"""The storyboard of an exported OpenSCENARIO file: entities, Init, events, stop trigger.

How a vei run becomes a storyboard that plays as written (checked with esmini 3.6 by
:mod:`vei.export.playback`, for every version 1.0-1.3):

- An agent whose first sample is at t = 0 is placed in ``Init``: a ``TeleportAction`` to
  its first vertex and its ``FollowTrajectoryAction`` (timed polyline, absolute timing).
  Init actions start with the simulation, so no start trigger can be missed (a
  ``SimulationTimeCondition 0`` under edge ``rising`` is missed at t = 0 by esmini).
- An agent whose first sample t0 is later has no Init action, so it does not exist
  before t0 (esmini keeps an entity without Init actions inactive: not drawn, not
  recorded, no collisions). An event fires at simulation time > t0 - ``TRIGGER_MARGIN_S``
  with an ``AddEntityAction`` at its first vertex and its ``FollowTrajectoryAction``.
- An agent whose last sample t1 is before the end of the run gets an event at simulation
  time > t1 - ``TRIGGER_MARGIN_S`` with a ``DeleteEntityAction``.
- ``StopTrigger``: simulation time > t_end - ``TRIGGER_MARGIN_S``.

Every condition uses edge ``none``; the margin (1 ms, ten times the 0.1 ms rounding of
the written times) makes a condition meant for an instant t fire at a player step that
lands on t. A player evaluates conditions before it advances its clock (esmini: the
storyboard steps at T, then the world moves to T + dt and is recorded), so an entity
added at T = t0 is recorded from t0 + dt on, at its trajectory's position of that time,
and one deleted at T = t1 is recorded last at t1: never outside [t0, t1].

AddEntityAction / DeleteEntityAction are GlobalActions (``EntityAction``) in every
version 1.0-1.3, and priority ``parallel`` and edge ``none`` exist in 1.0 too, so a 1.0
file expresses the same presence and motion. What 1.0 lacks: the rule
``greaterOrEqual`` (1.2+; the act starts on time > -1 ms instead), ``mass`` and
``model3d`` on vehicles (1.1+; without ``model3d=""`` esmini looks for a default 3D model
per category and, in a headless install without models, warns that it found none), and
vertices without time (a simulator ego's path keeps its sample times, ignored under
``TimeReference/None``).

``ego_controller='simulator'``: the ego gets its Init pose and speed and, from the first
step after the start, its path as a trajectory *without timing* (``TimeReference/None``,
following mode ``follow``): the simulator's own speed control moves it along the path.
When the recorded (or simulated) ego first moves (speed > ``MOVING_SPEED_MPS``), an event
sets its target speed to the run's cruise speed (median speed while moving) with a
``linear`` rate of ``SIMULATOR_ACCEL_MPS2``; when the path ends (the follow action's
``endTransition``) a step to 0 m/s stops it there instead of letting it drive on along the
road network. So the ego drives the recorded route and reaches the conflict area about
when the recording did (esmini 3.6 on stadtmitte_12, where the ego waits 50 s at a light
and then drives 60 m: within 0.1 mm of its path, moving from 50.45 s).

Every entity carries the properties ``vei:agent_id``, ``vei:category``, ``vei:span_s``
("t0 t1", its first and last sample time) and, where known, ``vei:source_track_id``.

Reference point and box: the reference point of every entity is its box centre (vei's
trajectories are box centres), the ``BoundingBox`` ``Center`` is (0, 0, height / 2) and
the rear axle sits at x = 0 (esmini shifts a vehicle's box when the rear axle is off the
reference point, which would move the box away from vei's). So two boxes overlap in the
player exactly when vei's footprints overlap.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Literal

import numpy as np
import pandas as pd

from vei.types import EGO_CATEGORY, AgentInfo

#: Margin [s] by which presence / stop conditions precede the instant they mark.
TRIGGER_MARGIN_S = 1e-3
#: Acceleration [m/s^2] of the simulator-driven ego towards its cruise speed.
SIMULATOR_ACCEL_MPS2 = 2.0
#: Speeds [m/s] above which a sample counts as moving (cruise speed of a simulator ego).
MOVING_SPEED_MPS = 0.5

#: Property names vei writes on every entity.
PROP_AGENT_ID = "vei:agent_id"
PROP_CATEGORY = "vei:category"
PROP_SOURCE_TRACK = "vei:source_track_id"
PROP_SPAN = "vei:span_s"
#: Property of an entity whose trajectory holds continuation samples (vei.continuation):
#: "first last" time [s] of its recorded samples; before / after them it is on its run-in
#: / run-out.
PROP_RECORDED_SPAN = "vei:recorded_span_s"


@dataclass(frozen=True)
class EntityModel:
    """How one vei category becomes an OpenSCENARIO entity.

    Attributes:
        kind: 'vehicle' or 'pedestrian' (the OpenSCENARIO entity element).
        osc_category: VehicleCategory / PedestrianCategory value.
        height_m: bounding-box height [m].
        mass_kg: mass [kg] (written from OpenSCENARIO 1.1 on for vehicles).
        max_speed_mps, max_accel_mps2, max_decel_mps2: Performance values (> 0).
    """

    kind: Literal["vehicle", "pedestrian"]
    osc_category: str
    height_m: float
    mass_kg: float
    max_speed_mps: float
    max_accel_mps2: float
    max_decel_mps2: float


#: Entity models per vei category. Performance limits: a sedan (50 m/s, 5 m/s^2,
#: 9 m/s^2), an e-scooter with rider (25 km/h class -> 10 m/s cap, 3 / 6 m/s^2), a
#: cyclist (15 m/s, 3 / 6 m/s^2), a pedestrian (3 m/s, 2 / 3 m/s^2). With
#: followingMode=position the trajectory governs; the limits only inform a simulator's
#: own controller.
ENTITY_MODELS: dict[str, EntityModel] = {
    "ego": EntityModel("vehicle", "car", 1.5, 1600.0, 50.0, 5.0, 9.0),
    "vehicle": EntityModel("vehicle", "car", 1.5, 1600.0, 50.0, 5.0, 9.0),
    "escooter": EntityModel("vehicle", "bicycle", 1.8, 95.0, 10.0, 3.0, 6.0),
    "cyclist": EntityModel("vehicle", "bicycle", 1.8, 95.0, 15.0, 3.0, 6.0),
    "pedestrian": EntityModel("pedestrian", "pedestrian", 1.75, 75.0, 3.0, 2.0, 3.0),
}


#: Entity name per category: the CARLA blueprint ScenarioRunner spawns. The same table as
#: ``vei.sim.backends.carla_frame.DEFAULT_BLUEPRINTS`` (a test keeps them equal), kept here
#: so that the export does not import the simulation layer.
ENTITY_NAMES: dict[str, str] = {
    "ego": "vehicle.lincoln.mkz_2020",
    "vehicle": "vehicle.tesla.model3",
    "escooter": "vehicle.diamondback.century",
    "cyclist": "vehicle.bh.crossbike",
    "pedestrian": "walker.pedestrian.0001",
}


@dataclass(frozen=True)
class BuildOptions:
    """What the storyboard builder needs besides the trajectories.

    Attributes:
        minor: OpenSCENARIO minor version (0..3).
        ego_controller: 'trajectory' | 'simulator' (module doc).
        blueprints: entity name (CARLA blueprint) per category.
        map_name: LogicFile path ('' for none).
        name, description, author, creation_date: FileHeader.
        vertex_rate_hz, max_position_error_m, max_yaw_error_rad: decimation.
    """

    minor: int
    ego_controller: str
    blueprints: Mapping[str, str]
    map_name: str
    name: str
    description: str
    author: str
    creation_date: datetime
    vertex_rate_hz: float | None
    max_position_error_m: float
    max_yaw_error_rad: float


def r(v: float, nd: int) -> float:
    """``v`` rounded to ``nd`` decimals, without a negative zero."""
    out = round(float(v), nd)
    return 0.0 if out == 0 else out


def world_position(xosc, x_m: float, y_m: float, yaw_rad: float):
    """WorldPosition (x, y [m], z = 0, h = yaw wrapped to [-pi, pi]) rounded to 0.1 mm / 1e-5 rad."""
    h = math.remainder(float(yaw_rad), 2 * math.pi)
    return xosc.WorldPosition(r(x_m, 4), r(y_m, 4), 0.0, r(h, 5), 0.0, 0.0)


def speeds(track: pd.DataFrame) -> np.ndarray:
    """[N] speed [m/s] of one agent's rows: ``speed_mps`` if given, else |d(xy)/dt|."""
    if "speed_mps" in track:
        return track["speed_mps"].to_numpy(dtype=float)
    t = track["t_s"].to_numpy(dtype=float)
    if t.size < 2:
        return np.zeros(t.size)
    xy = track[["x_m", "y_m"]].to_numpy(dtype=float)
    return np.hypot(*np.gradient(xy, t, axis=0).T)


def _entity(
    xosc,
    agent: AgentInfo,
    minor: int,
    blueprint: str,
    span: tuple[float, float],
    recorded: tuple[float, float] | None = None,
):
    m = ENTITY_MODELS[agent.category]
    bb = xosc.BoundingBox(agent.width_m, agent.length_m, m.height_m, 0.0, 0.0, m.height_m / 2)
    if m.kind == "pedestrian":
        ent = xosc.Pedestrian(
            blueprint,
            m.mass_kg,
            getattr(xosc.PedestrianCategory, m.osc_category),
            bb,
            model=blueprint,
        )
    else:
        # Rear axle at the reference point (the box centre); wheelbase 0.6 * length.
        # Wheel diameter and track from the footprint (informative only).
        wheel = 0.65 if m.osc_category == "car" else 0.5
        front = xosc.Axle(0.52, wheel, agent.width_m * 0.85, 0.6 * agent.length_m, wheel / 2)
        rear = xosc.Axle(0.0, wheel, agent.width_m * 0.85, 0.0, wheel / 2)
        ent = xosc.Vehicle(
            blueprint,
            getattr(xosc.VehicleCategory, m.osc_category),
            bb,
            front,
            rear,
            m.max_speed_mps,
            m.max_accel_mps2,
            m.max_decel_mps2,
            mass=m.mass_kg if minor >= 1 else None,
        )
    ent.add_property("type", "ego_vehicle" if agent.category == EGO_CATEGORY else "simulation")
    ent.add_property(PROP_AGENT_ID, agent.agent_id)
    ent.add_property(PROP_CATEGORY, agent.category)
    ent.add_property(PROP_SPAN, f"{r(span[0], 4):g} {r(span[1], 4):g}")
    if agent.source_track_id is not None:
        ent.add_property(PROP_SOURCE_TRACK, str(agent.source_track_id))
    if recorded is not None:
        ent.add_property(PROP_RECORDED_SPAN, f"{r(recorded[0], 4):g} {r(recorded[1], 4):g}")
    return ent


def _recorded_span(track) -> tuple[float, float] | None:
    """(first, last) time of a track's recorded samples when it also has continuation
    samples (column ``continuation``); None otherwise (or when none is recorded)."""
    if "continuation" not in track or not track["continuation"].any():
        return None
    rec = track.loc[~track["continuation"].astype(bool), "t_s"].to_numpy(dtype=float)
    return (float(rec[0]), float(rec[-1])) if rec.size else None


def _time_trigger(xosc, name: str, at_s: float, *, stop: bool = False):
    """Simulation time > at_s - margin, edge none."""
    return xosc.ValueTrigger(
        name,
        0.0,
        xosc.ConditionEdge.none,
        xosc.SimulationTimeCondition(r(at_s - TRIGGER_MARGIN_S, 4), xosc.Rule.greaterThan),
        triggeringpoint="stop" if stop else "start",
    )


def build_scenario(
    xosc,
    df: pd.DataFrame,
    agents: Sequence[AgentInfo],
    opts: BuildOptions,
    decimate,
):
    """The scenariogeneration ``Scenario`` of a validated trajectories table.

    Args:
        xosc: the ``scenariogeneration.xosc`` module (version already set).
        df: validated trajectories sorted by agent_id, t_s (see export_openscenario).
        agents: the agents present in ``df``.
        opts: versions, names, decimation.
        decimate: ``decimate_indices``-like callable (t, xy, yaw, **tolerances) -> [K] ints.
    """
    minor = opts.minor
    t_end = float(df["t_s"].max())
    entities = xosc.Entities()
    init = xosc.Init()
    groups = []
    parallel = xosc.Priority.parallel
    for agent in agents:
        track = df[df["agent_id"] == agent.agent_id]
        t = track["t_s"].to_numpy(dtype=float)
        xy = track[["x_m", "y_m"]].to_numpy(dtype=float)
        yaw = track["yaw_rad"].to_numpy(dtype=float)
        t0, t1 = float(t[0]), float(t[-1])
        aid = agent.agent_id
        entities.add_scenario_object(
            aid,
            _entity(
                xosc, agent, minor, opts.blueprints[agent.category], (t0, t1),
                _recorded_span(track),
            ),
        )  # fmt: skip
        first = world_position(xosc, xy[0, 0], xy[0, 1], yaw[0])
        simulator_ego = agent.category == EGO_CATEGORY and opts.ego_controller == "simulator"
        events = []
        follow = None
        if t.size >= 2:
            if simulator_ego:
                follow = _untimed_follow(xosc, aid, t, xy, yaw, minor)
            else:
                idx = decimate(
                    t,
                    xy,
                    yaw,
                    vertex_rate_hz=opts.vertex_rate_hz,
                    max_position_error_m=opts.max_position_error_m,
                    max_yaw_error_rad=opts.max_yaw_error_rad,
                )
                poly = xosc.Polyline(
                    [r(t[i], 4) for i in idx],
                    [world_position(xosc, xy[i, 0], xy[i, 1], yaw[i]) for i in idx],
                )
                traj = xosc.Trajectory(f"{aid}_trajectory", False)
                traj.add_shape(poly)
                follow = xosc.FollowTrajectoryAction(
                    traj, xosc.FollowingMode.position, xosc.ReferenceContext.absolute, 1.0, 0.0
                )
        if simulator_ego:
            init.add_init_action(aid, xosc.TeleportAction(first))
            events.extend(_simulator_ego_events(xosc, aid, track, follow, init))
        elif t0 <= TRIGGER_MARGIN_S:
            init.add_init_action(aid, xosc.TeleportAction(first))
            if follow is not None:
                init.add_init_action(aid, follow)
        else:
            ev = xosc.Event(f"{aid}_appear", parallel)
            ev.add_action(f"{aid}_add", xosc.AddEntityAction(aid, first))
            if follow is not None:
                ev.add_action(f"{aid}_follow_trajectory", follow)
            ev.add_trigger(_time_trigger(xosc, f"{aid}_start", t0))
            events.append(ev)
        if t1 < t_end - TRIGGER_MARGIN_S and not simulator_ego:
            ev = xosc.Event(f"{aid}_disappear", parallel)
            ev.add_action(f"{aid}_delete", xosc.DeleteEntityAction(aid))
            ev.add_trigger(_time_trigger(xosc, f"{aid}_end", t1))
            events.append(ev)
        if events:
            man = xosc.Maneuver(f"{aid}_maneuver")
            for ev in events:
                man.add_event(ev)
            grp = xosc.ManeuverGroup(f"{aid}_maneuver_group")
            grp.add_actor(aid)
            grp.add_maneuver(man)
            groups.append(grp)

    if minor >= 2:
        act_cond = xosc.SimulationTimeCondition(0.0, xosc.Rule.greaterOrEqual)
    else:  # 1.0 / 1.1 have no greaterOrEqual
        act_cond = xosc.SimulationTimeCondition(-TRIGGER_MARGIN_S, xosc.Rule.greaterThan)
    act = xosc.Act(
        "vei_act", xosc.ValueTrigger("vei_act_start", 0.0, xosc.ConditionEdge.none, act_cond)
    )
    if not groups:  # nothing to trigger (all present throughout): an act needs a group
        idle = xosc.ManeuverGroup("vei_idle")
        idle.add_actor(agents[0].agent_id)
        groups.append(idle)
    for g in groups:
        act.add_maneuver_group(g)
    story = xosc.Story("vei_story")
    story.add_act(act)
    sb = xosc.StoryBoard(init, _time_trigger(xosc, "vei_stop", t_end, stop=True))
    sb.add_story(story)
    road = xosc.RoadNetwork(roadfile=opts.map_name)
    return xosc.Scenario(
        opts.description if opts.description else opts.name,
        opts.author,
        xosc.ParameterDeclarations(),
        entities,
        sb,
        road,
        xosc.Catalog(),
        osc_minor_version=minor,
        creation_date=opts.creation_date,
    )


def _simulator_ego_events(xosc, aid: str, track: pd.DataFrame, follow, init) -> list:
    """Init speed and the events of a simulator-driven ego (module doc): its path from the
    start, its cruise speed from the first moving sample, a stop at the path's end."""
    v = speeds(track)
    t = track["t_s"].to_numpy(dtype=float)
    step = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0.0)
    init.add_init_action(aid, xosc.AbsoluteSpeedAction(r(max(v[0], 0.0), 4), step))
    if follow is None:
        return []
    parallel = xosc.Priority.parallel
    moving = np.flatnonzero(v > MOVING_SPEED_MPS)
    cruise = float(np.median(v[moving])) if moving.size else float(max(v[0], 0.0))
    t_move = float(t[moving[0]]) if moving.size else float(t[0])
    path = xosc.Event(f"{aid}_path", parallel)
    path.add_action(f"{aid}_follow_path", follow)
    # time > t (no margin): never in the first step, where Init's TeleportAction and
    # speed are still running (an action started in that step stops them, with a warning)
    path.add_trigger(
        xosc.ValueTrigger(
            f"{aid}_path_start",
            0.0,
            xosc.ConditionEdge.none,
            xosc.SimulationTimeCondition(r(t[0], 4), xosc.Rule.greaterThan),
        )
    )
    go = xosc.Event(f"{aid}_cruise", parallel)
    go.add_action(
        f"{aid}_cruise_speed",
        xosc.AbsoluteSpeedAction(
            r(cruise, 4),
            xosc.TransitionDynamics(
                xosc.DynamicsShapes.linear, xosc.DynamicsDimension.rate, SIMULATOR_ACCEL_MPS2
            ),
        ),
    )
    go.add_trigger(
        xosc.ValueTrigger(
            f"{aid}_cruise_start",
            0.0,
            xosc.ConditionEdge.none,
            xosc.SimulationTimeCondition(r(t_move, 4), xosc.Rule.greaterThan),
        )
    )
    stop = xosc.Event(f"{aid}_path_end", parallel)
    stop.add_action(f"{aid}_stop", xosc.AbsoluteSpeedAction(0.0, step))
    stop.add_trigger(
        xosc.ValueTrigger(
            f"{aid}_path_done",
            0.0,
            xosc.ConditionEdge.none,
            xosc.StoryboardElementStateCondition(
                xosc.StoryboardElementType.action,
                f"{aid}_follow_path",
                xosc.StoryboardElementState.endTransition,
            ),
        )
    )
    return [path, go, stop]


def finish_element(element, minor: int):
    """Touch up the XML element tree of a built scenario (in place; returns it).

    From 1.1 on every Vehicle / Pedestrian gets ``model3d=""`` (no 3D model: a player
    draws its default or a box; scenariogeneration drops empty attributes).
    """
    if minor >= 1:
        for tag in ("Vehicle", "Pedestrian"):
            for el in element.iter(tag):
                el.set("model3d", "")
    return element


def _untimed_follow(xosc, aid: str, t_s: np.ndarray, xy: np.ndarray, yaw: np.ndarray, minor: int):
    """FollowTrajectoryAction along the path without timing (vertices every >= 0.5 m);
    None when the path is shorter than 0.5 m (the ego then keeps its Init pose and speed
    and the file has no event for it: vei's esmini backend replaces such an ego)."""
    keep = [0]
    for i in range(1, len(xy)):
        if math.hypot(*(xy[i] - xy[keep[-1]])) >= 0.5:
            keep.append(i)
    if keep[-1] != len(xy) - 1 and math.hypot(*(xy[-1] - xy[keep[-1]])) > 1e-3:
        keep.append(len(xy) - 1)
    if len(keep) < 2:  # a standing ego (< 0.5 m in all): no path to follow
        return None
    # 1.0 requires vertex times: the sample times, ignored under TimeReference/None
    times = [r(t_s[i], 4) for i in keep] if minor == 0 else []
    poly = xosc.Polyline(times, [world_position(xosc, xy[i, 0], xy[i, 1], yaw[i]) for i in keep])
    traj = xosc.Trajectory(f"{aid}_path", False)
    traj.add_shape(poly)
    return xosc.FollowTrajectoryAction(traj, xosc.FollowingMode.follow, None, None, None)
