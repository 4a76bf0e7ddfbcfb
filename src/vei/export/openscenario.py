"""OpenSCENARIO 1.x export of a vei run (replayed or simulated), via scenariogeneration.

What the exported ``.xosc`` holds:

- ``RoadNetwork/LogicFile``: the scenario's OpenDRIVE map, copied next to the ``.xosc``
  and referenced by its bare file name (a path relative to the ``.xosc``, which esmini
  and CARLA ScenarioRunner both resolve against the scenario file's folder).
- One ``ScenarioObject`` per agent, named by its ``agent_id``, with a ``BoundingBox`` from
  the agent's footprint (the entity's reference point is the box centre: the box's
  ``Center`` is (0, 0, height/2), so the trajectory positions are box centres, the same
  points vei's engine moves). The ego and vehicles are ``car``s; e-scooters and cyclists
  are ``bicycle``s (OpenSCENARIO has no scooter category) told apart by the property
  ``vei:category`` (``escooter`` | ``cyclist`` | ...); pedestrians are ``Pedestrian``s.
  The ``Vehicle``/``Pedestrian`` ``name`` is the CARLA blueprint (ScenarioRunner spawns
  that model) and the ego carries ``Property type=ego_vehicle`` (ScenarioRunner's marker).
- ``Init``: a ``TeleportAction`` to each agent's first position (``WorldPosition``) and an
  ``AbsoluteTargetSpeed`` step to its first speed.
- One ``ManeuverGroup`` per moving agent with a ``FollowTrajectoryAction``: a ``Polyline``
  with timed vertices, ``TimeReference/Timing domainAbsoluteRelative=absolute``
  (vertex times are simulation times), ``followingMode=position``. The event starts
  when the simulation time passes the agent's first sample time (an agent that appears
  later waits at its first position until then).
- ``StopTrigger``: simulation time greater than the last sample time.

Decimation: the vertices are the samples on a ``vertex_rate_hz`` grid (10 Hz by default,
plus the last sample), refined so that the polyline, linearly interpolated in time, stays
within ``max_position_error_m`` (5 cm) and ``max_yaw_error_rad`` (0.05 rad) of every
full-rate sample: where a segment is off by more, its worst sample becomes a vertex too
(an abrupt stop at a collision, say). ``vertex_rate_hz=None`` keeps every sample.
Values are rounded to 0.1 mm, 1e-5 rad and 0.1 ms.

Frame: vei's plane (x east, y north, yaw CCW from +x) is the OpenDRIVE inertial frame of
the map, which is also OpenSCENARIO's world frame: positions are written unchanged.

scenariogeneration keeps the OpenSCENARIO version in class-level state; the export sets
it for the duration of one call, so do not export from several threads at once.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from vei.errors import ConfigError, DependencyError, InputError
from vei.io.atomic import atomic_path
from vei.types import EGO_CATEGORY, AgentInfo

#: OpenSCENARIO versions the export writes (scenariogeneration >= 0.14 supports 1.0-1.3).
OSC_VERSIONS: tuple[str, ...] = ("1.0", "1.1", "1.2", "1.3")
#: Default version: 1.2 (esmini and most tools read it; use 1.0 for CARLA ScenarioRunner,
#: which accepts only 1.0).
DEFAULT_OSC_VERSION = "1.2"

EgoController = Literal["trajectory", "simulator"]

#: Columns the trajectories table must have (speed_mps optional).
REQUIRED_COLUMNS: tuple[str, ...] = ("t_s", "agent_id", "category", "x_m", "y_m", "yaw_rad")

#: Property names vei writes on every entity.
PROP_AGENT_ID = "vei:agent_id"
PROP_CATEGORY = "vei:category"
PROP_SOURCE_TRACK = "vei:source_track_id"


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


def _xosc():
    try:
        from scenariogeneration import xosc
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise DependencyError(
            "OpenSCENARIO export needs scenariogeneration: pip install 'vei[export]'"
        ) from exc
    return xosc


def _minor(osc_version: str) -> int:
    if osc_version not in OSC_VERSIONS:
        raise ConfigError(
            f"osc_version must be one of {', '.join(OSC_VERSIONS)}; got {osc_version!r}"
        )
    return int(osc_version.split(".")[1])


def decimate_indices(
    t_s: np.ndarray,
    xy_m: np.ndarray,
    yaw_rad: np.ndarray,
    *,
    vertex_rate_hz: float | None = 10.0,
    max_position_error_m: float = 0.05,
    max_yaw_error_rad: float = 0.05,
) -> np.ndarray:
    """Indices of the samples kept as polyline vertices.

    Args:
        t_s: [N] strictly increasing sample times [s].
        xy_m: [N, 2] positions [m].
        yaw_rad: [N] yaw [rad] (unwrapped internally).
        vertex_rate_hz: base vertex rate [Hz] (> 0), or None to keep every sample.
        max_position_error_m: largest allowed distance [m] between a sample and the
            polyline linearly interpolated at the sample's time (> 0).
        max_yaw_error_rad: same for yaw [rad] (> 0).

    Returns:
        [K] sorted int indices into the samples, first and last included (K >= min(N, 2)).
    """
    t = np.asarray(t_s, dtype=float)
    n = t.size
    if n <= 2 or vertex_rate_hz is None:
        return np.arange(n)
    if vertex_rate_hz <= 0 or max_position_error_m <= 0 or max_yaw_error_rad <= 0:
        raise ConfigError("vertex_rate_hz, max_position_error_m, max_yaw_error_rad must be > 0")
    period = 1.0 / vertex_rate_hz
    slot = np.floor((t - t[0]) / period + 1e-9).astype(np.int64)
    keep = np.zeros(n, dtype=bool)
    keep[0] = True
    keep[1:] = slot[1:] != slot[:-1]
    keep[-1] = True
    xy = np.asarray(xy_m, dtype=float)
    yaw = np.unwrap(np.asarray(yaw_rad, dtype=float))
    for _ in range(n):  # each pass adds at least one vertex or stops
        idx = np.flatnonzero(keep)
        seg = np.searchsorted(idx, np.arange(n), side="right") - 1
        seg = np.clip(seg, 0, idx.size - 2)
        i0, i1 = idx[seg], idx[seg + 1]
        w = (t - t[i0]) / (t[i1] - t[i0])
        pos = xy[i0] + w[:, None] * (xy[i1] - xy[i0])
        ang = yaw[i0] + w * (yaw[i1] - yaw[i0])
        err_p = np.hypot(*(pos - xy).T) / max_position_error_m
        err_a = np.abs(ang - yaw) / max_yaw_error_rad
        err = np.maximum(err_p, err_a)
        err[keep] = 0.0
        if not np.any(err > 1.0):
            break
        # the worst sample of every offending segment becomes a vertex
        bad = err > 1.0
        order = np.lexsort((-err, seg))
        order = order[bad[order]]
        first = np.ones(order.size, dtype=bool)
        first[1:] = seg[order[1:]] != seg[order[:-1]]
        keep[order[first]] = True
    return np.flatnonzero(keep)


def _validate(trajectories: pd.DataFrame, agents: Sequence[AgentInfo]) -> pd.DataFrame:
    missing = [c for c in REQUIRED_COLUMNS if c not in trajectories.columns]
    if missing:
        raise InputError(
            f"trajectories lack column(s) {', '.join(missing)}; expected {', '.join(REQUIRED_COLUMNS)}"
            " [, speed_mps]",
            field=missing[0],
        )
    df = trajectories.copy()
    df["agent_id"] = df["agent_id"].astype(str)
    num = ["t_s", "x_m", "y_m", "yaw_rad"] + (["speed_mps"] if "speed_mps" in df else [])
    for col in num:
        vals = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(vals))
        if bad.size:
            raise InputError(
                f"not a finite number: {df[col].iloc[bad[0]]!r}", row=int(bad[0]) + 1, field=col
            )
        df[col] = vals
    if (df["t_s"] < 0).any():
        row = int(np.flatnonzero(df["t_s"].to_numpy() < 0)[0]) + 1
        raise InputError("times must be >= 0 s (simulation time)", row=row, field="t_s")
    known = {a.agent_id for a in agents}
    unknown = sorted(set(df["agent_id"]) - known)
    if unknown:
        raise InputError(
            f"agent(s) {', '.join(unknown)} have trajectories but no AgentInfo", field="agent_id"
        )
    dup = df.duplicated(["agent_id", "t_s"])
    if dup.any():
        row = int(np.flatnonzero(dup.to_numpy())[0]) + 1
        raise InputError("duplicate time for one agent", row=row, field="t_s")
    for a in agents:
        if a.category not in ENTITY_MODELS:
            raise InputError(
                f"agent {a.agent_id}: unknown category {a.category!r}; expected one of "
                f"{', '.join(ENTITY_MODELS)}",
                field="category",
            )
        if not (a.length_m > 0 and a.width_m > 0):
            raise InputError(f"agent {a.agent_id}: dimensions must be > 0 m", field="length_m")
    if df.empty:
        raise InputError("trajectories are empty", field="t_s")
    return df.sort_values(["agent_id", "t_s"], kind="stable").reset_index(drop=True)


def _speeds(track: pd.DataFrame) -> np.ndarray:
    if "speed_mps" in track:
        return track["speed_mps"].to_numpy(dtype=float)
    t = track["t_s"].to_numpy(dtype=float)
    if t.size < 2:
        return np.zeros(t.size)
    xy = track[["x_m", "y_m"]].to_numpy(dtype=float)
    v = np.hypot(*np.gradient(xy, t, axis=0).T)
    return v


def _r(v: float, nd: int) -> float:
    out = round(float(v), nd)
    return 0.0 if out == 0 else out


def _world_position(xosc, x_m: float, y_m: float, yaw_rad: float):
    """WorldPosition (x, y [m], z = 0, h = yaw wrapped to [-pi, pi]) rounded as documented."""
    h = math.remainder(float(yaw_rad), 2 * math.pi)
    return xosc.WorldPosition(_r(x_m, 4), _r(y_m, 4), 0.0, _r(h, 5), 0.0, 0.0)


def export_openscenario(
    trajectories: pd.DataFrame,
    agents: Sequence[AgentInfo],
    out_dir: str | Path,
    *,
    xodr: str | Path | None = None,
    osc_version: str = DEFAULT_OSC_VERSION,
    ego_controller: EgoController = "trajectory",
    name: str = "vei_scenario",
    description: str = "vei scenario",
    author: str = "vei",
    creation_date: datetime | None = None,
    vertex_rate_hz: float | None = 10.0,
    max_position_error_m: float = 0.05,
    max_yaw_error_rad: float = 0.05,
    blueprints: Mapping[str, str] | None = None,
) -> Path:
    """Write ``out_dir/<name>.xosc`` (and a copy of the map) from a run's trajectories.

    Args:
        trajectories: long table, one row per agent per sample; columns t_s [s] (>= 0,
            simulation time), agent_id, category, x_m, y_m [m] (plane, box centre),
            yaw_rad [rad, CCW from +x], optional speed_mps [m/s] (else from positions).
            A run's time series (vei.types.TIMESERIES_COLUMNS) works once filtered to
            one config/variant and to ``active`` rows.
        agents: AgentInfo of every agent in ``trajectories`` (footprints, categories).
        out_dir: output folder (created).
        xodr: the OpenDRIVE map; copied into ``out_dir`` and referenced by file name.
            None: an empty LogicFile path (scenario without a road network).
        osc_version: '1.0' | '1.1' | '1.2' | '1.3'.
        ego_controller: 'trajectory' (the ego follows its timed trajectory) or
            'simulator' (the ego gets only its initial position and speed: the simulator
            or the system under test drives it).
        name: file stem of the .xosc.
        description, author: FileHeader fields.
        creation_date: FileHeader date; None: 1970-01-01T00:00:00 (deterministic files).
        vertex_rate_hz, max_position_error_m, max_yaw_error_rad: decimation (module doc).
        blueprints: CARLA blueprint per category, written as the entity's name
            (defaults: vei.sim.backends.carla_frame.DEFAULT_BLUEPRINTS).

    Returns:
        Path of the written .xosc.
    """
    from vei.sim.backends.carla_frame import DEFAULT_BLUEPRINTS

    xosc = _xosc()
    minor = _minor(osc_version)
    if ego_controller not in ("trajectory", "simulator"):
        raise ConfigError(
            f"ego_controller must be 'trajectory' or 'simulator'; got {ego_controller!r}"
        )
    if not name or any(c in name for c in "/\\"):
        raise ConfigError(f"name must be a plain file stem; got {name!r}")
    df = _validate(trajectories, agents)
    bps = dict(DEFAULT_BLUEPRINTS)
    bps.update(blueprints or {})
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    map_name = ""
    if xodr is not None:
        xodr = Path(xodr)
        if not xodr.is_file():
            raise InputError("OpenDRIVE map not found", path=xodr)
        map_name = xodr.name
        target = out_dir / map_name
        if target.resolve() != xodr.resolve():
            with atomic_path(target) as tmp:
                shutil.copyfile(xodr, tmp)

    present = [a for a in agents if a.agent_id in set(df["agent_id"])]
    t_end = float(df["t_s"].max())
    # scenariogeneration's version is class-level state: set it, build, restore.
    base = xosc.VersionBase()
    saved = (xosc.VersionBase.version_major, xosc.VersionBase.version_minor)
    base.setVersion(major=1, minor=minor)
    try:
        scenario = _build(
            xosc,
            df,
            present,
            minor,
            ego_controller,
            bps,
            map_name,
            t_end,
            name=name,
            description=description,
            author=author,
            creation_date=creation_date or datetime(1970, 1, 1),
            decimation=(vertex_rate_hz, max_position_error_m, max_yaw_error_rad),
        )
        from scenariogeneration.helpers import prettify

        xml = prettify(scenario.get_element(), encoding="utf-8")
    finally:
        xosc.VersionBase.version_major, xosc.VersionBase.version_minor = saved
    path = out_dir / f"{name}.xosc"
    with atomic_path(path) as tmp:
        tmp.write_bytes(xml.encode("utf-8") if isinstance(xml, str) else xml)
    return path


def _entity(xosc, agent: AgentInfo, minor: int, blueprint: str):
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
        # Axles relative to the reference point (box centre): wheelbase 0.6 * length,
        # wheel diameter and track from the footprint (informative only).
        half_wb = 0.3 * agent.length_m
        wheel = 0.65 if m.osc_category == "car" else 0.5
        front = xosc.Axle(0.52, wheel, agent.width_m * 0.85, half_wb, wheel / 2)
        rear = xosc.Axle(0.0, wheel, agent.width_m * 0.85, -half_wb, wheel / 2)
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
    if agent.source_track_id is not None:
        ent.add_property(PROP_SOURCE_TRACK, str(agent.source_track_id))
    return ent


def _build(
    xosc,
    df,
    agents,
    minor,
    ego_controller,
    bps,
    map_name,
    t_end,
    *,
    name,
    description,
    author,
    creation_date,
    decimation,
):
    rate, tol_p, tol_a = decimation
    entities = xosc.Entities()
    init = xosc.Init()
    step = xosc.TransitionDynamics(xosc.DynamicsShapes.step, xosc.DynamicsDimension.time, 0.0)
    groups = []
    for agent in agents:
        entities.add_scenario_object(
            agent.agent_id, _entity(xosc, agent, minor, bps[agent.category])
        )
        track = df[df["agent_id"] == agent.agent_id]
        t = track["t_s"].to_numpy(dtype=float)
        xy = track[["x_m", "y_m"]].to_numpy(dtype=float)
        yaw = track["yaw_rad"].to_numpy(dtype=float)
        v = _speeds(track)

        def pos(i: int, xy=xy, yaw=yaw) -> object:
            return _world_position(xosc, xy[i, 0], xy[i, 1], yaw[i])

        init.add_init_action(agent.agent_id, xosc.TeleportAction(pos(0)))
        init.add_init_action(agent.agent_id, xosc.AbsoluteSpeedAction(_r(max(v[0], 0.0), 4), step))
        if t.size < 2 or (agent.category == EGO_CATEGORY and ego_controller == "simulator"):
            continue
        idx = decimate_indices(
            t, xy, yaw, vertex_rate_hz=rate, max_position_error_m=tol_p, max_yaw_error_rad=tol_a
        )
        poly = xosc.Polyline([_r(t[i], 4) for i in idx], [pos(int(i)) for i in idx])
        traj = xosc.Trajectory(f"{agent.agent_id}_trajectory", False)
        traj.add_shape(poly)
        action = xosc.FollowTrajectoryAction(
            traj,
            xosc.FollowingMode.position,
            xosc.ReferenceContext.absolute,
            1.0,
            0.0,
        )
        event = xosc.Event(
            f"{agent.agent_id}_event",
            xosc.Priority.override if minor >= 2 else xosc.Priority.overwrite,
        )
        event.add_action(f"{agent.agent_id}_follow_trajectory", action)
        event.add_trigger(
            xosc.ValueTrigger(
                f"{agent.agent_id}_start",
                0.0,
                xosc.ConditionEdge.rising,
                xosc.SimulationTimeCondition(_r(t[0], 4), xosc.Rule.greaterThan),
            )
        )
        man = xosc.Maneuver(f"{agent.agent_id}_maneuver")
        man.add_event(event)
        grp = xosc.ManeuverGroup(f"{agent.agent_id}_maneuver_group")
        grp.add_actor(agent.agent_id)
        grp.add_maneuver(man)
        groups.append(grp)

    stop = xosc.ValueTrigger(
        "vei_stop",
        0.0,
        xosc.ConditionEdge.rising,
        xosc.SimulationTimeCondition(_r(t_end, 4), xosc.Rule.greaterThan),
        triggeringpoint="stop",
    )
    act = xosc.Act(
        "vei_act",
        xosc.ValueTrigger(
            "vei_act_start",
            0.0,
            xosc.ConditionEdge.none,
            xosc.SimulationTimeCondition(0.0, xosc.Rule.greaterThan),
        ),
    )
    for g in groups:
        act.add_maneuver_group(g)
    story = xosc.Story("vei_story")
    story.add_act(act)
    sb = xosc.StoryBoard(init, stop)
    sb.add_story(story)
    road = xosc.RoadNetwork(roadfile=map_name)
    return xosc.Scenario(
        description if description else name,
        author,
        xosc.ParameterDeclarations(),
        entities,
        sb,
        road,
        xosc.Catalog(),
        osc_minor_version=minor,
        creation_date=creation_date,
    )


def read_openscenario_trajectories(path: str | Path) -> pd.DataFrame:
    """Read back the timed polyline trajectories and initial poses of an exported .xosc.

    Parses with defusedxml (no entity expansion). Every agent contributes its Init
    TeleportAction pose (t_s = NaN when the agent also has a trajectory, else 0) and the
    vertices of its FollowTrajectoryAction.

    Returns:
        DataFrame with columns agent_id, category (the entity's ``vei:category`` property,
        '' if absent), t_s [s] (vertex time; NaN for an Init pose), x_m, y_m, yaw_rad,
        kind ('init' | 'vertex'); sorted by agent_id, kind, t_s.
    """
    from defusedxml import ElementTree as SafeET

    path = Path(path)
    try:
        root = SafeET.parse(path).getroot()
    except Exception as exc:  # ParseError, DefusedXmlException, OSError
        raise InputError(f"not a readable OpenSCENARIO file: {exc}", path=path) from exc
    cats: dict[str, str] = {}
    for obj in root.iter("ScenarioObject"):
        cat = ""
        for prop in obj.iter("Property"):
            if prop.get("name") == PROP_CATEGORY:
                cat = prop.get("value", "")
        cats[obj.get("name", "")] = cat
    rows: list[tuple] = []

    def wp(el) -> tuple[float, float, float]:
        w = el.find("WorldPosition")
        if w is None:
            raise InputError("only WorldPosition positions are read back", path=path)
        return float(w.get("x")), float(w.get("y")), float(w.get("h", 0.0))

    init = root.find("Storyboard/Init")
    if init is not None:
        for priv in init.iter("Private"):
            ent = priv.get("entityRef", "")
            for tp in priv.iter("TeleportAction"):
                x, y, h = wp(tp.find("Position"))
                rows.append((ent, cats.get(ent, ""), math.nan, x, y, h, "init"))
    for grp in root.iter("ManeuverGroup"):
        actors = [e.get("entityRef", "") for e in grp.iter("EntityRef")]
        for fta in grp.iter("FollowTrajectoryAction"):
            for ent in actors:
                for vert in fta.iter("Vertex"):
                    x, y, h = wp(vert.find("Position"))
                    rows.append(
                        (ent, cats.get(ent, ""), float(vert.get("time")), x, y, h, "vertex")
                    )
    out = pd.DataFrame(
        rows, columns=["agent_id", "category", "t_s", "x_m", "y_m", "yaw_rad", "kind"]
    )
    return out.sort_values(["agent_id", "kind", "t_s"], kind="stable").reset_index(drop=True)


def timeseries_to_trajectories(
    timeseries: pd.DataFrame, *, config: str | None = None, variant: int = 0
) -> pd.DataFrame:
    """Rows of one run of a time series (TIMESERIES_COLUMNS) ready for the export.

    Keeps the rows of ``config`` (the only config if None) and ``variant`` where the agent
    is ``active``; returns columns t_s, agent_id, category, x_m, y_m, yaw_rad, speed_mps.
    """
    df = timeseries
    if "config" in df:
        names = list(dict.fromkeys(df["config"].astype(str)))
        if config is None:
            if len(names) != 1:
                raise InputError(
                    f"time series holds several configs ({', '.join(names)}): choose one",
                    field="config",
                )
            config = names[0]
        elif config not in names:
            raise InputError(
                f"config {config!r} not in the time series ({', '.join(names)})", field="config"
            )
        df = df[df["config"].astype(str) == config]
    if "variant" in df:
        df = df[df["variant"] == variant]
    if "active" in df:
        df = df[df["active"].astype(bool)]
    cols = ["t_s", "agent_id", "category", "x_m", "y_m", "yaw_rad", "speed_mps"]
    return df[[c for c in cols if c in df]].reset_index(drop=True)
