"""Engine inputs and state: per-scenario tables, per-variant parameter arrays, the state.

- :class:`ScenarioArrays`: everything the engine needs from a :class:`vei.types.Scenario`,
  precomputed once (ego path arc-length table, recorded tracks as uniform time tables,
  replayed other road users at every engine step).
- :class:`VariantParams` (vei.sim.params): every per-variant parameter as an array ``[B]``
  (a sweep varies any of them without Python loops). :class:`TimeTable` (vei.sim.tables).
- :class:`SimState`: the engine state at one step, arrays ``[B]``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from vei.config import SimConfig
from vei.continuation import recorded_rows, recorded_span_s, with_continuations
from vei.continuation.where import Route, route_of
from vei.errors import InputError
from vei.models.drivable_path import (
    PATH_SPEED_MARGIN,
    EgoPathInfo,
    build_ego_path,
    recorded_arc_length,
)
from vei.models.ego import PathTable, median_moving_speed_mps
from vei.policy.v2x.links import scene_buildings
from vei.sim.decisions import Conflicts, find_conflicts
from vei.sim.params import (
    EGO_CAP,
    EGO_MODE_CODES,
    EGO_PID,
    EGO_POLICY,
    EGO_REPLAY_SPEED,
    VariantParams,
)
from vei.sim.pedestrians import Pedestrians, prepare_pedestrians
from vei.sim.riders import (
    RIDER_PATH_STEP_M,
    ExtraRiders,
    moving_speeds,
    prepare_extra_riders,
    rider_track,
    select_extra_riders,
    sfm_entry_s,
)
from vei.sim.tables import TimeTable, _uniform_track
from vei.sim.traffic import Traffic, prepare_traffic
from vei.types import EGO_ID, Scenario

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


# --------------------------------------------------------------------------------------
# Per-scenario arrays
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class ScenarioArrays:
    """Per-scenario inputs of the engine, precomputed once (see :func:`prepare_scenario`).

    Attributes:
        scenario_id: the scenario's id.
        dt_s: engine step [s]. t_s: [T] step times k * dt_s [s].
        ego_path: the ego's recorded path made drivable (arc-length table; s = 0 at its
            first sample; vei.models.drivable_path: standstill jitter collapsed, smoothing
            spline with curvature <= sim.ego_max_lat_accel_mps2 / v^2, straight
            extensions along the end tangents, the backwards one being the run-up).
        ego_track: the ego's recording on a uniform time grid, columns s_m (arc length
            along ego_path of the recorded positions, never decreasing), speed_mps.
        ego_length_m, ego_width_m: ego footprint [m].
        ego_speed0_mps: recorded ego speed at t = 0 [m/s].
        conflict_s_m: arc length [m] along the ego's recorded path of its point nearest to
            the rider's recorded path (where the paths meet, if they do).
        ego_median_moving_speed_mps: median recorded speed while moving (> threshold) [m/s]
            (NaN if the ego never moves).
        rider_id, rider_category: the primary threat (the simulated rider).
        rider_track: its recording on a uniform time grid (recording time), columns x_m,
            y_m, yaw_rad (unwrapped), speed_mps, vx_mps, vy_mps (the recorded speed along
            the recorded heading, like every replayed road user's; finite differences of
            the positions where no speed is recorded), arc_m (arc length along rider_path).
        rider_path: the rider's own recorded path (arc-length table; SFM goals).
        rider_length_m, rider_width_m: rider footprint [m].
        other_ids, other_categories: the replayed other road users (n_o of them).
        other_length_m, other_width_m: [n_o] footprints [m].
        other_x_m, other_y_m, other_yaw_rad, other_speed_mps: [T, n_o] at the engine steps
            (last known values where inactive), other_active: [T, n_o] bool.
        ego_path_info: how ego_path was built (curvature bound, deviation, headings).
        riders: the extra social-force riders (vei.sim.riders; none unless
            ``sim.sfm_riders`` is not 'primary'); they are not among the replayed others.
        rider_recorded_span_s: (first, last) recording time of the rider's *recorded*
            samples [s]: rider_track also holds its run-in before and its run-out after
            (vei.continuation); (-inf, inf) = all of it is recorded.
        rider_sfm_entry_s: recording time [s] from which a social-force rider is driven
            by its forces (vei.sim.riders.sfm_entry_s: the track's start, or its first
            recorded sample after a standing run-in, where it waits replayed); -inf =
            whenever it enters.
        conflicts: where the rider's path crosses the ego's (vei.sim.decisions: the
            conflict zones of the rider's yield / go decision).
        rider_moving_speeds_mps: the rider's recorded speeds outside its waits
            (vei.sim.riders.moving_speeds: the calibrated rider's cruise speed), None
            where it never waits (every recorded speed counts).
        traffic: the reacting cars among the replayed others (vei.sim.traffic: the
            vehicles on or across the ego's path; they react where ``cars_react``).
        peds: the recorded pedestrians (vei.sim.pedestrians; social-force driven where
            ``peds_sfm``).
        routes: agent id -> its labelled continued track (vei.continuation.where.Route)
            for every road user but the ego: where a run's contacts happened (on the
            recorded behaviour, a run-in or a run-out: SimResult.where).
        buildings: the building outlines of the scenario's OpenStreetMap source near the
            scene (vei.policy.v2x.links.Buildings; None without): V2X links through one are
            NLOS.
    """

    scenario_id: str
    dt_s: float
    t_s: FloatArray
    ego_path: PathTable
    ego_track: TimeTable
    ego_length_m: float
    ego_width_m: float
    ego_speed0_mps: float
    ego_median_moving_speed_mps: float
    conflict_s_m: float
    rider_id: str
    rider_category: str
    rider_track: TimeTable
    rider_path: PathTable
    rider_length_m: float
    rider_width_m: float
    other_ids: tuple[str, ...]
    other_categories: tuple[str, ...]
    other_length_m: FloatArray
    other_width_m: FloatArray
    other_x_m: FloatArray
    other_y_m: FloatArray
    other_yaw_rad: FloatArray
    other_speed_mps: FloatArray
    other_active: BoolArray
    ego_path_info: EgoPathInfo | None = None
    riders: ExtraRiders = field(default_factory=ExtraRiders)
    rider_recorded_span_s: tuple[float, float] = (-math.inf, math.inf)
    rider_sfm_entry_s: float = -math.inf
    conflicts: Conflicts = field(default_factory=Conflicts)
    rider_moving_speeds_mps: FloatArray | None = None
    traffic: Traffic = field(default_factory=Traffic)
    peds: Pedestrians = field(default_factory=Pedestrians)
    routes: Mapping[str, Route] = field(default_factory=dict)
    buildings: Any = None

    @property
    def n_steps(self) -> int:
        """Number of recorded steps T (including t = 0)."""
        return int(self.t_s.shape[0])


def prepare_scenario(
    scenario: Scenario,
    sim: SimConfig | None = None,
    *,
    rider_id: str | None = None,
    moving_threshold_mps: float = 0.5,
) -> ScenarioArrays:
    """Precompute the engine's per-scenario arrays.

    The ego is agent 'ego'; the simulated rider is ``rider_id`` or the scenario's
    primary threat; every other agent is replayed kinematically (recording time, no
    shift). The simulated span is [0, sim.duration_s] or [0, last recorded time].
    Every road user but the ego arrives and leaves along its continuation
    (:func:`vei.continuation.with_continuations` with ``sim.continuation``, unless the
    scenario is continued already with those settings): the rider's track and path and
    the replayed others include their run-ins and run-outs.

    Args:
        scenario: the reconstructed scenario (trajectories at any uniform rate).
        sim: engine settings (step, duration, footprints).
        rider_id: agent to simulate as the rider (default: scenario.primary_threat).
        moving_threshold_mps: threshold of the median moving speed.
    Returns:
        The ScenarioArrays. Raises InputError if the ego or the rider is missing.
    """
    sim = sim or SimConfig()
    where = f"scenario {scenario.id}"
    scenario = with_continuations(scenario, sim.continuation)
    traj = scenario.trajectories
    rid = rider_id or scenario.primary_threat
    if rid is None:
        raise InputError(
            "scenario has no primary threat: nothing to simulate",
            path=where,
            field="primary_threat",
        )
    ids = set(traj["agent_id"].unique())
    if EGO_ID not in ids:
        raise InputError("scenario trajectories have no agent 'ego'", path=where, field="agent_id")
    if rid not in ids:
        raise InputError(f"rider {rid!r} has no trajectory", path=where, field="agent_id")

    t_last = float(recorded_rows(traj)["t_s"].max())
    duration = sim.duration_s if sim.duration_s is not None else t_last
    n = int(math.floor(duration / sim.dt_s + 1e-9)) + 1
    t_s = np.arange(n) * sim.dt_s

    # Ego (never continued: it has its own run-up).
    ego = scenario.track(EGO_ID)
    ex = ego["x_m"].to_numpy(dtype=np.float64)
    ey = ego["y_m"].to_numpy(dtype=np.float64)
    eyaw = ego["yaw_rad"].to_numpy(dtype=np.float64)
    espeed = ego["speed_mps"].to_numpy(dtype=np.float64)
    if not np.all(np.isfinite(espeed)):
        tt = ego["t_s"].to_numpy(dtype=np.float64)
        raw_arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(ex), np.diff(ey)))])
        espeed = np.gradient(raw_arc, tt) if tt.size > 1 else np.zeros_like(raw_arc)
    try:
        med = median_moving_speed_mps(espeed, moving_threshold_mps)
    except InputError:
        med = float("nan")
    path_speed = sim.ego_path_speed_mps or PATH_SPEED_MARGIN * (med if math.isfinite(med) else 1.0)
    ego_path, ego_path_info = build_ego_path(
        ex,
        ey,
        yaw_hint_rad=float(eyaw[0]),
        path_speed_mps=path_speed,
        max_lat_accel_mps2=sim.ego_max_lat_accel_mps2,
        where=f"{where}: ego",
    )
    s_rec = recorded_arc_length(ego_path, ex, ey)
    ego_df = ego.assign(s_m=s_rec, speed_mps=espeed)
    t0, dte, edata = _uniform_track(ego_df, ("s_m", "speed_mps"), f"{where}: ego")
    ego_track = TimeTable(t0, dte, edata, ("s_m", "speed_mps"))
    ego_info = scenario.agent(EGO_ID)

    # Rider.
    rinfo = scenario.agent(rid)
    rider = scenario.track(rid)
    rec_span = recorded_span_s(scenario, rid)
    rider_rec = recorded_rows(rider)  # the conflict point is the recorded encounter's
    rx = rider_rec["x_m"].to_numpy(dtype=np.float64)
    ry = rider_rec["y_m"].to_numpy(dtype=np.float64)
    several = sim.sfm_riders != "primary"
    r_track, rider_path = rider_track(scenario, rid, where, RIDER_PATH_STEP_M if several else None)
    extra_ids = select_extra_riders(scenario, rid, sim.sfm_riders, where)

    # Others, replayed on the engine grid.
    skip = {EGO_ID, rid, *extra_ids}
    others = [a for a in scenario.agents if a.agent_id not in skip and a.agent_id in ids]
    no = len(others)
    ox = np.zeros((n, no))
    oy = np.zeros((n, no))
    oyaw = np.zeros((n, no))
    osp = np.zeros((n, no))
    oact = np.zeros((n, no), dtype=bool)
    for j, a in enumerate(others):
        tr = scenario.track(a.agent_id)
        tt = tr["t_s"].to_numpy(dtype=np.float64)
        oact[:, j] = (t_s >= tt[0] - 1e-9) & (t_s <= tt[-1] + 1e-9)
        ox[:, j] = np.interp(t_s, tt, tr["x_m"].to_numpy(dtype=np.float64))
        oy[:, j] = np.interp(t_s, tt, tr["y_m"].to_numpy(dtype=np.float64))
        oyaw[:, j] = np.interp(t_s, tt, np.unwrap(tr["yaw_rad"].to_numpy(dtype=np.float64)))
        sp = tr["speed_mps"].to_numpy(dtype=np.float64)
        osp[:, j] = np.where(oact[:, j], np.interp(t_s, tt, np.nan_to_num(sp)), 0.0)

    rider_len = float(sim.rider_length_m or rinfo.length_m)
    rider_wid = float(sim.rider_width_m or rinfo.width_m)
    ego_len = float(sim.ego_length_m or ego_info.length_m)
    ego_wid = float(sim.ego_width_m or ego_info.width_m)
    return ScenarioArrays(
        scenario_id=scenario.id,
        dt_s=float(sim.dt_s),
        t_s=t_s,
        ego_path=ego_path,
        ego_track=ego_track,
        ego_length_m=float(sim.ego_length_m or ego_info.length_m),
        ego_width_m=float(sim.ego_width_m or ego_info.width_m),
        ego_speed0_mps=float(ego_track.lookup(np.array([0.0]))[0, 1]),
        ego_median_moving_speed_mps=med,
        conflict_s_m=_conflict_arc_m(ex, ey, s_rec, rx, ry),
        rider_id=rid,
        rider_category=rinfo.category,
        rider_track=r_track,
        rider_path=rider_path,
        rider_length_m=rider_len,
        rider_width_m=rider_wid,
        other_ids=tuple(a.agent_id for a in others),
        other_categories=tuple(a.category for a in others),
        other_length_m=np.array([a.length_m for a in others], dtype=np.float64),
        other_width_m=np.array([a.width_m for a in others], dtype=np.float64),
        other_x_m=ox,
        other_y_m=oy,
        other_yaw_rad=oyaw,
        other_speed_mps=osp,
        other_active=oact,
        ego_path_info=ego_path_info,
        riders=_with_conflicts(
            prepare_extra_riders(
                scenario,
                extra_ids,
                enabled=several,
                primary_length_m=rider_len,
                primary_width_m=rider_wid,
                others=others,
                where=where,
            ),
            ego_path,
            ego_len,
            ego_wid,
        ),  # fmt: skip
        rider_recorded_span_s=rec_span,
        rider_sfm_entry_s=sfm_entry_s(scenario, rid, r_track),
        conflicts=find_conflicts(ego_path, rider_path, ego_len, ego_wid, rider_len, rider_wid),
        rider_moving_speeds_mps=moving_speeds(r_track, rec_span),
        traffic=prepare_traffic(
            scenario, others, t_s, ego_path, ego_track, ego_len, ego_wid, where
        ),
        peds=prepare_pedestrians(scenario, others, t_s, where),
        routes={
            a.agent_id: route_of(scenario, a.agent_id)
            for a in scenario.agents
            if a.agent_id != EGO_ID
        },
        buildings=scene_buildings(scenario),
    )


def _with_conflicts(
    riders: ExtraRiders, ego_path: PathTable, ego_length_m: float, ego_width_m: float
) -> ExtraRiders:
    """The extra riders with each one's conflicts with the ego (they decide too)."""
    if not riders.n:
        return riders
    conf = tuple(
        find_conflicts(ego_path, riders.paths[j], ego_length_m, ego_width_m,
                       float(riders.length_m[j]), float(riders.width_m[j]))
        for j in range(riders.n)
    )  # fmt: skip
    return dataclasses.replace(riders, conflicts=conf)


def _conflict_arc_m(
    ex: FloatArray, ey: FloatArray, s_m: FloatArray, rx: FloatArray, ry: FloatArray
) -> float:
    """Arc length [m] (s_m [M], along the ego path) of the ego sample (ex, ey) [M]
    nearest to the rider path (rx, ry)."""
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(np.column_stack([rx, ry])).query(np.column_stack([ex, ey]))
    return float(max(s_m[int(np.argmin(dist))], 0.0))


# --------------------------------------------------------------------------------------
# State
# --------------------------------------------------------------------------------------
class SimState(NamedTuple):
    """Engine state at step k (time t = k dt); every array ``[B]`` unless noted.

    Attributes:
        k: step index (int).
        ego_s_m: arc length along the ego path [m]; ego_x_m, ego_y_m, ego_yaw_rad: pose.
        ego_v_mps: speed. ego_a_mps2: reported longitudinal acceleration (the actuator's,
            0 while standing or after a collision) [m/s^2]. ego_act_mps2: the actuator's
            internal acceleration state [m/s^2]. ego_cmd: last command u in [-1, 1].
        pid_integral_m, pid_prev_error_mps: PID memory. cap_state: int8 CAP state.
        rider_x_m, rider_y_m, rider_yaw_rad, rider_vx_mps, rider_vy_mps, rider_speed_mps,
            rider_a_mps2: rider state (finite also while inactive: the recorded first /
            last pose, speed 0). rider_prog_m: SFM progress along the rider's own path [m].
        rider_active: bool, present in the scene. rider_started: bool, has entered.
        rider_done: bool, has left (recording over / SFM rider arrived).
        collided: bool latch, ego and rider have collided at or before this step.
        hit_other: [B, n_o] bool latch, ego has touched replayed other j.
        hist: perception ring buffer [4, H, B] (x, y, yaw, active) of the rider's poses;
            H = max delay steps + 1 (H = 1: no delay in the batch).
        extra_x_m, extra_y_m, extra_yaw_rad, extra_vx_mps, extra_vy_mps,
            extra_speed_mps, extra_a_mps2, extra_prog_m: [B, R] the extra riders
            (vei.sim.riders; R = 0 in the one-rider engine), like the rider_* fields.
        extra_decision: [B, R] int8, each extra social-force rider's decision at its own
            current conflict with the ego (as rider_decision).
        extra_active, extra_started, extra_done: [B, R] bool, like the rider's.
        extra_hit: [B, R] bool latch, the ego touched extra rider j (nothing stops).
        rider_decision: [B] int8, the social-force rider's decision at its current
            conflict (vei.models.decision_core: 0 FREE, 1 GO, 2 YIELD; 0 without decisions).
        car_s_m, car_v_mps, car_timer_s, car_x_m, car_y_m, car_yaw_rad: [B, C] the
            reacting cars (vei.sim.traffic): arc length along their paths [m], speed
            [m/s], reaction countdown [s], pose [m, rad]; car_mode [B, C] int8
            (vei.models.traffic_core: 0 replay, 1 reacting, 2 IDM, 3 stopped).
        rider_hit_other: [B, n_o] bool latch, the rider touched replayed other j.
        car_hit: [B, C] bool latch, reacting car j touched another other (car_hit_with:
            which, -1 none). sec_count, sec_first_t_s, sec_striker, sec_struck,
            sec_max_speed_mps, rear_end: [B] the secondary collisions so far
            (vei.sim.contacts).
        ped_x_m, ped_y_m, ped_vx_mps, ped_vy_mps, ped_prog_m: [B, P] the pedestrians
            (vei.sim.pedestrians; meaningful where peds_sfm).
    """

    k: int
    ego_s_m: FloatArray
    ego_x_m: FloatArray
    ego_y_m: FloatArray
    ego_yaw_rad: FloatArray
    ego_v_mps: FloatArray
    ego_a_mps2: FloatArray
    ego_act_mps2: FloatArray
    ego_cmd: FloatArray
    pid_integral_m: FloatArray
    pid_prev_error_mps: FloatArray
    cap_state: npt.NDArray[np.int8]
    rider_x_m: FloatArray
    rider_y_m: FloatArray
    rider_yaw_rad: FloatArray
    rider_vx_mps: FloatArray
    rider_vy_mps: FloatArray
    rider_speed_mps: FloatArray
    rider_a_mps2: FloatArray
    rider_prog_m: FloatArray
    rider_active: BoolArray
    rider_started: BoolArray
    rider_done: BoolArray
    collided: BoolArray
    hit_other: BoolArray
    hist: FloatArray
    extra_x_m: FloatArray
    extra_y_m: FloatArray
    extra_yaw_rad: FloatArray
    extra_vx_mps: FloatArray
    extra_vy_mps: FloatArray
    extra_speed_mps: FloatArray
    extra_a_mps2: FloatArray
    extra_prog_m: FloatArray
    extra_decision: npt.NDArray[np.int8]
    extra_active: BoolArray
    extra_started: BoolArray
    extra_done: BoolArray
    extra_hit: BoolArray
    rider_decision: npt.NDArray[np.int8]
    car_s_m: FloatArray
    car_v_mps: FloatArray
    car_timer_s: FloatArray
    car_x_m: FloatArray
    car_y_m: FloatArray
    car_yaw_rad: FloatArray
    car_mode: npt.NDArray[np.int8]
    rider_hit_other: BoolArray
    car_hit: BoolArray
    car_hit_with: npt.NDArray[np.int32]
    sec_count: npt.NDArray[np.int32]
    sec_first_t_s: FloatArray
    sec_striker: npt.NDArray[np.int32]
    sec_struck: npt.NDArray[np.int32]
    sec_max_speed_mps: FloatArray
    rear_end: BoolArray
    ped_x_m: FloatArray
    ped_y_m: FloatArray
    ped_vx_mps: FloatArray
    ped_vy_mps: FloatArray
    ped_prog_m: FloatArray


__all__ = [
    "EGO_CAP",
    "EGO_MODE_CODES",
    "EGO_PID",
    "EGO_POLICY",
    "EGO_REPLAY_SPEED",
    "ScenarioArrays",
    "SimState",
    "TimeTable",
    "VariantParams",
    "prepare_scenario",
]
