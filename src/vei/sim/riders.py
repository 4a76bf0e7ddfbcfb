"""Several social-force riders: the extra riders of a scenario and their NumPy step.

The primary rider keeps its own state (``SimState.rider_*`` ``[B]``); the other riders
that ``SimConfig.sfm_riders`` selects form a block of R extra riders with state
``SimState.extra_*`` ``[B, R]``. In SFM variants each extra rider follows its own recorded
route with the same social force as the primary (look-ahead goal on its own path, vehicle
force from the ego, the variant's SFM parameters; speeds from its own recording where the
variant's ``speed_from_recording`` is set), enters at its first recorded sample
(recording time: the time shift moves the primary only) and leaves once at its final
point after its last sample. All SFM riders (primary and extras) repel each other and the
recorded pedestrians (:func:`vei.models.sfm.rider_force`). In replay variants the extra
riders are replayed. Contacts of the ego with an extra rider are latched
(``extra_hit``), nothing stops (like the replayed others).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.boxes import boxes_overlap
from vei.continuation import recorded_span_s
from vei.errors import InputError
from vei.models import sfm as sfm_model
from vei.models.decision_core import capped_velocity_core, reference_speed_core
from vei.models.drivable_path import decimate_standstill, jitter_mask, recorded_arc_length
from vei.models.ego import PathTable, build_path
from vei.models.sfm_core import obstacle_speed_core
from vei.sim.decisions import Conflicts, decision_step
from vei.sim.tables import TimeTable, _uniform_track, recorded_column
from vei.types import EGO_ID, RIDER_CATEGORIES, Scenario

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Columns of a rider's uniform time table.
RIDER_COLUMNS = ("x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps", "arc_m")
#: SimState fields of the extra riders ([B, R]), floats then bools.
EXTRA_FLOAT_FIELDS = (
    "extra_x_m", "extra_y_m", "extra_yaw_rad", "extra_vx_mps", "extra_vy_mps",
    "extra_speed_mps", "extra_a_mps2", "extra_prog_m", "extra_decision",
)  # fmt: skip
#: The one int8 field among them (decision states, vei.models.decision_core).
EXTRA_INT_FIELDS = ("extra_decision",)
EXTRA_BOOL_FIELDS = ("extra_active", "extra_started", "extra_done", "extra_hit")
_SPAN_EPS = 1e-9
#: Spacing [m] of the points of the SFM riders' paths in the several-rider mode
#: (rider_track's min_step_m): more than the jitter of a waiting rider in the shared
#: recordings (up to ~1.4 m on stadtmitte_12_audi_geradeaus_03), less than the radius of
#: its turns.
RIDER_PATH_STEP_M = 1.5


def rider_track(
    scenario: Scenario, agent_id: str, where: str, min_step_m: float | None = None
) -> tuple[TimeTable, PathTable]:
    """A rider's recording as a uniform time table (RIDER_COLUMNS) and its path table.

    Args:
        scenario: the scenario. agent_id: the rider. where: prefix of error messages.
        min_step_m: None = the path through every recorded position (the one-rider
            engine); else the path through positions at least this far apart
            (vei.models.drivable_path.decimate_standstill: a rider waiting in the
            recording jitters by up to a metre, and a path through that jitter has loops
            in which a social-force rider, whose progress never goes back, gets stuck),
            and ``arc_m`` the recorded positions' monotone arc length along it.
    Returns:
        (track, path): velocities are the recorded speed along the recorded heading (finite
        differences of the positions where no speed is recorded); ``arc_m`` the arc length
        along the path; the path extends 50 m beyond both ends.
    """
    tr = scenario.track(agent_id)
    rx = tr["x_m"].to_numpy(dtype=np.float64)
    ry = tr["y_m"].to_numpy(dtype=np.float64)
    ryaw = np.unwrap(tr["yaw_rad"].to_numpy(dtype=np.float64))
    rt = tr["t_s"].to_numpy(dtype=np.float64)
    if rt.size > 1:
        vx, vy = np.gradient(rx, rt), np.gradient(ry, rt)
    else:
        vx = vy = np.zeros_like(rx)
    sp = tr["speed_mps"].to_numpy(dtype=np.float64)
    # One truth for every rider (issue 32.4): where the speed is recorded, the velocity is
    # that speed along the recorded heading, as for every replayed road user
    # (vei.sim.observe.ground_truth); finite differences of the positions only where it
    # is not (np.gradient is one-sided at the ends: a rider's first VAM would differ).
    rec = np.isfinite(sp)
    vx = np.where(rec, sp * np.cos(ryaw), vx)
    vy = np.where(rec, sp * np.sin(ryaw), vy)
    sp = np.where(rec, sp, np.hypot(vx, vy))
    dwell = jitter_mask(rx, ry, rt) if min_step_m is None else None
    if min_step_m is None and dwell is not None and dwell.any():
        # A rider that waits (its track jitters within a metre for seconds): its path runs
        # through the first point of each wait only (a social-force rider, whose progress
        # never goes back, would get stuck in the jitter's loops), its arc_m is the
        # recorded positions' monotone arc length along that path.
        keep = ~dwell | np.concatenate([[True], ~dwell[:-1]])
        path = build_path(
            rx[keep], ry[keep], yaw_hint_rad=float(ryaw[0]), extend_m=50.0,
            where=f"{where}: {agent_id}",
        )  # fmt: skip
        arc = np.maximum(recorded_arc_length(path, rx, ry), 0.0)
    elif min_step_m is None:
        arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(rx), np.diff(ry)))])
        path = build_path(
            rx, ry, yaw_hint_rad=float(ryaw[0]), extend_m=50.0, where=f"{where}: {agent_id}"
        )
    else:
        keep = decimate_standstill(rx, ry, min_step_m)
        path = build_path(
            rx[keep],
            ry[keep],
            yaw_hint_rad=float(ryaw[0]),
            extend_m=50.0,
            where=f"{where}: {agent_id}",
        )
        arc = np.maximum(recorded_arc_length(path, rx, ry), 0.0)
    df = tr.assign(yaw_rad=ryaw, speed_mps=sp, vx_mps=vx, vy_mps=vy, arc_m=arc)
    t0, dt, data = _uniform_track(df, RIDER_COLUMNS, f"{where}: {agent_id}")
    return TimeTable(t0, dt, data, RIDER_COLUMNS), path


def moving_speeds(track: TimeTable, span_s: tuple[float, float]) -> FloatArray | None:
    """The recorded speeds [m/s] of a rider's moving parts: its table's samples inside the
    recorded span ``span_s`` outside its jittering waits (:func:`vei.models.drivable_path.
    jitter_mask`: a waiting rider's jitter reads as 0.5-1 m/s of speed and would pull the
    median moving speed, the calibrated rider's cruise speed, down); None where it never
    dwells (then every recorded sample counts, as before)."""
    t = track.t0_s + np.arange(track.data.shape[0]) * track.dt_s
    rec = (t >= span_s[0] - 1e-6) & (t <= span_s[1] + 1e-6)
    x, y = track.data[rec, track.col("x_m")], track.data[rec, track.col("y_m")]
    if x.size == 0:
        return None
    dwell = jitter_mask(x, y, t[rec])
    if not dwell.any():
        return None
    return np.ascontiguousarray(track.data[rec, track.col("speed_mps")][~dwell])


@dataclass(frozen=True)
class ExtraRiders:
    """The extra social-force riders of a scenario (R of them; R = 0: one-rider engine).

    Attributes:
        enabled: several-rider mode (``sfm_riders`` not 'primary'): the rider-rider and
            rider-pedestrian repulsion act (on the primary too), even with R = 0.
        ids, categories: the extra riders.
        length_m, width_m: [R] footprints [m]. radius_m: [R] disc radius (half the
            longer side) [m]. primary_radius_m: the primary rider's [m].
        tracks, paths: each rider's uniform time table (RIDER_COLUMNS) and path table.
        median_speed_mps, p99_speed_mps: [R] recorded median speed while moving
            (> 0.5 m/s) and 99th percentile of the speed (NaN if it never moves).
        ped_idx: indices (into the replayed others) of recorded pedestrians, the
            repulsion's fixed-path obstacles (empty unless enabled). ped_radius_m: theirs.
        sfm_entry_s: [R] recording time [s] from which the social force drives each rider
            in SFM variants (:func:`sfm_entry_s`); before it a present rider is replayed
            (a standing run-in).
        conflicts: [R] each rider's conflicts with the ego (vei.sim.decisions.Conflicts):
            a social-force extra rider decides to yield or go there as the primary does.
    """

    enabled: bool = False
    ids: tuple[str, ...] = ()
    categories: tuple[str, ...] = ()
    length_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    width_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    radius_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    primary_radius_m: float = 0.0
    tracks: tuple[TimeTable, ...] = ()
    paths: tuple[PathTable, ...] = ()
    median_speed_mps: FloatArray = field(default_factory=lambda: np.zeros(0))
    p99_speed_mps: FloatArray = field(default_factory=lambda: np.zeros(0))
    ped_idx: npt.NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    ped_radius_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    sfm_entry_s: FloatArray = field(default_factory=lambda: np.zeros(0))
    conflicts: tuple[Conflicts, ...] = ()

    @property
    def n(self) -> int:
        """R, the number of extra riders."""
        return len(self.ids)


def select_extra_riders(
    scenario: Scenario, primary_id: str, selection: str | Sequence[str], where: str
) -> list[str]:
    """Ids of the extra SFM riders for ``SimConfig.sfm_riders`` (primary excluded).

    'primary' -> none; 'all' -> every e-scooter and cyclist with a trajectory; a list ->
    those ids (each must have a trajectory and be an e-scooter or cyclist; InputError).
    """
    if selection == "primary":
        return []
    ids = set(scenario.trajectories["agent_id"].unique())
    if selection == "all":
        return [
            a.agent_id
            for a in scenario.agents
            if a.agent_id not in (EGO_ID, primary_id)
            and a.agent_id in ids
            and a.category in RIDER_CATEGORIES
        ]
    out = []
    cats = {a.agent_id: a.category for a in scenario.agents}
    for rid in selection:
        if rid == primary_id:
            continue
        if rid not in ids or rid not in cats:
            raise InputError(f"rider {rid!r} has no trajectory", path=where, field="sfm_riders")
        if cats[rid] not in RIDER_CATEGORIES:
            raise InputError(
                f"agent {rid!r} is a {cats[rid]}, not a rider ({', '.join(RIDER_CATEGORIES)})",
                path=where,
                field="sfm_riders",
            )
        if rid not in out:
            out.append(rid)
    return out


def prepare_extra_riders(
    scenario: Scenario,
    extra_ids: Sequence[str],
    *,
    enabled: bool,
    primary_length_m: float,
    primary_width_m: float,
    others: Sequence[Any],
    where: str,
) -> ExtraRiders:
    """Tables of the extra riders and the pedestrian obstacles (see :class:`ExtraRiders`).

    Args:
        scenario: the scenario. extra_ids: from :func:`select_extra_riders`.
        enabled: several-rider mode. primary_length_m, primary_width_m: the primary's
            footprint [m]. others: the replayed others' AgentInfo (engine order).
        where: prefix of error messages.
    """
    if not enabled:
        return ExtraRiders()
    info = {a.agent_id: a for a in scenario.agents}
    tracks, paths, med, p99, entry = [], [], [], [], []
    for rid in extra_ids:
        tr, path = rider_track(scenario, rid, where, RIDER_PATH_STEP_M)
        tracks.append(tr)
        paths.append(path)
        sp = recorded_column(tr, "speed_mps", recorded_span_s(scenario, rid))
        entry.append(sfm_entry_s(scenario, rid, tr))
        moving = sp[np.isfinite(sp) & (sp > 0.5)]
        if moving.size:
            med.append(float(np.median(moving)))
            p99.append(float(np.quantile(sp[np.isfinite(sp)], 0.99)))
        else:
            med.append(np.nan)
            p99.append(np.nan)
    length = np.array([info[r].length_m for r in extra_ids], dtype=np.float64)
    width = np.array([info[r].width_m for r in extra_ids], dtype=np.float64)
    ped = np.array([j for j, a in enumerate(others) if a.category == "pedestrian"], dtype=np.intp)
    ped_r = np.array([0.5 * max(others[j].length_m, others[j].width_m) for j in ped])
    return ExtraRiders(
        enabled=True,
        ids=tuple(extra_ids),
        categories=tuple(info[r].category for r in extra_ids),
        length_m=length,
        width_m=width,
        radius_m=0.5 * np.maximum(length, width),
        primary_radius_m=0.5 * max(primary_length_m, primary_width_m),
        tracks=tuple(tracks),
        paths=tuple(paths),
        median_speed_mps=np.array(med, dtype=np.float64),
        p99_speed_mps=np.array(p99, dtype=np.float64),
        ped_idx=ped,
        ped_radius_m=ped_r.astype(np.float64),
        sfm_entry_s=np.array(entry, dtype=np.float64),
    )


def sfm_entry_s(scenario: Scenario, agent_id: str, track: TimeTable) -> float:
    """Recording time [s] from which a social-force rider is driven by its forces: its
    first *recorded* sample. Before it the rider rides (or stands on) its run-in replayed
    (vei.continuation): present and seen, on the time line of its recording, so that the
    social force takes over where and when it did without a run-in (a rider faster than
    its recording would otherwise gain on it over the whole run-in, and the time shift,
    found under replay, would no longer bring it to the car). The run-in keeps beyond the
    car's reach, where the vehicle force (A exp(-b d), 4e-6 N at 5 m) is nil anyway."""
    first = recorded_span_s(scenario, agent_id)[0]
    return float(first) if np.isfinite(first) else float(track.t0_s)


# --------------------------------------------------------------------------------------
# NumPy step
# --------------------------------------------------------------------------------------
def initial_extra_state(
    ex: ExtraRiders, b: int, sfm: npt.NDArray[np.bool_] | None = None
) -> dict[str, np.ndarray]:
    """The extra riders' SimState fields at k = 0 ([B, R]): each at its recorded first
    pose, active (with its recorded velocity) if its recording starts at t <= 0; started
    unless the variant is SFM (``sfm`` [B]) and t = 0 lies before the rider's SFM entry."""
    r = ex.n
    out: dict[str, np.ndarray] = {f: np.zeros((b, r)) for f in EXTRA_FLOAT_FIELDS}
    for f in EXTRA_INT_FIELDS:
        out[f] = np.zeros((b, r), dtype=np.int8)
    for f in EXTRA_BOOL_FIELDS:
        out[f] = np.zeros((b, r), dtype=bool)
    for j, tr in enumerate(ex.tracks):
        i, w = tr.index(np.array([0.0]))
        x, y, yaw, sp, vx, vy, arc = (float(v[0]) for v in tr.values_at(i, w, *RIDER_COLUMNS))
        inside = tr.t0_s - _SPAN_EPS <= 0.0 <= tr.t_end_s + _SPAN_EPS
        out["extra_x_m"][:, j] = x
        out["extra_y_m"][:, j] = y
        out["extra_yaw_rad"][:, j] = yaw
        out["extra_prog_m"][:, j] = arc
        if inside:
            out["extra_vx_mps"][:, j] = vx
            out["extra_vy_mps"][:, j] = vy
            out["extra_speed_mps"][:, j] = sp
            out["extra_active"][:, j] = True
            waiting = ex.sfm_entry_s.size and 0.0 < ex.sfm_entry_s[j] - _SPAN_EPS
            out["extra_started"][:, j] = True if (sfm is None or not waiting) else ~sfm
    return out


def extra_speeds(ex: ExtraRiders, p: Any, j: int) -> tuple[FloatArray, FloatArray]:
    """[B] v0 and speed limit of extra rider j: from its own recording where the variant
    has ``speed_from_recording`` (v0 L / sqrt(L^2 + sigma^2) = its median moving speed;
    limit = max(99th percentile, median)), else the variant's v0_mps / max_speed_mps."""
    med, p99 = ex.median_speed_mps[j], ex.p99_speed_mps[j]
    if not np.isfinite(med):
        return p.v0_mps, p.max_speed_mps
    use = p.speed_from_recording
    v0 = np.where(use, med * np.hypot(p.lookahead_m, p.sigma_m) / p.lookahead_m, p.v0_mps)
    vmax = np.where(use, max(p99, med), p.max_speed_mps)
    return v0, vmax


def repulsion(
    x: FloatArray,
    y: FloatArray,
    r_self: float,
    p: Any,
    sources: Sequence[tuple[FloatArray, FloatArray, npt.ArrayLike, float]],
) -> tuple[FloatArray, FloatArray]:
    """Sum of rider_force on agents at (x, y) [B] from ``sources`` in order.

    Args:
        x, y: [B] positions [m]. r_self: own radius [m]. p: VariantParams (a_rider_n,
        b_rider_per_m, use_rider_force). sources: (qx [B] or scalar, qy, active [B] or
        bool, radius) of each other agent.
    Returns:
        (fx_n, fy_n) [B], 0 where use_rider_force is off.
    """
    fx = np.zeros_like(x)
    fy = np.zeros_like(y)
    for qx, qy, act, rad in sources:
        hx, hy = sfm_model.rider_force(x, y, qx, qy, r_self + rad, p.a_rider_n, p.b_rider_per_m)
        on = np.logical_and(act, p.use_rider_force)
        fx = fx + np.where(on, hx, 0.0)
        fy = fy + np.where(on, hy, 0.0)
    return fx, fy


def pedestrian_sources(
    arrays: Any, k: int
) -> list[tuple[FloatArray, FloatArray, npt.ArrayLike, float]]:
    """The recorded pedestrians at step k as repulsion sources (scalar positions)."""
    ex = arrays.riders
    return [
        (
            arrays.other_x_m[k, j],
            arrays.other_y_m[k, j],
            bool(arrays.other_active[k, j]),
            float(ex.ped_radius_m[m]),
        )
        for m, j in enumerate(ex.ped_idx)
    ]


def step_extras(
    st: Any,
    arrays: Any,
    p: Any,
    sfm: bool,
    t_new: float,
    ego_new: tuple[FloatArray, FloatArray, FloatArray],
) -> dict[str, np.ndarray]:
    """Advance the extra riders of one block by one step (forces from the state at step k).

    Args:
        st: SimState at step k (the block's variants). arrays: ScenarioArrays.
        p: the block's VariantParams. sfm: SFM block (else replay). t_new: (k + 1) dt [s].
        ego_new: the ego's pose (x, y, yaw) [B] at step k + 1 (contact test).
    Returns:
        The new SimState extra_* fields ([B, R], fresh arrays).
    """
    ex = arrays.riders
    k = st.k
    dt = arrays.dt_s
    out = {f: getattr(st, f).copy() for f in EXTRA_FLOAT_FIELDS + EXTRA_BOOL_FIELDS}
    x0, y0 = st.extra_x_m, st.extra_y_m
    act0 = st.extra_active
    peds = pedestrian_sources(arrays, k) if sfm else []
    for j in range(ex.n):
        tr, rp = ex.tracks[j], ex.paths[j]
        in_span = tr.t0_s - _SPAN_EPS <= t_new <= tr.t_end_s + _SPAN_EPS
        if not sfm:
            if in_span:
                i, w = tr.index(np.array([t_new]))
                vals = [float(v[0]) for v in tr.values_at(i, w, *RIDER_COLUMNS[:6])]
            else:
                row = tr.data[0] if t_new < tr.t0_s else tr.data[-1]
                vals = [row[tr.col(c)] for c in RIDER_COLUMNS[:3]] + [0.0, 0.0, 0.0]
            for name, val in zip(
                ("extra_x_m", "extra_y_m", "extra_yaw_rad", "extra_speed_mps"),
                (vals[0], vals[1], vals[2], vals[3]),
                strict=True,
            ):
                out[name][:, j] = val
            out["extra_vx_mps"][:, j] = vals[4]
            out["extra_vy_mps"][:, j] = vals[5]
            out["extra_active"][:, j] = in_span
            out["extra_done"][:, j] |= st.extra_started[:, j] & (not in_span)
            out["extra_started"][:, j] |= in_span
        else:
            moving = np.flatnonzero(act0[:, j] & st.extra_started[:, j])
            if moving.size:
                _sfm_extra(st, arrays, p, j, moving, t_new, dt, peds, out)
            if in_span:
                # enter (or, before the SFM entry, stand replayed on a standing run-in)
                entering = np.flatnonzero(~st.extra_started[:, j])
                if entering.size:
                    i, w = tr.index(np.array([t_new]))
                    vals = [float(v[0]) for v in tr.values_at(i, w, *RIDER_COLUMNS)]
                    names = (
                        "extra_x_m", "extra_y_m", "extra_yaw_rad", "extra_speed_mps",
                        "extra_vx_mps", "extra_vy_mps", "extra_prog_m",
                    )  # fmt: skip
                    for name, val in zip(names, vals, strict=True):
                        out[name][entering, j] = val
                    out["extra_active"][entering, j] = True
                    entry = ex.sfm_entry_s[j] if ex.sfm_entry_s.size else -np.inf
                    out["extra_started"][entering, j] = t_new >= entry - _SPAN_EPS
        del rp
        act_new = out["extra_active"][:, j]
        out["extra_a_mps2"][:, j] = np.where(
            act_new & act0[:, j],
            (out["extra_speed_mps"][:, j] - st.extra_speed_mps[:, j]) / dt,
            0.0,
        )
        # Ego contact latch (nothing stops).
        exn, eyn, eyawn = ego_new
        reach = 0.5 * (
            np.hypot(arrays.ego_length_m, arrays.ego_width_m)
            + np.hypot(ex.length_m[j], ex.width_m[j])
        )
        xj, yj = out["extra_x_m"][:, j], out["extra_y_m"][:, j]
        cand = np.flatnonzero(
            act_new & ~st.extra_hit[:, j] & ((xj - exn) ** 2 + (yj - eyn) ** 2 <= reach * reach)
        )
        if cand.size:
            ov = boxes_overlap(
                exn[cand], eyn[cand], eyawn[cand], arrays.ego_length_m, arrays.ego_width_m,
                xj[cand], yj[cand], out["extra_yaw_rad"][cand, j], ex.length_m[j], ex.width_m[j],
            )  # fmt: skip
            out["extra_hit"][cand[ov], j] = True
    del x0, y0
    return out


def _sfm_extra(
    st: Any,
    arrays: Any,
    p: Any,
    j: int,
    sel: npt.NDArray[np.intp],
    t_new: float,
    dt: float,
    peds: list[tuple[FloatArray, FloatArray, npt.ArrayLike, float]],
    out: dict[str, np.ndarray],
) -> None:
    """Social-force step of extra rider j for the variants ``sel`` (written into out)."""
    ex = arrays.riders
    ps = p.take(sel)
    rp = ex.paths[j]
    x0, y0 = st.extra_x_m[sel, j], st.extra_y_m[sel, j]
    vx0, vy0 = st.extra_vx_mps[sel, j], st.extra_vy_mps[sel, j]
    prog0 = st.extra_prog_m[sel, j]
    i, w = rp.index(prog0)
    qx, qy, qc, qs = rp.values_at(i, w, "x", "y", "cos", "sin")
    prog = np.maximum(prog0 + (x0 - qx) * qc + (y0 - qy) * qs, prog0)
    i, w = rp.index(np.minimum(prog + ps.lookahead_m, rp.length_m))
    gx, gy = rp.values_at(i, w, "x", "y")
    v0, vmax = extra_speeds(ex, ps, j)
    vdx, vdy = sfm_model.desired_velocity(x0, y0, gx, gy, v0, ps.sigma_m, ps.paper_vdes)
    conf = ex.conflicts[j] if ex.conflicts else None
    if conf is not None and conf.n and ps.decide.any():  # its yield / go decision
        old = st.extra_decision[sel, j]
        new_dec, cap = decision_step(
            conf, old, prog0, prog, st.extra_speed_mps[sel, j], st.ego_s_m[sel],
            st.ego_v_mps[sel], ps, reference_speed_core(v0, ps.lookahead_m, ps.sigma_m),
            ps.mass_kg / ps.k_des_nspm,
        )  # fmt: skip
        new_dec = np.where(ps.decide, new_dec, old).astype(np.int8)
        vdx, vdy = capped_velocity_core(vdx, vdy, np.where(ps.decide, cap, np.inf))
        out["extra_decision"][sel, j] = new_dec
    ego_x, ego_y, ego_yaw = st.ego_x_m[sel], st.ego_y_m[sel], st.ego_yaw_rad[sel]
    on = ps.obstacle_braking & (st.ego_v_mps[sel] < ps.obstacle_speed_mps)
    if on.any():  # braking for a standing or slow car in its way (vei.sim.obstacles)
        cap = obstacle_speed_core(
            x0, y0, vdx, vdy, st.extra_speed_mps[sel, j], ego_x, ego_y, np.cos(ego_yaw),
            np.sin(ego_yaw), 0.5 * arrays.ego_length_m, 0.5 * arrays.ego_width_m,
            0.5 * np.hypot(ex.length_m[j], ex.width_m[j]), ps.obstacle_margin_m,
            ps.obstacle_decel_mps2, ps.mass_kg / ps.k_des_nspm,
        )  # fmt: skip
        vdx, vdy = capped_velocity_core(vdx, vdy, np.where(on, cap, np.inf))
    fx, fy = sfm_model.destination_force(vdx, vdy, vx0, vy0, ps.k_des_nspm)
    bx, by = sfm_model.influential_point(
        x0, y0, ego_x, ego_y, ego_yaw, arrays.ego_length_m, arrays.ego_width_m, ps.front_bumper
    )
    hx, hy = sfm_model.vehicle_force(
        x0, y0, bx, by, ps.a_veh_n, ps.b_veh_per_m, ego_x, ego_y, ego_yaw
    )
    fx = fx + np.where(ps.use_vehicle_force, hx, 0.0)
    fy = fy + np.where(ps.use_vehicle_force, hy, 0.0)
    sources = [(st.rider_x_m[sel], st.rider_y_m[sel], st.rider_active[sel], ex.primary_radius_m)]
    for m in range(ex.n):
        if m != j:
            sources.append(
                (
                    st.extra_x_m[sel, m],
                    st.extra_y_m[sel, m],
                    st.extra_active[sel, m],
                    float(ex.radius_m[m]),
                )
            )
    rx_, ry_ = repulsion(x0, y0, float(ex.radius_m[j]), ps, sources + peds)
    fx, fy = fx + rx_, fy + ry_
    mass = ps.mass_kg
    fx, fy = sfm_model.cap_force(fx, fy, ps.max_accel_mps2 * mass)
    nx, ny, nvx, nvy = sfm_model.point_mass_step(x0, y0, vx0, vy0, fx, fy, mass, dt)
    nsp = np.sqrt(nvx * nvx + nvy * nvy)
    nx, ny, nvx, nvy, nsp = sfm_model.cap_speed(x0, y0, nx, ny, nvx, nvy, nsp, vmax, dt)
    nyaw = np.where(nsp > 0.05, np.arctan2(nvy, nvx), st.extra_yaw_rad[sel, j])
    arrived = (nx - rp.end_x_m) ** 2 + (ny - rp.end_y_m) ** 2 <= np.square(ps.arrive_radius_m)
    leaving = arrived & (t_new > ex.tracks[j].t_end_s + _SPAN_EPS)
    out["extra_x_m"][sel, j] = nx
    out["extra_y_m"][sel, j] = ny
    out["extra_yaw_rad"][sel, j] = nyaw
    out["extra_vx_mps"][sel, j] = np.where(leaving, 0.0, nvx)
    out["extra_vy_mps"][sel, j] = np.where(leaving, 0.0, nvy)
    out["extra_speed_mps"][sel, j] = np.where(leaving, 0.0, nsp)
    out["extra_prog_m"][sel, j] = prog
    out["extra_active"][sel, j] = ~leaving
    out["extra_done"][sel, j] |= leaving
