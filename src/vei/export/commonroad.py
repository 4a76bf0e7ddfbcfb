"""CommonRoad scenarios out of vei: ``vei export commonroad SCENARIO --config ... --out DIR``.

:func:`export_commonroad` writes one run (the recorded trajectories, or a configuration's
run handed in by the CLI, which runs it: export knows no engine) as a CommonRoad 2020a
scenario with commonroad-io's XML writer:

- the lanelet network converted from the scenario's own OpenDRIVE map
  (:mod:`vei.export.commonroad_map`); a scenario without a map is an error (a CommonRoad
  scenario is defined on its lanelets);
- every road user but the ego as a DynamicObstacle: its box (Rectangle length x width
  [m]), its state at its first step as the initial state and the rest as a
  TrajectoryPrediction (position [m], orientation [rad], velocity [m/s] at time steps
  of the run's step dt); it exists in the scenario only during its own span. E-scooters
  and cyclists are BICYCLE (CommonRoad has no e-scooter type; the obstacle id and
  ``<id>_obstacles.csv`` name it), pedestrians PEDESTRIAN, vehicles CAR;
- a planning problem for the ego: its state at t = 0 and a goal region around where the
  run's ego ends (a circle of GOAL_RADIUS_M, within the run's span);
- ``<name>_ego.csv``: the ego's trajectory of the run (time_step, t_s, x_m, y_m, yaw_rad,
  speed_mps), the solution the simulated ego drove, for CommonRoad's collision and
  drivability checks (tests/export/test_commonroad.py runs CommonRoad's collision
  checker on it);
- ``<name>_obstacles.csv``: CommonRoad obstacle id -> vei agent id and category.

commonroad-io is imported lazily (extra ``commonroad``; see docs/commonroad.md). vei uses
its XML reader / writer modules directly: ``commonroad.common.file_reader`` also imports
the protobuf format, whose generated code needs protobuf 3.20.x, which Ray's own pin
(>= 3.20.3, vei[distributed]) excludes.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.errors import DependencyError, InputError
from vei.io.atomic import atomic_path
from vei.types import EGO_CATEGORY, AgentInfo

#: Decimals of every coordinate written (1 um): values are rounded before writing, so
#: the file reads back equal.
DECIMALS = 6
#: Radius of the ego's goal region around its final position [m].
GOAL_RADIUS_M = 5.0
#: First CommonRoad id of the obstacles, of the lanelets, and the planning problem's id.
FIRST_OBSTACLE_ID = 1
FIRST_LANELET_ID = 10_000
PLANNING_PROBLEM_ID = 100_000
#: vei category -> CommonRoad ObstacleType name.
OBSTACLE_TYPES = {"escooter": "BICYCLE", "cyclist": "BICYCLE", "pedestrian": "PEDESTRIAN",
                  "vehicle": "CAR"}  # fmt: skip


def _require() -> None:
    try:
        import commonroad  # noqa: F401
    except ImportError as exc:
        raise DependencyError(
            "the CommonRoad export needs commonroad-io (pip install 'vei[commonroad]' and "
            "commonroad-io; see docs/commonroad.md)"
        ) from exc


def _steps(t_s: np.ndarray, dt_s: float, where: str) -> np.ndarray:
    k = np.rint(t_s / dt_s)
    if np.any(np.abs(k * dt_s - t_s) > 1e-6 * max(1.0, dt_s)):
        raise InputError(f"{where}: times are not on the {dt_s:g} s grid", field="t_s")
    return k.astype(np.int64)


def _state(cls: Any, row: Any, k: int) -> Any:
    from commonroad.common.util import make_valid_orientation

    r = DECIMALS
    return cls(
        position=np.round(np.array([row.x_m, row.y_m], dtype=np.float64), r),
        orientation=round(float(make_valid_orientation(float(row.yaw_rad))), r),
        velocity=round(float(row.speed_mps if np.isfinite(row.speed_mps) else 0.0), r),
        time_step=int(k),
    )


def build_scenario(
    traj: pd.DataFrame,
    agents: list[AgentInfo],
    xodr: str | Path,
    *,
    dt_s: float,
    name: str,
    description: str = "",
    projection: str | None = None,
    tags: tuple[str, ...] = ("URBAN",),
) -> tuple[Any, Any, pd.DataFrame, pd.DataFrame]:
    """The CommonRoad Scenario and PlanningProblemSet of one run (module docstring).

    Args:
        traj: one run's rows: t_s [s] (on the dt_s grid from 0), agent_id, category, x_m,
            y_m [m], yaw_rad [rad], speed_mps [m/s]; an agent's rows are its span.
        agents: the scenario's agents (footprints). xodr: its OpenDRIVE map.
        dt_s: the run's step [s]. name: the scenario's map name (CommonRoad id part).
        description: the scenario's source text. projection: the plane's PROJ string
            (the scenario's; written as the Location's geo reference, with its origin as
            the GPS position). tags: CommonRoad Tag names.
    Returns:
        (Scenario, PlanningProblemSet, ego trajectory table, obstacle id table).
    """
    _require()
    from commonroad.common.util import Interval
    from commonroad.geometry.shape import Circle, Rectangle
    from commonroad.planning.goal import GoalRegion
    from commonroad.planning.planning_problem import PlanningProblem, PlanningProblemSet
    from commonroad.prediction.prediction import TrajectoryPrediction
    from commonroad.scenario.obstacle import DynamicObstacle, ObstacleType
    from commonroad.scenario.scenario import GeoTransformation, Location, Scenario, ScenarioID, Tag
    from commonroad.scenario.state import CustomState, InitialState
    from commonroad.scenario.trajectory import Trajectory

    from vei.export.commonroad_map import load_lanelet_network

    if not dt_s > 0:
        raise InputError(f"dt_s must be > 0, got {dt_s}", field="dt_s")
    dims = {a.agent_id: a for a in agents}
    ego_rows = traj[traj["category"] == EGO_CATEGORY].sort_values("t_s")
    if ego_rows.empty:
        raise InputError("the run has no ego rows", field="category")
    sid = ScenarioID(country_id="ZAM", map_name=_cr_name(name), map_id=1)
    location = Location()  # the writer's default when unknown (read back equal)
    if projection:
        from vei.geo import LocalFrame

        frame = LocalFrame.from_proj_string(projection)
        location = Location(
            gps_latitude=frame.origin_lat_deg, gps_longitude=frame.origin_lon_deg,
            geo_transformation=GeoTransformation(geo_reference=projection),
        )  # fmt: skip
    scenario = Scenario(
        dt=dt_s, scenario_id=sid, author="vei", affiliation="vei", source=description or "vei",
        tags={Tag[t] for t in tags}, location=location,
    )  # fmt: skip
    network, _ = load_lanelet_network(xodr, first_id=FIRST_LANELET_ID, decimals=DECIMALS)
    scenario.add_objects(network)
    rows = []
    oid = FIRST_OBSTACLE_ID
    for aid, g in traj[traj["category"] != EGO_CATEGORY].groupby("agent_id", sort=True):
        g = g.sort_values("t_s")
        info = dims.get(str(aid))
        if info is None:
            raise InputError(f"agent {aid!r} has rows but no footprint", field="agent_id")
        ks = _steps(g["t_s"].to_numpy(np.float64), dt_s, f"agent {aid}")
        states = [_state(CustomState, r, k) for r, k in zip(g.itertuples(), ks, strict=True)]
        init = _state(InitialState, next(g.itertuples()), int(ks[0]))
        init.fill_with_defaults()
        shape = Rectangle(round(info.length_m, DECIMALS), round(info.width_m, DECIMALS))
        pred = None
        if len(states) > 1:
            pred = TrajectoryPrediction(Trajectory(int(ks[1]), states[1:]), shape)
        cat = str(g["category"].iloc[0])
        otype = ObstacleType[OBSTACLE_TYPES.get(cat, "UNKNOWN")]
        # signal_series [] (not None): what the XML reader gives back for "no signals"
        scenario.add_objects(DynamicObstacle(oid, otype, shape, init, pred, signal_series=[]))
        rows.append((oid, str(aid), cat, int(ks[0]), int(ks[-1])))
        oid += 1
    ek = _steps(ego_rows["t_s"].to_numpy(np.float64), dt_s, "ego")
    first = next(ego_rows.itertuples())
    init = _state(InitialState, first, int(ek[0]))
    init.fill_with_defaults()
    last = ego_rows.iloc[-1]
    goal_state = CustomState(
        position=Circle(GOAL_RADIUS_M, np.round(np.array([last["x_m"], last["y_m"]]), DECIMALS)),
        time_step=Interval(int(ek[0]), int(ek[-1])),
    )
    problem = PlanningProblem(PLANNING_PROBLEM_ID, init, GoalRegion([goal_state]))
    ego = pd.DataFrame(
        {
            "time_step": ek,
            "t_s": ego_rows["t_s"].to_numpy(np.float64),
            "x_m": ego_rows["x_m"].to_numpy(np.float64),
            "y_m": ego_rows["y_m"].to_numpy(np.float64),
            "yaw_rad": ego_rows["yaw_rad"].to_numpy(np.float64),
            "speed_mps": ego_rows["speed_mps"].to_numpy(np.float64),
        }
    )
    ids = pd.DataFrame(
        rows, columns=["obstacle_id", "agent_id", "category", "first_step", "last_step"]
    )
    return scenario, PlanningProblemSet([problem]), ego, ids


def _cr_name(name: str) -> str:
    """A CommonRoad map name: letters and digits only (the id's parts are '_'-separated)."""
    out = "".join(ch for ch in name.title() if ch.isalnum())
    return out[:60] or "Vei"


def write_commonroad(scenario: Any, problems: Any, path: str | Path) -> Path:
    """Write scenario + planning problems as CommonRoad XML (atomically); returns the path."""
    _require()
    from commonroad.common.writer.file_writer_xml import XMLFileWriter

    try:  # commonroad-io >= 2023: OverwriteExistingFile lives in file_writer_interface
        from commonroad.common.writer.file_writer_interface import OverwriteExistingFile
    except ImportError:  # pragma: no cover - older layout
        from commonroad.common.file_writer import OverwriteExistingFile  # type: ignore
    p = Path(path)
    import contextlib
    import io

    writer = XMLFileWriter(scenario, problems, decimal_precision=DECIMALS)
    with atomic_path(p) as tmp, contextlib.redirect_stdout(io.StringIO()):  # its chatter
        writer.write_to_file(str(tmp), OverwriteExistingFile.ALWAYS)
    return p


def read_commonroad(path: str | Path) -> tuple[Any, Any]:
    """(Scenario, PlanningProblemSet) of a CommonRoad XML file (commonroad-io's XML reader)."""
    _require()
    from commonroad.common.reader.file_reader_xml import XMLFileReader

    p = Path(path)
    if not p.is_file():
        raise InputError("CommonRoad file not found", path=p)
    return XMLFileReader(str(p)).open()


def export_commonroad(
    traj: pd.DataFrame,
    agents: list[AgentInfo],
    out_dir: str | Path,
    *,
    xodr: str | Path | None,
    dt_s: float,
    name: str,
    description: str = "",
    projection: str | None = None,
    tags: tuple[str, ...] = ("URBAN",),
) -> Path:
    """Write ``<name>.xml``, ``<name>_ego.csv`` and ``<name>_obstacles.csv`` into out_dir.

    Args: as :func:`build_scenario`; ``xodr`` None (a scenario without a map) is an
    InputError naming the way out (``vei reconstruct --map``).
    Returns:
        The .xml path.
    """
    if xodr is None or not Path(xodr).is_file():
        raise InputError(
            "the scenario has no road map (map.xodr): a CommonRoad scenario needs its lanelet "
            "network; reconstruct with 'vei reconstruct --map'",
            path=xodr,
            field="maps.opendrive",
        )
    scenario, problems, ego, ids = build_scenario(
        traj, agents, xodr, dt_s=dt_s, name=name, description=description,
        projection=projection, tags=tags,
    )  # fmt: skip
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    path = write_commonroad(scenario, problems, out / f"{name}.xml")
    with atomic_path(out / f"{name}_ego.csv") as tmp:
        ego.to_csv(tmp, index=False, float_format="%.9g")
    with atomic_path(out / f"{name}_obstacles.csv") as tmp:
        ids.to_csv(tmp, index=False)
    return path


def ego_trajectory(ego: pd.DataFrame) -> Any:
    """The ego table (``<name>_ego.csv``) as a CommonRoad Trajectory (from its first step)."""
    _require()
    from commonroad.scenario.state import CustomState
    from commonroad.scenario.trajectory import Trajectory

    states = [
        CustomState(
            position=np.array([r.x_m, r.y_m]),
            orientation=float(r.yaw_rad),
            velocity=float(r.speed_mps),
            time_step=int(r.time_step),
        )  # fmt: skip
        for r in ego.itertuples()
    ]
    return Trajectory(int(ego["time_step"].iloc[0]), states)


def first_collision_step(
    scenario: Any, ego: pd.DataFrame, length_m: float, width_m: float
) -> int | None:
    """The first time step at which CommonRoad's collision checker (commonroad-drivability-
    checker) finds the ego box (length x width [m], at the ego table's states) colliding
    with an obstacle of ``scenario``; None without contact."""
    try:
        from commonroad_dc.collision.collision_detection.pycrcc_collision_dispatch import (
            create_collision_checker,
            create_collision_object,
        )
    except ImportError as exc:
        raise DependencyError(
            "the collision check needs commonroad-drivability-checker (docs/commonroad.md)"
        ) from exc
    from commonroad.geometry.shape import Rectangle
    from commonroad.prediction.prediction import TrajectoryPrediction

    checker = create_collision_checker(scenario)
    pred = TrajectoryPrediction(ego_trajectory(ego), Rectangle(length_m, width_m))
    obj = create_collision_object(pred)  # a time-variant object: one box per time step
    for k in range(obj.time_start_idx(), obj.time_end_idx() + 1):
        # the obstacles present at step k against the ego's box at step k
        if checker.time_slice(k).collide(obj.obstacle_at_time(k)):
            return k
    return None


__all__ = [
    "DECIMALS",
    "GOAL_RADIUS_M",
    "OBSTACLE_TYPES",
    "build_scenario",
    "ego_trajectory",
    "export_commonroad",
    "first_collision_step",
    "read_commonroad",
    "write_commonroad",
]
