"""Engine inputs and state: per-scenario tables, per-variant parameter arrays, the state.

- :class:`ScenarioArrays`: everything the engine needs from a :class:`vei.types.Scenario`,
  precomputed once (ego path arc-length table, recorded tracks as uniform time tables,
  replayed other road users at every engine step).
- :class:`VariantParams`: every per-variant parameter as an array ``[B]`` (a sweep varies
  any of them without Python loops).
- :class:`SimState`: the engine state at one step, arrays ``[B]``.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from vei.config import AUTO, MAX_RUN_UP_M, MEDIAN_MOVING, CaseConfig, SimConfig
from vei.errors import ConfigError, InputError
from vei.models.drivable_path import (
    PATH_SPEED_MARGIN,
    EgoPathInfo,
    build_ego_path,
    recorded_arc_length,
)
from vei.models.ego import PathTable, build_path, median_moving_speed_mps, uniform_grid_index
from vei.types import EGO_ID, Scenario

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Ego modes (int8 codes of VariantParams.ego_mode).
EGO_REPLAY_SPEED, EGO_PID, EGO_CAP = 0, 1, 2
EGO_MODE_CODES: dict[str, int] = {"replay-speed": EGO_REPLAY_SPEED, "pid": EGO_PID, "cap": EGO_CAP}


# --------------------------------------------------------------------------------------
# Uniform time tables
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TimeTable:
    """A recorded track resampled on a uniform time grid ``t0_s + i * dt_s``.

    Attributes:
        t0_s: time of the first sample [s] (recording time, before any shift).
        dt_s: sample spacing [s].
        data: [M, C] samples, columns named by ``columns``.
        columns: column names.
    """

    t0_s: float
    dt_s: float
    data: FloatArray
    columns: tuple[str, ...]

    def __post_init__(self) -> None:
        d = np.asarray(self.data, dtype=np.float64)
        slope = np.zeros_like(d)
        if d.shape[0] > 1:
            slope[:-1] = np.diff(d, axis=0)
        object.__setattr__(
            self, "_cols", {c: np.ascontiguousarray(d[:, j]) for j, c in enumerate(self.columns)}
        )
        object.__setattr__(
            self,
            "_slopes",
            {c: np.ascontiguousarray(slope[:, j]) for j, c in enumerate(self.columns)},
        )

    def index(self, t_s: npt.ArrayLike) -> tuple[npt.NDArray[np.intp], FloatArray]:
        """Sample index and weight of times t (clamped): t lies between samples i and i + 1."""
        return uniform_grid_index(t_s, self.t0_s, self.dt_s, self.data.shape[0])

    def values_at(self, i: npt.NDArray[np.intp], w: FloatArray, *names: str) -> list[FloatArray]:
        """Linearly interpolated named columns at (i, w) from :meth:`index`."""
        cols = self._cols  # type: ignore[attr-defined]
        slopes = self._slopes  # type: ignore[attr-defined]
        return [cols[n][i] + w * slopes[n][i] for n in names]

    @property
    def t_end_s(self) -> float:
        """Time of the last sample [s]."""
        return self.t0_s + (self.data.shape[0] - 1) * self.dt_s

    def col(self, name: str) -> int:
        """Index of a column."""
        return self.columns.index(name)

    def lookup(self, t_s: npt.ArrayLike) -> FloatArray:
        """Linear interpolation at times t (clamped to the first / last sample).

        Args:
            t_s: [B] recording times [s].
        Returns:
            [B, C] interpolated samples.
        """
        i, w = self.index(t_s)
        return np.stack(self.values_at(i, w, *self.columns), axis=-1)


def _uniform_track(df: Any, cols: Sequence[str], where: str) -> tuple[float, float, FloatArray]:
    t = df["t_s"].to_numpy(dtype=np.float64)
    if t.size == 0:
        raise InputError("track has no samples", path=where)
    if np.any(np.diff(t) <= 0):
        raise InputError("track times must be strictly increasing", path=where, field="t_s")
    vals = np.stack([df[c].to_numpy(dtype=np.float64) for c in cols], axis=1)
    if t.size == 1:
        return float(t[0]), 1.0, vals
    dt = float(np.median(np.diff(t)))
    n = int(round((t[-1] - t[0]) / dt)) + 1
    grid = t[0] + np.arange(n) * dt
    if n == t.size and np.allclose(grid, t, atol=1e-6):
        return float(t[0]), dt, vals
    out = np.stack([np.interp(grid, t, vals[:, j]) for j in range(vals.shape[1])], axis=1)
    return float(t[0]), dt, out


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
            y_m, yaw_rad (unwrapped), speed_mps, vx_mps, vy_mps (finite differences of the
            positions), arc_m (arc length along rider_path).
        rider_path: the rider's own recorded path (arc-length table; SFM goals).
        rider_length_m, rider_width_m: rider footprint [m].
        other_ids, other_categories: the replayed other road users (n_o of them).
        other_length_m, other_width_m: [n_o] footprints [m].
        other_x_m, other_y_m, other_yaw_rad, other_speed_mps: [T, n_o] at the engine steps
            (last known values where inactive), other_active: [T, n_o] bool.
        ego_path_info: how ego_path was built (curvature bound, deviation, headings).
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
    shift). The simulated span is [0, sim.duration_s] or [0, last trajectory time].

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

    t_last = float(traj["t_s"].max())
    duration = sim.duration_s if sim.duration_s is not None else t_last
    n = int(math.floor(duration / sim.dt_s + 1e-9)) + 1
    t_s = np.arange(n) * sim.dt_s

    # Ego.
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
    rider = scenario.track(rid)
    rinfo = scenario.agent(rid)
    rx = rider["x_m"].to_numpy(dtype=np.float64)
    ry = rider["y_m"].to_numpy(dtype=np.float64)
    ryaw = np.unwrap(rider["yaw_rad"].to_numpy(dtype=np.float64))
    rt = rider["t_s"].to_numpy(dtype=np.float64)
    if rt.size > 1:
        vx, vy = np.gradient(rx, rt), np.gradient(ry, rt)
    else:
        vx = vy = np.zeros_like(rx)
    rspeed = rider["speed_mps"].to_numpy(dtype=np.float64)
    rspeed = np.where(np.isfinite(rspeed), rspeed, np.hypot(vx, vy))
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(rx), np.diff(ry)))])
    rdf = rider.assign(yaw_rad=ryaw, speed_mps=rspeed, vx_mps=vx, vy_mps=vy, arc_m=arc)
    cols = ("x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps", "arc_m")
    r0, drt, rdata = _uniform_track(rdf, cols, f"{where}: {rid}")
    rider_path = build_path(
        rx, ry, yaw_hint_rad=float(ryaw[0]), extend_m=50.0, where=f"{where}: {rid}"
    )

    # Others, replayed on the engine grid.
    others = [a for a in scenario.agents if a.agent_id not in (EGO_ID, rid) and a.agent_id in ids]
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
        rider_track=TimeTable(r0, drt, rdata, cols),
        rider_path=rider_path,
        rider_length_m=float(sim.rider_length_m or rinfo.length_m),
        rider_width_m=float(sim.rider_width_m or rinfo.width_m),
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
    )


def _conflict_arc_m(
    ex: FloatArray, ey: FloatArray, s_m: FloatArray, rx: FloatArray, ry: FloatArray
) -> float:
    """Arc length [m] (s_m [M], along the ego path) of the ego sample (ex, ey) [M]
    nearest to the rider path (rx, ry)."""
    from scipy.spatial import cKDTree

    dist, _ = cKDTree(np.column_stack([rx, ry])).query(np.column_stack([ex, ey]))
    return float(max(s_m[int(np.argmin(dist))], 0.0))


# --------------------------------------------------------------------------------------
# Per-variant parameters
# --------------------------------------------------------------------------------------
_BOOL_FIELDS = ("rider_sfm", "use_vehicle_force", "paper_vdes", "front_bumper", "paper_per_step")
_INT_FIELDS = ("ego_mode",)


@dataclass(frozen=True)
class VariantParams:
    """Per-variant parameters, every field an array ``[B]`` (float64 unless noted).

    Build with :meth:`from_case` (a configuration broadcast to B variants, with optional
    per-variant overrides), :meth:`concat` (stack several) or directly.

    Attributes:
        time_shift_s: shift of the primary rider's timing [s]; the rider at engine time t
            is the recording at t - time_shift_s (positive = the rider comes later).
        rider_sfm: bool; False = kinematic replay, True = social-force rider.
        k_des_nspm: effective destination gain (k_des * k_des_factor) [N s/m].
        a_veh_n, b_veh_per_m, v0_mps, mass_kg, sigma_m, lookahead_m, arrive_radius_m:
            SFM parameters (SFMConfig).
        use_vehicle_force, paper_vdes, front_bumper: bool switches (SFMConfig:
            use_vehicle_force, desired_velocity == 'paper', influential_point ==
            'front_bumper').
        max_speed_mps, max_accel_mps2: rider limits; +inf = none.
        ego_mode: int8, 0 replay-speed, 1 pid, 2 cap.
        cruise_speed_mps: v_d [m/s]. initial_speed_mps: ego speed at t = 0 [m/s].
        ego_start_s_m: ego arc length at t = 0 [m] (-run_up_m; 0 for replay-speed),
            in [-250, 0].
        kp, ki, kd, integral_limit: PID. integral_window_s: the integral's memory [s]
            (+inf = plain integral). max_accel_mps2_ego, max_decel_mps2_ego,
            actuator_lag_s: actuator (EgoConfig).
        t_safe_s, d_buf_m, a_min_mps2, corridor_half_width_m, detection_range_m,
            release_margin_m, recover_tolerance_mps: CAP (CAPConfig).
        paper_per_step: bool, CAP braking law 'paper_per_step'.
        perception_delay_s: CAP perception delay [s] (rounded to whole steps).
        labels: [B] object array of configuration names (for outputs).
    """

    time_shift_s: FloatArray
    rider_sfm: BoolArray
    k_des_nspm: FloatArray
    a_veh_n: FloatArray
    b_veh_per_m: FloatArray
    v0_mps: FloatArray
    mass_kg: FloatArray
    sigma_m: FloatArray
    lookahead_m: FloatArray
    arrive_radius_m: FloatArray
    use_vehicle_force: BoolArray
    paper_vdes: BoolArray
    front_bumper: BoolArray
    max_speed_mps: FloatArray
    max_accel_mps2: FloatArray
    ego_mode: npt.NDArray[np.int8]
    cruise_speed_mps: FloatArray
    initial_speed_mps: FloatArray
    ego_start_s_m: FloatArray
    kp: FloatArray
    ki: FloatArray
    kd: FloatArray
    integral_limit: FloatArray
    integral_window_s: FloatArray
    max_accel_mps2_ego: FloatArray
    max_decel_mps2_ego: FloatArray
    actuator_lag_s: FloatArray
    t_safe_s: FloatArray
    d_buf_m: FloatArray
    a_min_mps2: FloatArray
    corridor_half_width_m: FloatArray
    detection_range_m: FloatArray
    release_margin_m: FloatArray
    recover_tolerance_mps: FloatArray
    paper_per_step: BoolArray
    perception_delay_s: FloatArray
    labels: npt.NDArray[np.object_]

    def __post_init__(self) -> None:
        b = None
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if not isinstance(v, np.ndarray) or v.ndim != 1:
                raise ConfigError(f"VariantParams.{f.name} must be a 1-D array [B]")
            if b is None:
                b = v.shape[0]
            elif v.shape[0] != b:
                raise ConfigError(f"VariantParams.{f.name} has {v.shape[0]} entries, expected {b}")
            if v.dtype.kind == "f" and not np.all(np.isfinite(v) | np.isposinf(v)):
                raise ConfigError(f"VariantParams.{f.name} has NaN or -inf values")
        if b == 0:
            raise ConfigError("VariantParams needs at least one variant")
        for name in (
            "mass_kg",
            "sigma_m",
            "lookahead_m",
            "arrive_radius_m",
            "k_des_nspm",
            "max_accel_mps2_ego",
            "max_decel_mps2_ego",
            "corridor_half_width_m",
            "detection_range_m",
            "recover_tolerance_mps",
            "max_speed_mps",
            "max_accel_mps2",
            "integral_window_s",
        ):
            if np.any(getattr(self, name) <= 0):
                raise ConfigError(f"VariantParams.{name} must be > 0")
        for name in (
            "a_veh_n",
            "b_veh_per_m",
            "v0_mps",
            "cruise_speed_mps",
            "initial_speed_mps",
            "kp",
            "ki",
            "kd",
            "actuator_lag_s",
            "t_safe_s",
            "d_buf_m",
            "release_margin_m",
            "perception_delay_s",
            "integral_limit",
        ):
            if np.any(getattr(self, name) < 0):
                raise ConfigError(f"VariantParams.{name} must be >= 0")
        if np.any((self.ego_start_s_m > 0) | (self.ego_start_s_m < -250.0)):
            raise ConfigError("VariantParams.ego_start_s_m must lie in [-250, 0] m")
        if np.any(self.a_min_mps2 >= 0):
            raise ConfigError("VariantParams.a_min_mps2 must be < 0")
        if np.any((self.ego_mode < 0) | (self.ego_mode > 2)):
            raise ConfigError("VariantParams.ego_mode must be 0 (replay-speed), 1 (pid) or 2 (cap)")

    @property
    def batch_size(self) -> int:
        """B, the number of variants."""
        return int(self.time_shift_s.shape[0])

    @classmethod
    def from_case(
        cls,
        case: CaseConfig,
        arrays: ScenarioArrays,
        batch_size: int = 1,
        *,
        time_shift_s: npt.ArrayLike = 0.0,
        **overrides: npt.ArrayLike,
    ) -> VariantParams:
        """B copies of one configuration, with optional per-variant overrides.

        The cruise speed 'median-moving' resolves to the scenario's median moving speed;
        initial_speed 'cruise' to v_d, 'recorded' to the recorded speed at t = 0 (the
        replay-speed mode always starts from the recorded speed).

        Args:
            case: the configuration. arrays: the scenario's arrays (for resolved defaults).
            batch_size: B. time_shift_s: scalar or [B] [s].
            overrides: any field of VariantParams, scalar or [B] (e.g. cruise_speed_mps=
                np.linspace(4, 8, B)). An overridden cruise_speed_mps also sets
                initial_speed_mps when the case starts at cruise and it is not overridden.
        Returns:
            VariantParams with B variants.
        """
        sfm, ego, cap = case.sfm, case.ego, case.cap
        if ego.cruise_speed_mps == MEDIAN_MOVING:
            vd = arrays.ego_median_moving_speed_mps
            if not math.isfinite(vd):
                raise InputError(
                    "cannot derive the cruise speed: the recorded ego never moves; set ego.cruise_speed_mps",
                    path=f"scenario {arrays.scenario_id}",
                    field="cruise_speed_mps",
                )
        else:
            vd = float(ego.cruise_speed_mps)
        v_init: Any
        if case.ego_mode == "replay-speed" or ego.initial_speed == "recorded":
            v_init = arrays.ego_speed0_mps
        else:
            v_init = overrides.get("cruise_speed_mps", vd)
        if ego.run_up_m == AUTO:
            # Per variant: the cruise speed may be overridden per variant (sweeps).
            v_cruise = np.asarray(overrides.get("cruise_speed_mps", vd), dtype=np.float64)
            run_up_m: Any = np.clip(
                v_cruise * ego.approach_time_s - arrays.conflict_s_m, 0.0, MAX_RUN_UP_M
            )
        else:
            run_up_m = float(ego.run_up_m)
        inf = math.inf
        v0, vmax = sfm.v0_mps, sfm.max_speed_mps
        if sfm.speed_from_recording:  # calibrated rider: speeds from its own recording
            from vei.models.sfm import speed_from_recording

            tr = arrays.rider_track
            v0, vmax = speed_from_recording(
                tr.data[:, tr.col("speed_mps")], sfm.lookahead_m, sfm.sigma_m, v0, vmax
            )
        base: dict[str, Any] = {
            "time_shift_s": time_shift_s,
            "rider_sfm": case.rider == "sfm",
            "k_des_nspm": sfm.k_des_effective_nspm,
            "a_veh_n": sfm.a_veh_n,
            "b_veh_per_m": sfm.b_veh_per_m,
            "v0_mps": v0,
            "mass_kg": sfm.mass_kg,
            "sigma_m": sfm.sigma_m,
            "lookahead_m": sfm.lookahead_m,
            "arrive_radius_m": sfm.arrive_radius_m,
            "use_vehicle_force": sfm.use_vehicle_force,
            "paper_vdes": sfm.desired_velocity == "paper",
            "front_bumper": sfm.influential_point == "front_bumper",
            "max_speed_mps": inf if vmax is None else vmax,
            "max_accel_mps2": inf if sfm.max_accel_mps2 is None else sfm.max_accel_mps2,
            "ego_mode": EGO_MODE_CODES[case.ego_mode],
            "cruise_speed_mps": vd,
            "initial_speed_mps": v_init,
            "ego_start_s_m": 0.0 if case.ego_mode == "replay-speed" else -run_up_m,
            "kp": ego.kp,
            "ki": ego.ki,
            "kd": ego.kd,
            "integral_limit": ego.integral_limit,
            "integral_window_s": inf if ego.integral_window_s is None else ego.integral_window_s,
            "max_accel_mps2_ego": ego.max_accel_mps2,
            "max_decel_mps2_ego": ego.max_decel_mps2,
            "actuator_lag_s": ego.actuator_lag_s,
            "t_safe_s": cap.t_safe_s,
            "d_buf_m": cap.d_buf_m,
            "a_min_mps2": cap.a_min_mps2,
            "corridor_half_width_m": cap.corridor_half_width_m,
            "detection_range_m": cap.detection_range_m,
            "release_margin_m": cap.release_margin_m,
            "recover_tolerance_mps": cap.recover_tolerance_mps,
            "paper_per_step": cap.braking_law == "paper_per_step",
            "perception_delay_s": cap.perception_delay_s,
            "labels": case.name,
        }
        unknown = set(overrides) - set(base)
        if unknown:
            raise ConfigError(f"unknown VariantParams field(s): {', '.join(sorted(unknown))}")
        base.update(overrides)
        return cls._broadcast(base, batch_size)

    @classmethod
    def _broadcast(cls, values: dict[str, Any], batch_size: int) -> VariantParams:
        out: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            v = values[f.name]
            if f.name == "labels":
                arr = np.empty(batch_size, dtype=object)
                arr[:] = v if np.ndim(v) == 0 else list(v)
            elif f.name in _BOOL_FIELDS:
                arr = np.broadcast_to(np.asarray(v, dtype=bool), (batch_size,)).copy()
            elif f.name in _INT_FIELDS:
                arr = np.broadcast_to(np.asarray(v, dtype=np.int8), (batch_size,)).copy()
            else:
                arr = np.broadcast_to(np.asarray(v, dtype=np.float64), (batch_size,)).copy()
            out[f.name] = arr
        return cls(**out)

    @classmethod
    def concat(cls, parts: Sequence[VariantParams]) -> VariantParams:
        """Stack several VariantParams along the batch axis (in order)."""
        if not parts:
            raise ConfigError("concat needs at least one VariantParams")
        return cls(
            **{
                f.name: np.concatenate([getattr(p, f.name) for p in parts])
                for f in dataclasses.fields(cls)
            }
        )

    def take(self, index: npt.ArrayLike) -> VariantParams:
        """The variants at ``index`` (int array, slice or bool mask) as a new VariantParams."""
        if isinstance(index, slice):
            return VariantParams(
                **{f.name: getattr(self, f.name)[index].copy() for f in dataclasses.fields(self)}
            )
        idx = np.atleast_1d(np.asarray(index))
        return VariantParams(
            **{f.name: getattr(self, f.name)[idx] for f in dataclasses.fields(self)}
        )

    def with_values(self, **values: npt.ArrayLike) -> VariantParams:
        """A copy with some fields replaced (scalars or [B] arrays, broadcast)."""
        current = {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
        unknown = set(values) - set(current)
        if unknown:
            raise ConfigError(f"unknown VariantParams field(s): {', '.join(sorted(unknown))}")
        current.update(values)
        return VariantParams._broadcast(current, self.batch_size)

    def delay_steps(self, dt_s: float) -> npt.NDArray[np.intp]:
        """Perception delay in whole engine steps [B] (rounded to nearest)."""
        return np.rint(self.perception_delay_s / dt_s).astype(np.intp)


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
