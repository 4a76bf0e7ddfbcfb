"""The built-in engine: batched, vectorised, deterministic closed-loop simulation.

One scenario, B variants (arrays with a leading batch axis ``[B]``), a fixed step. The
ego follows its recorded path with a speed set by its mode (replay of the recorded speed,
PID cruise, PID + CAP); the primary rider is replayed (time-shifted) or driven by social
forces; every other recorded road user is replayed. Collisions are oriented-box overlaps.

Entry points:
    arrays = prepare_scenario(scenario, SimConfig())               # once per scenario
    params = VariantParams.from_case(case_preset("normal-cap"), arrays, B, time_shift_s=...)
    result = simulate(arrays, params)                              # SimResult [B, T]
    # or, step by step (pure):
    state = initial_state(arrays, params); state = step(state, params, arrays)
    # or, the named configurations in one batch:
    result = run_cases(scenario, ["replay", "normal", ...], time_shift_s=2.0)
    # large batches: the compiled kernel (numba), same model, ~10x faster at B >= 1e3:
    result = simulate(arrays, params, record="none", kernel="auto")

Batch layout: :func:`simulate` sorts the variants into contiguous blocks of equal (ego
mode, rider model) so that each block runs only its own branches (no per-variant mode
masks), and restores the caller's order in the outputs.

Order of one step k -> k + 1 (t = k dt):
  1. CAP perception: the rider pose of step k - n (n = perception delay in steps; not
     perceived while k < n); corridor test on the ego path; CAP state machine.
  2. Ego: PID (or the CAP's braking demand) -> command u in [-1, 1] -> demanded
     acceleration -> first-order actuator lag -> v' = max(0, v + a dt) -> s' = s + v' dt
     (semi-implicit); replay-speed: s and v from the recording at t + dt.
  3. Rider: replay = the recording at (t + dt - shift) (inactive outside its span); SFM =
     forces from the state at step k (ego box at step k), semi-implicit Euler. An SFM
     rider enters at the first step whose shifted recording time reaches the track's
     start, with the recorded position, heading and velocity there; its goal is the point
     ``lookahead_m`` ahead along its own recorded path from its progress (the local
     projection of its position, never decreasing), the final point near the end; it
     leaves (inactive) once within ``arrive_radius_m`` of the final point and the
     recording's span is over.
  4. Collision of the new poses: ego box vs rider box (if active). On collision both stop
     (speed 0, frozen pose) and stay so to the end; recording continues. Ego vs replayed
     others: recorded (``hit_other``) but nothing stops.

Determinism: no randomness; the same inputs give bit-identical outputs, and the
computation of one variant does not depend on the others in the batch (B single runs
equal one batch of B).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.config import CASE_PRESETS, CaseConfig, SimConfig, case_preset
from vei.errors import ConfigError
from vei.models import ego as ego_model
from vei.models import sfm as sfm_model
from vei.models.geometry import boxes_overlap
from vei.sim.state import (
    EGO_CAP,
    EGO_PID,
    EGO_REPLAY_SPEED,
    ScenarioArrays,
    SimState,
    VariantParams,
    prepare_scenario,
)
from vei.types import EGO_CATEGORY, EGO_ID, TIMESERIES_COLUMNS, Scenario, Trace

FloatArray = npt.NDArray[np.float64]
Record = Literal["full", "none"]
Kernel = Literal["numpy", "numba", "auto"]


# --------------------------------------------------------------------------------------
# Batch structure (computed once, outside the loop)
# --------------------------------------------------------------------------------------
def _switch(mask: npt.NDArray[np.bool_]) -> bool | npt.NDArray[np.bool_]:
    """True / False where the mask is uniform (lets the models skip a branch), else the mask."""
    if mask.all():
        return True
    if not mask.any():
        return False
    return mask


@dataclass(frozen=True)
class Block:
    """A contiguous run of variants with the same ego mode and rider model.

    Attributes:
        start, stop: the batch slice [start, stop).
        ego_mode: 0 replay-speed, 1 pid, 2 cap. rider_sfm: social-force rider (else replay).
        params: the VariantParams of the slice (views).
        delay_steps: [b] perception delay in steps (CAP blocks).
        paper_vdes, vehicle_force, front_bumper, paper_per_step: True / False if uniform in
            the block, else the [b] mask.
        rider_limits: some variant has a finite rider speed / acceleration cap.
    """

    start: int
    stop: int
    ego_mode: int
    rider_sfm: bool
    params: VariantParams
    delay_steps: npt.NDArray[np.intp]
    paper_vdes: bool | npt.NDArray[np.bool_]
    vehicle_force: bool | npt.NDArray[np.bool_]
    front_bumper: bool | npt.NDArray[np.bool_]
    paper_per_step: bool | npt.NDArray[np.bool_]
    rider_limits: bool


@dataclass(frozen=True)
class BatchFlags:
    """Static structure of a parameter batch: which branches run, on which slices.

    Attributes:
        any_sfm, any_replay: rider models present. any_cap, any_pid, any_replay_speed:
            ego modes present.
        delay_steps: [B] perception delay in steps. hist_len: H = max(delay) + 1 (1 when
            no CAP variant has a delay).
        is_sfm, is_cap, is_replay_speed, is_ctrl: [B] masks (ctrl = pid or cap).
        blocks: the maximal runs of variants with equal (ego mode, rider model), in batch
            order. :func:`simulate` sorts the batch so that there are at most six.
    """

    any_sfm: bool
    any_replay: bool
    any_cap: bool
    any_pid: bool
    any_replay_speed: bool
    delay_steps: npt.NDArray[np.intp]
    hist_len: int
    is_sfm: npt.NDArray[np.bool_]
    is_cap: npt.NDArray[np.bool_]
    is_replay_speed: npt.NDArray[np.bool_]
    is_ctrl: npt.NDArray[np.bool_]
    blocks: tuple[Block, ...]


def group_keys(params: VariantParams) -> npt.NDArray[np.int64]:
    """[B] group key 2 * ego_mode + rider_sfm (variants with equal keys share a block)."""
    return 2 * params.ego_mode.astype(np.int64) + params.rider_sfm.astype(np.int64)


def batch_flags(params: VariantParams, dt_s: float) -> BatchFlags:
    """The static BatchFlags of a parameter batch at step dt_s."""
    delay = params.delay_steps(dt_s)
    is_sfm = params.rider_sfm.copy()
    is_cap = params.ego_mode == EGO_CAP
    is_rs = params.ego_mode == EGO_REPLAY_SPEED
    keys = group_keys(params)
    cuts = np.concatenate([[0], np.flatnonzero(np.diff(keys)) + 1, [keys.size]])
    blocks = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        a, b = int(a), int(b)
        bp = params.take(slice(a, b)) if (a, b) != (0, keys.size) else params
        sfm = bool(bp.rider_sfm[0])
        cap = int(bp.ego_mode[0]) == EGO_CAP
        blocks.append(
            Block(
                start=a,
                stop=b,
                ego_mode=int(bp.ego_mode[0]),
                rider_sfm=sfm,
                params=bp,
                delay_steps=delay[a:b],
                paper_vdes=_switch(bp.paper_vdes) if sfm else False,
                vehicle_force=_switch(bp.use_vehicle_force) if sfm else False,
                front_bumper=_switch(bp.front_bumper) if sfm else False,
                paper_per_step=_switch(bp.paper_per_step) if cap else False,
                rider_limits=sfm
                and bool((np.isfinite(bp.max_speed_mps) | np.isfinite(bp.max_accel_mps2)).any()),
            )
        )
    return BatchFlags(
        any_sfm=bool(is_sfm.any()),
        any_replay=bool((~is_sfm).any()),
        any_cap=bool(is_cap.any()),
        any_pid=bool((params.ego_mode == EGO_PID).any()),
        any_replay_speed=bool(is_rs.any()),
        delay_steps=delay,
        hist_len=int(delay.max()) + 1 if bool((delay[is_cap] > 0).any()) else 1,
        is_sfm=is_sfm,
        is_cap=is_cap,
        is_replay_speed=is_rs,
        is_ctrl=~is_rs,
        blocks=tuple(blocks),
    )


# --------------------------------------------------------------------------------------
# Initial state and step
# --------------------------------------------------------------------------------------
_SPAN_EPS = 1e-9


def _rider_span(arrays: ScenarioArrays, t_rec: FloatArray) -> npt.NDArray[np.bool_]:
    tr = arrays.rider_track
    return (t_rec >= tr.t0_s - _SPAN_EPS) & (t_rec <= tr.t_end_s + _SPAN_EPS)


def _sub(a: npt.ArrayLike, idx: npt.NDArray[np.intp] | None) -> npt.ArrayLike:
    """a[idx] for arrays, a for scalars; idx None = everything."""
    if idx is None or np.ndim(a) == 0:
        return a
    return np.asarray(a)[idx]


def _collide_others(
    arrays: ScenarioArrays,
    k: int,
    ex: FloatArray,
    ey: FloatArray,
    eyaw: FloatArray,
    hit: npt.NDArray[np.bool_],
) -> npt.NDArray[np.bool_]:
    """Latch ego contacts with the replayed others at step k ([B, n_o]; copy if changed)."""
    if hit.shape[1] == 0:
        return hit
    act = np.flatnonzero(arrays.other_active[k])
    if act.size == 0:
        return hit
    reach = 0.5 * (
        np.hypot(arrays.ego_length_m, arrays.ego_width_m)
        + np.hypot(arrays.other_length_m, arrays.other_width_m)
    )
    out = hit
    for j in act:
        dx = arrays.other_x_m[k, j] - ex
        dy = arrays.other_y_m[k, j] - ey
        cand = np.flatnonzero((dx * dx + dy * dy <= reach[j] ** 2) & ~hit[:, j])
        if cand.size == 0:
            continue
        ov = boxes_overlap(
            ex[cand], ey[cand], eyaw[cand], arrays.ego_length_m, arrays.ego_width_m,
            arrays.other_x_m[k, j], arrays.other_y_m[k, j], arrays.other_yaw_rad[k, j],
            arrays.other_length_m[j], arrays.other_width_m[j],
        )  # fmt: skip
        if ov.any():
            if out is hit:
                out = hit.copy()
            out[cand[ov], j] = True
    return out


def initial_state(
    arrays: ScenarioArrays, params: VariantParams, flags: BatchFlags | None = None
) -> SimState:
    """The state at k = 0 (t = 0) for B variants.

    Ego at ``ego_start_s_m`` on its path (0 = the recorded start; negative = a run-up on
    the path's backwards extension) with ``initial_speed_mps``; CAP in CRUISE; PID
    with zero integral. Rider from the recording at recording time -time_shift_s: active
    if that lies in the track's span; before the span it waits (inactive) at the recorded
    first pose, after it at the last.

    Args:
        arrays: the scenario's arrays. params: [B] variants. flags: precomputed (optional).
    Returns:
        SimState at k = 0.
    """
    fl = flags or batch_flags(params, arrays.dt_s)
    b = params.batch_size
    z = np.zeros(b)
    s0 = params.ego_start_s_m.copy()
    ex, ey, eyaw = arrays.ego_path.lookup(s0)
    v0 = params.initial_speed_mps.copy()
    t_rec = -params.time_shift_s
    tr = arrays.rider_track
    i, w = tr.index(t_rec)
    rx, ry, ryaw, rsp, rvx, rvy, rarc = tr.values_at(
        i, w, "x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps", "arc_m"
    )
    inside = _rider_span(arrays, t_rec)
    collided = inside & boxes_overlap(
        ex,
        ey,
        eyaw,
        arrays.ego_length_m,
        arrays.ego_width_m,
        rx,
        ry,
        ryaw,
        arrays.rider_length_m,
        arrays.rider_width_m,
    )
    moving = inside & ~collided
    hist = np.zeros((4, fl.hist_len, b))
    hist[:, 0, :] = np.stack([rx, ry, ryaw, inside.astype(np.float64)])
    no = len(arrays.other_ids)
    hit = _collide_others(arrays, 0, ex, ey, eyaw, np.zeros((b, no), dtype=bool))
    return SimState(
        k=0,
        ego_s_m=s0,
        ego_x_m=ex,
        ego_y_m=ey,
        ego_yaw_rad=eyaw,
        ego_v_mps=np.where(collided, 0.0, v0),
        ego_a_mps2=z.copy(),
        ego_act_mps2=z.copy(),
        ego_cmd=z.copy(),
        pid_integral_m=z.copy(),
        pid_prev_error_mps=params.cruise_speed_mps - v0,
        cap_state=np.zeros(b, dtype=np.int8),
        rider_x_m=rx,
        rider_y_m=ry,
        rider_yaw_rad=ryaw,
        rider_vx_mps=np.where(moving, rvx, 0.0),
        rider_vy_mps=np.where(moving, rvy, 0.0),
        rider_speed_mps=np.where(moving, rsp, 0.0),
        rider_a_mps2=z.copy(),
        rider_prog_m=rarc,
        rider_active=inside,
        rider_started=inside.copy(),
        rider_done=np.zeros(b, dtype=bool),
        collided=collided,
        hit_other=hit,
        hist=hist,
    )


def _slice_state(st: SimState, a: int, b: int) -> SimState:
    fields = {}
    for name, val in zip(SimState._fields, st, strict=True):
        if name == "k":
            fields[name] = val
        elif name == "hist":
            fields[name] = val[:, :, a:b]
        else:
            fields[name] = val[a:b]
    return SimState(**fields)


def step(
    state: SimState, params: VariantParams, arrays: ScenarioArrays, flags: BatchFlags | None = None
) -> SimState:
    """Advance all B variants by one step (pure: returns a new state, mutates nothing).

    Args:
        state: SimState at step k. params: [B] variants. arrays: the scenario's arrays.
        flags: ``batch_flags(params, arrays.dt_s)``, precomputed once (optional).
    Returns:
        SimState at step k + 1.
    """
    fl = flags or batch_flags(params, arrays.dt_s)
    if len(fl.blocks) == 1:
        return SimState(k=state.k + 1, **_step_block(state, arrays, fl.blocks[0], fl.hist_len))
    outs = [
        _step_block(_slice_state(state, blk.start, blk.stop), arrays, blk, fl.hist_len)
        for blk in fl.blocks
    ]
    merged = {
        name: np.concatenate([o[name] for o in outs], axis=-1 if name == "hist" else 0)
        for name in outs[0]
    }
    return SimState(k=state.k + 1, **merged)


def _step_block(
    st: SimState, arrays: ScenarioArrays, blk: Block, hist_len: int
) -> dict[str, np.ndarray]:
    """One step of one homogeneous block; returns the new state's fields (k excluded)."""
    p = blk.params
    dt = arrays.dt_s
    k = st.k
    t_new = (k + 1) * dt
    collided = st.collided
    any_coll = bool(collided.any())
    b = collided.shape[0]
    L_e, W_e = arrays.ego_length_m, arrays.ego_width_m
    L_r, W_r = arrays.rider_length_m, arrays.rider_width_m
    path = arrays.ego_path

    # ---- 1-2. Ego --------------------------------------------------------------------
    v = st.ego_v_mps
    cap_state = st.cap_state
    pid_i, pid_e = st.pid_integral_m, st.pid_prev_error_mps
    if blk.ego_mode == EGO_REPLAY_SPEED:
        ti, tw = arrays.ego_track.index(t_new)
        s_rec, v_rec = arrays.ego_track.values_at(ti, tw, "s_m", "speed_mps")
        s_new = np.full(b, float(s_rec))
        v_new = np.full(b, float(v_rec))
        a_act = (v_new - v) / dt
        a_rep = a_act
        u = ego_model.accel_to_command(a_act, p.max_accel_mps2_ego, p.max_decel_mps2_ego)
    else:
        vd = p.cruise_speed_mps
        err = vd - v
        pid = ego_model.PIDState(pid_i, pid_e)
        braking = a_brake = None
        if blk.ego_mode == EGO_CAP:
            if hist_len == 1:
                px, py, pyaw, pact = st.rider_x_m, st.rider_y_m, st.rider_yaw_rad, st.rider_active
            else:
                lag_k = k - blk.delay_steps
                slot = np.mod(lag_k, hist_len)
                cols = np.arange(b)
                px = st.hist[0, slot, cols]
                py = st.hist[1, slot, cols]
                pyaw = st.hist[2, slot, cols]
                pact = (st.hist[3, slot, cols] > 0.5) & (lag_k >= 0)
            # Only variants that perceive an active rider can see it ahead.
            seen = pact & ~collided if any_coll else pact
            sidx = np.flatnonzero(seen)
            if sidx.size == b:
                ahead, gap = ego_model.corridor_check(
                    path, st.ego_s_m, L_e, px, py, pyaw, L_r, W_r, True,
                    p.corridor_half_width_m, p.detection_range_m,
                )  # fmt: skip
            else:
                ahead = np.zeros(b, dtype=bool)
                gap = np.full(b, np.inf)
                if sidx.size:
                    ahead[sidx], gap[sidx] = ego_model.corridor_check(
                        path, st.ego_s_m[sidx], L_e, px[sidx], py[sidx], pyaw[sidx], L_r, W_r, True,
                        p.corridor_half_width_m[sidx], p.detection_range_m[sidx],
                    )  # fmt: skip
            new_cap, a_brake, braking, entered = ego_model.cap_step(
                cap_state, v, vd, ahead, gap,
                t_safe_s=p.t_safe_s, d_buf_m=p.d_buf_m, a_min_mps2=p.a_min_mps2,
                release_margin_m=p.release_margin_m, recover_tolerance_mps=p.recover_tolerance_mps,
                paper_per_step=blk.paper_per_step,
            )  # fmt: skip
            cap_state = np.where(collided, cap_state, new_cap) if any_coll else new_cap
            if entered.any():
                pid = ego_model.pid_reset_where(pid, entered, err)
        u, pid_new = ego_model.pid_step(
            pid, err, dt, p.kp, p.ki, p.kd, p.integral_limit, p.integral_window_s
        )
        pid_i, pid_e = pid_new.integral_m, pid_new.prev_error_mps
        if braking is not None and braking.any():
            u = np.where(
                braking,
                ego_model.accel_to_command(a_brake, p.max_accel_mps2_ego, p.max_decel_mps2_ego),
                u,
            )
        a_cmd = ego_model.command_to_accel(u, p.max_accel_mps2_ego, p.max_decel_mps2_ego)
        a_act = ego_model.actuator_step(st.ego_act_mps2, a_cmd, p.actuator_lag_s, dt)
        v_new = ego_model.speed_step(v, a_act, dt)
        s_new = st.ego_s_m + v_new * dt
        # Reported acceleration: what changes the speed (0 while standing still).
        a_rep = np.where((v_new <= 0.0) & (a_act < 0.0), (v_new - v) / dt, a_act)
    if any_coll:  # frozen after a collision
        s_new = np.where(collided, st.ego_s_m, s_new)
        v_new = np.where(collided, 0.0, v_new)
        a_act = np.where(collided, 0.0, a_act)
        a_rep = np.where(collided, 0.0, a_rep)
        u = np.where(collided, 0.0, u)
    pi, pw = path.index(s_new)
    ex, ey, eyaw = path.values_at(pi, pw, "x", "y", "yaw")

    # ---- 3. Rider --------------------------------------------------------------------
    tr = arrays.rider_track
    t_rec = t_new - p.time_shift_s
    r_started, r_done = st.rider_started, st.rider_done
    if not blk.rider_sfm:
        in_span = _rider_span(arrays, t_rec)
        iidx = np.flatnonzero(in_span)
        if iidx.size == b:
            ri, rw = tr.index(t_rec)
            rx, ry, ryaw, rsp, rvx, rvy = tr.values_at(
                ri, rw, "x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps"
            )
        else:
            # Outside the span: the recorded first pose (before) or last pose (after), at rest.
            before = t_rec < tr.t0_s
            first, last = tr.data[0], tr.data[-1]
            cx, cy, cyaw = tr.col("x_m"), tr.col("y_m"), tr.col("yaw_rad")
            rx = np.where(before, first[cx], last[cx])
            ry = np.where(before, first[cy], last[cy])
            ryaw = np.where(before, first[cyaw], last[cyaw])
            rsp, rvx, rvy = np.zeros(b), np.zeros(b), np.zeros(b)
            if iidx.size:
                ri, rw = tr.index(t_rec[iidx])
                vals = tr.values_at(
                    ri, rw, "x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps"
                )
                for arr, val in zip((rx, ry, ryaw, rsp, rvx, rvy), vals, strict=True):
                    arr[iidx] = val
        r_active = in_span
        r_started = r_started | in_span
        r_done = r_done | (st.rider_started & ~in_span)
        r_prog = st.rider_prog_m
    else:
        rx, ry, ryaw = st.rider_x_m.copy(), st.rider_y_m.copy(), st.rider_yaw_rad.copy()
        rvx, rvy, rsp = st.rider_vx_mps.copy(), st.rider_vy_mps.copy(), st.rider_speed_mps.copy()
        r_prog, r_active = st.rider_prog_m.copy(), st.rider_active.copy()
        moving = st.rider_active & ~collided if any_coll else st.rider_active
        idx = np.flatnonzero(moving)
        if idx.size:
            sel = None if idx.size == b else idx
            _social_force_update(
                st, arrays, blk, sel, t_rec, dt, (rx, ry, ryaw, rvx, rvy, rsp, r_prog, r_active)
            )
            r_done = r_done | (st.rider_active & ~r_active)
        not_started = ~r_started
        if not_started.any():
            entering = np.flatnonzero(not_started & _rider_span(arrays, t_rec))
            if entering.size:
                ei, ew = tr.index(t_rec[entering])
                vals = tr.values_at(
                    ei, ew, "x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps", "arc_m"
                )
                for arr, val in zip((rx, ry, ryaw, rsp, rvx, rvy, r_prog), vals, strict=True):
                    arr[entering] = val
                r_active[entering] = True
                r_started = r_started.copy()
                r_started[entering] = True
    if any_coll:  # frozen after a collision (both stop; the rider stays in the scene)
        rx = np.where(collided, st.rider_x_m, rx)
        ry = np.where(collided, st.rider_y_m, ry)
        ryaw = np.where(collided, st.rider_yaw_rad, ryaw)
        rvx = np.where(collided, 0.0, rvx)
        rvy = np.where(collided, 0.0, rvy)
        rsp = np.where(collided, 0.0, rsp)
        r_active = np.where(collided, st.rider_active, r_active)
    r_acc = np.where(r_active & st.rider_active, (rsp - st.rider_speed_mps) / dt, 0.0)
    if any_coll:
        r_acc = np.where(collided, 0.0, r_acc)

    # ---- 4. Collision ----------------------------------------------------------------
    reach = 0.5 * (np.hypot(L_e, W_e) + np.hypot(L_r, W_r))
    dx, dy = rx - ex, ry - ey
    cand = r_active & (dx * dx + dy * dy <= reach * reach)
    if any_coll:
        cand &= ~collided
    cidx = np.flatnonzero(cand)
    collided_new = collided
    if cidx.size:
        ov = boxes_overlap(
            ex[cidx], ey[cidx], eyaw[cidx], L_e, W_e, rx[cidx], ry[cidx], ryaw[cidx], L_r, W_r
        )
        hits = cidx[ov]
        if hits.size:
            collided_new = collided.copy()
            collided_new[hits] = True
            # Fresh arrays of this step (never shared with the previous state) or copies.
            v_new, a_act, a_rep = (
                v_new.copy(),
                np.array(a_act, copy=True),
                np.array(a_rep, copy=True),
            )
            rvx, rvy, rsp, r_acc = rvx.copy(), rvy.copy(), rsp.copy(), r_acc.copy()
            for arr in (v_new, a_act, a_rep, rvx, rvy, rsp, r_acc):
                arr[hits] = 0.0
    hit_other = _collide_others(arrays, k + 1, ex, ey, eyaw, st.hit_other)

    hist = st.hist
    if hist_len > 1:
        hist = hist.copy()
        slot = (k + 1) % hist_len
        hist[0, slot] = rx
        hist[1, slot] = ry
        hist[2, slot] = ryaw
        hist[3, slot] = r_active
    return {
        "ego_s_m": s_new,
        "ego_x_m": ex,
        "ego_y_m": ey,
        "ego_yaw_rad": eyaw,
        "ego_v_mps": v_new,
        "ego_a_mps2": a_rep,
        "ego_act_mps2": a_act,
        "ego_cmd": u,
        "pid_integral_m": pid_i,
        "pid_prev_error_mps": pid_e,
        "cap_state": cap_state,
        "rider_x_m": rx,
        "rider_y_m": ry,
        "rider_yaw_rad": ryaw,
        "rider_vx_mps": rvx,
        "rider_vy_mps": rvy,
        "rider_speed_mps": rsp,
        "rider_a_mps2": r_acc,
        "rider_prog_m": r_prog,
        "rider_active": r_active,
        "rider_started": r_started,
        "rider_done": r_done,
        "collided": collided_new,
        "hit_other": hit_other,
        "hist": hist,
    }


def _social_force_update(
    st: SimState,
    arrays: ScenarioArrays,
    blk: Block,
    sel: npt.NDArray[np.intp] | None,
    t_rec: FloatArray,
    dt: float,
    out: tuple[np.ndarray, ...],
) -> None:
    """Social-force step of the moving riders ``sel`` (None = all), written into ``out``.

    ``out`` = (x, y, yaw, vx, vy, speed, progress, active) arrays of this step (fresh
    copies, modified in place at ``sel``).
    """
    p = blk.params
    g = _sub
    x0, y0 = g(st.rider_x_m, sel), g(st.rider_y_m, sel)
    vx0, vy0 = g(st.rider_vx_mps, sel), g(st.rider_vy_mps, sel)
    prog0 = g(st.rider_prog_m, sel)
    rp = arrays.rider_path
    # Progress along the own recorded path: one local projection step, never backwards.
    i, w = rp.index(prog0)
    px, py, pc, ps = rp.values_at(i, w, "x", "y", "cos", "sin")
    prog = np.maximum(prog0 + (x0 - px) * pc + (y0 - py) * ps, prog0)
    i, w = rp.index(np.minimum(prog + g(p.lookahead_m, sel), rp.length_m))
    gx, gy = rp.values_at(i, w, "x", "y")
    vdx, vdy = sfm_model.desired_velocity(
        x0, y0, gx, gy, g(p.v0_mps, sel), g(p.sigma_m, sel), _sub(blk.paper_vdes, sel)
    )
    fx, fy = sfm_model.destination_force(vdx, vdy, vx0, vy0, g(p.k_des_nspm, sel))
    vf = blk.vehicle_force
    if vf is not False:
        ex, ey, eyaw = g(st.ego_x_m, sel), g(st.ego_y_m, sel), g(st.ego_yaw_rad, sel)
        qx, qy = sfm_model.influential_point(
            x0,
            y0,
            ex,
            ey,
            eyaw,
            arrays.ego_length_m,
            arrays.ego_width_m,
            _sub(blk.front_bumper, sel),
        )
        hx, hy = sfm_model.vehicle_force(
            x0, y0, qx, qy, g(p.a_veh_n, sel), g(p.b_veh_per_m, sel), ex, ey, eyaw
        )
        if vf is True:
            fx, fy = fx + hx, fy + hy
        else:
            use = _sub(vf, sel)
            fx, fy = fx + np.where(use, hx, 0.0), fy + np.where(use, hy, 0.0)
    mass = g(p.mass_kg, sel)
    if blk.rider_limits:
        fmag = np.sqrt(fx * fx + fy * fy)
        fmax = g(p.max_accel_mps2, sel) * mass
        scale = np.where(fmag > fmax, fmax / np.where(fmag > 0, fmag, 1.0), 1.0)
        fx, fy = fx * scale, fy * scale
    nx, ny, nvx, nvy = sfm_model.point_mass_step(x0, y0, vx0, vy0, fx, fy, mass, dt)
    nsp = np.sqrt(nvx * nvx + nvy * nvy)
    if blk.rider_limits:
        vmax = g(p.max_speed_mps, sel)
        sc = np.where(nsp > vmax, vmax / np.where(nsp > 0, nsp, 1.0), 1.0)
        nvx, nvy, nsp = nvx * sc, nvy * sc, nsp * sc
        nx, ny = x0 + nvx * dt, y0 + nvy * dt
    nyaw = np.where(nsp > 0.05, np.arctan2(nvy, nvx), g(st.rider_yaw_rad, sel))
    # Leaves once at the final point of its path and the recording's span is over.
    fxe, fye = float(rp.end_x_m), float(rp.end_y_m)
    arrived = (nx - fxe) ** 2 + (ny - fye) ** 2 <= np.square(g(p.arrive_radius_m, sel))
    leaving = arrived & (g(t_rec, sel) > arrays.rider_track.t_end_s + _SPAN_EPS)
    rx, ry, ryaw, rvx, rvy, rsp, r_prog, r_active = out
    s = slice(None) if sel is None else sel
    rx[s] = nx
    ry[s] = ny
    ryaw[s] = nyaw
    rvx[s] = np.where(leaving, 0.0, nvx)
    rvy[s] = np.where(leaving, 0.0, nvy)
    rsp[s] = np.where(leaving, 0.0, nsp)
    r_prog[s] = prog
    r_active[s] = ~leaving


# --------------------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SimResult:
    """Outputs of a batched run. Time series are ``[B, T]`` (transposed views of the
    engine's time-major buffers); ``None`` when the run used ``record="none"``.

    Attributes:
        t_s: [T] step times [s].
        labels: [B] configuration name of each variant.
        params: the VariantParams that ran.
        scenario_id, rider_id, rider_category: identities.
        ego_length_m, ego_width_m, rider_length_m, rider_width_m: footprints [m].
        ego_s_m, ego_x_m, ego_y_m, ego_yaw_rad, ego_speed_mps: [B, T] ego path position
            [m], pose [m, rad], speed [m/s].
        ego_accel_mps2: [B, T] longitudinal acceleration (actuator; 0 standing / after a
            collision: the crash itself shows as the speed drop, not as an acceleration).
        ego_command: [B, T] the command u in [-1, 1] applied during the step that ended
            here (0 at k = 0). cap_state: [B, T] int8 (0 CRUISE, 1 BRAKE, 2 RECOVER; 0 for
            non-CAP variants).
        rider_x_m, rider_y_m, rider_yaw_rad, rider_speed_mps, rider_vx_mps, rider_vy_mps,
            rider_accel_mps2: [B, T] the primary rider (finite while inactive: first /
            last pose, speed 0). rider_active: [B, T] bool.
        collided: [B, T] bool latch of the ego / rider collision.
        hit_other: [B, T, n_o] bool latch, the ego touched replayed other j.
        collision_time_s: [B] first collision time [s] (NaN if none) (always present).
        min_center_distance_m: [B] minimum ego-rider centre distance while the rider is
            active [m] (inf if never active) (always present).
        other_ids, other_categories, other_length_m, other_width_m: replayed others.
        other_x_m, other_y_m, other_yaw_rad, other_speed_mps, other_active: [T, n_o]
            (the same for every variant).
        final_state: the SimState at the last step.
    """

    t_s: FloatArray
    labels: npt.NDArray[np.object_]
    params: VariantParams
    scenario_id: str
    rider_id: str
    rider_category: str
    ego_length_m: float
    ego_width_m: float
    rider_length_m: float
    rider_width_m: float
    ego_s_m: FloatArray | None
    ego_x_m: FloatArray | None
    ego_y_m: FloatArray | None
    ego_yaw_rad: FloatArray | None
    ego_speed_mps: FloatArray | None
    ego_accel_mps2: FloatArray | None
    ego_command: FloatArray | None
    cap_state: npt.NDArray[np.int8] | None
    rider_x_m: FloatArray | None
    rider_y_m: FloatArray | None
    rider_yaw_rad: FloatArray | None
    rider_speed_mps: FloatArray | None
    rider_vx_mps: FloatArray | None
    rider_vy_mps: FloatArray | None
    rider_accel_mps2: FloatArray | None
    rider_active: npt.NDArray[np.bool_] | None
    collided: npt.NDArray[np.bool_] | None
    hit_other: npt.NDArray[np.bool_] | None
    collision_time_s: FloatArray
    min_center_distance_m: FloatArray
    other_ids: tuple[str, ...]
    other_categories: tuple[str, ...]
    other_length_m: FloatArray
    other_width_m: FloatArray
    other_x_m: FloatArray
    other_y_m: FloatArray
    other_yaw_rad: FloatArray
    other_speed_mps: FloatArray
    other_active: npt.NDArray[np.bool_]
    final_state: SimState

    @property
    def batch_size(self) -> int:
        """B."""
        return int(self.labels.shape[0])

    @property
    def collision(self) -> npt.NDArray[np.bool_]:
        """[B] bool: the ego and the primary rider collided at some step."""
        return np.isfinite(self.collision_time_s)

    def _require(self) -> None:
        if self.ego_x_m is None:
            raise ConfigError("this SimResult was run with record='none': no time series")

    def to_trace(self, variant_slice: slice | Sequence[int] | int | None = None) -> Trace:
        """Ego vs primary rider as a :class:`vei.types.Trace` (copies, C-contiguous).

        Args:
            variant_slice: which variants (slice, index list or int); None = all.
        Returns:
            Trace with B' = the selected variants.
        """
        self._require()
        sel: slice | npt.NDArray[np.intp]
        if variant_slice is None:
            sel = slice(None)
        elif isinstance(variant_slice, slice):
            sel = variant_slice
        else:
            sel = np.atleast_1d(np.asarray(variant_slice, dtype=np.intp))

        def c(a: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(a[sel])

        return Trace(
            t_s=self.t_s.copy(),
            ego_xy_m=np.stack([c(self.ego_x_m), c(self.ego_y_m)], axis=-1),
            ego_yaw_rad=c(self.ego_yaw_rad),
            ego_speed_mps=c(self.ego_speed_mps),
            ego_accel_mps2=c(self.ego_accel_mps2),
            other_xy_m=np.stack([c(self.rider_x_m), c(self.rider_y_m)], axis=-1),
            other_yaw_rad=c(self.rider_yaw_rad),
            other_speed_mps=c(self.rider_speed_mps),
            other_vel_mps=np.stack([c(self.rider_vx_mps), c(self.rider_vy_mps)], axis=-1),
            other_active=c(self.rider_active),
            collided=c(self.collided),
            ego_length_m=self.ego_length_m,
            ego_width_m=self.ego_width_m,
            other_length_m=self.rider_length_m,
            other_width_m=self.rider_width_m,
        )

    def to_frame(
        self,
        config_name: str | Sequence[str] | None = None,
        variant_slice: slice | Sequence[int] | int | None = None,
        *,
        include_others: bool = True,
    ) -> pd.DataFrame:
        """Long-format time series with columns ``vei.types.TIMESERIES_COLUMNS``.

        One row per agent per step per variant: the ego, the primary rider (all steps,
        ``active`` telling presence) and, if ``include_others``, each replayed road user
        over the steps where it is present. ``collided`` is the ego/rider latch for both
        of them and the ego-contact latch for the others. ``accel_mps2`` of the others is
        the finite difference of their speed. ``cap_state`` is set on ego rows of CAP
        variants only.

        Args:
            config_name: name written in the ``config`` column: one string for all the
                selected variants, one per variant, or None = the variants' labels.
            variant_slice: which variants (None = all); ``variant`` keeps the batch index.
            include_others: add the replayed other road users.
        Returns:
            DataFrame sorted by (variant, t_s, agent order: ego, rider, others).
        """
        self._require()
        b, t = self.batch_size, self.t_s.shape[0]
        if variant_slice is None:
            idx = np.arange(b)
        elif isinstance(variant_slice, slice):
            idx = np.arange(b)[variant_slice]
        else:
            idx = np.atleast_1d(np.asarray(variant_slice, dtype=np.intp))
        nb = idx.size
        if config_name is None:
            names = np.asarray(self.labels[idx], dtype=object)
        elif isinstance(config_name, str):
            names = np.full(nb, config_name, dtype=object)
        else:
            names = np.asarray(list(config_name), dtype=object)
            if names.size != nb:
                raise ConfigError(f"config_name has {names.size} names for {nb} variants")
        cap_names = np.array(["CRUISE", "BRAKE", "RECOVER"], dtype=object)
        is_cap = self.params.ego_mode[idx] == EGO_CAP
        tt = np.broadcast_to(self.t_s, (nb, t))
        var = np.broadcast_to(idx[:, None], (nb, t))
        cfg = np.broadcast_to(names[:, None], (nb, t))
        ego_cap = np.where(is_cap[:, None], cap_names[self.cap_state[idx]], "")
        parts = [
            {
                "config": cfg, "variant": var, "t_s": tt, "agent_id": EGO_ID, "category": EGO_CATEGORY,
                "x_m": self.ego_x_m[idx], "y_m": self.ego_y_m[idx], "yaw_rad": self.ego_yaw_rad[idx],
                "speed_mps": self.ego_speed_mps[idx], "accel_mps2": self.ego_accel_mps2[idx],
                "active": np.ones((nb, t), dtype=bool), "collided": self.collided[idx], "cap_state": ego_cap,
            },
            {
                "config": cfg, "variant": var, "t_s": tt, "agent_id": self.rider_id,
                "category": self.rider_category, "x_m": self.rider_x_m[idx], "y_m": self.rider_y_m[idx],
                "yaw_rad": self.rider_yaw_rad[idx], "speed_mps": self.rider_speed_mps[idx],
                "accel_mps2": self.rider_accel_mps2[idx], "active": self.rider_active[idx],
                "collided": self.collided[idx], "cap_state": "",
            },
        ]  # fmt: skip
        frames = []
        for order, part in enumerate(parts):
            frames.append(_flatten(part, nb, t, order))
        if include_others:
            for j, oid in enumerate(self.other_ids):
                act = self.other_active[:, j]
                acc = np.zeros(t)
                if t > 1:
                    acc[1:] = np.diff(self.other_speed_mps[:, j]) / (self.t_s[1] - self.t_s[0])
                part = {
                    "config": cfg, "variant": var, "t_s": tt, "agent_id": oid,
                    "category": self.other_categories[j],
                    "x_m": np.broadcast_to(self.other_x_m[:, j], (nb, t)),
                    "y_m": np.broadcast_to(self.other_y_m[:, j], (nb, t)),
                    "yaw_rad": np.broadcast_to(self.other_yaw_rad[:, j], (nb, t)),
                    "speed_mps": np.broadcast_to(self.other_speed_mps[:, j], (nb, t)),
                    "accel_mps2": np.broadcast_to(acc, (nb, t)),
                    "active": np.broadcast_to(act, (nb, t)),
                    "collided": self.hit_other[idx, :, j], "cap_state": "",
                }  # fmt: skip
                df = _flatten(part, nb, t, 2 + j)
                frames.append(df[np.broadcast_to(act, (nb, t)).ravel()])
        out = pd.concat(frames, ignore_index=True)
        out = out.sort_values(["variant", "t_s", "_order"], kind="stable").drop(columns="_order")
        out = out.reset_index(drop=True)
        out["variant"] = out["variant"].astype(np.int64)
        for col in ("config", "agent_id", "category", "cap_state"):
            out[col] = out[col].astype(str)
        return out[list(TIMESERIES_COLUMNS)]


def _flatten(part: dict, nb: int, t: int, order: int) -> pd.DataFrame:
    cols = {}
    for key, val in part.items():
        if isinstance(val, str):
            cols[key] = np.full(nb * t, val, dtype=object)
        else:
            cols[key] = np.asarray(val).reshape(nb * t)
    cols["_order"] = np.full(nb * t, order, dtype=np.int16)
    return pd.DataFrame(cols)


# --------------------------------------------------------------------------------------
# Simulation loop
# --------------------------------------------------------------------------------------
_RECORDED = (
    ("ego_s_m", "ego_s_m", np.float64),
    ("ego_x_m", "ego_x_m", np.float64),
    ("ego_y_m", "ego_y_m", np.float64),
    ("ego_yaw_rad", "ego_yaw_rad", np.float64),
    ("ego_speed_mps", "ego_v_mps", np.float64),
    ("ego_accel_mps2", "ego_a_mps2", np.float64),
    ("ego_command", "ego_cmd", np.float64),
    ("cap_state", "cap_state", np.int8),
    ("rider_x_m", "rider_x_m", np.float64),
    ("rider_y_m", "rider_y_m", np.float64),
    ("rider_yaw_rad", "rider_yaw_rad", np.float64),
    ("rider_speed_mps", "rider_speed_mps", np.float64),
    ("rider_vx_mps", "rider_vx_mps", np.float64),
    ("rider_vy_mps", "rider_vy_mps", np.float64),
    ("rider_accel_mps2", "rider_a_mps2", np.float64),
    ("rider_active", "rider_active", np.bool_),
    ("collided", "collided", np.bool_),
)


def simulate(
    arrays: ScenarioArrays,
    params: VariantParams,
    *,
    record: Record = "full",
    progress: bool = False,
    kernel: Kernel = "numpy",
) -> SimResult:
    """Run B variants of one scenario over the whole span (arrays.t_s).

    Args:
        arrays: from :func:`prepare_scenario` (fixes dt and the span).
        params: [B] variants.
        record: 'full' = every time series [B, T] (memory ~ 16 float64 x B x T);
            'none' = only the summaries (collision time, minimum centre distance) and the
            final state (sweeps that score online, benchmarks).
        progress: show a rich progress bar (when stderr is a terminal; NumPy kernel).
        kernel: 'numpy' (default): the reference, :func:`step` in a loop; 'numba': the
            compiled kernel :mod:`vei.sim.kernel` (same model, ~10-50x faster at large B,
            needs numba; agrees with 'numpy' to rounding, not bit for bit); 'auto':
            'numba' when importable, else 'numpy'. Each kernel on its own is deterministic
            and batch-invariant (B single runs equal one batch of B, bit for bit).
    Returns:
        SimResult.
    """
    if record not in ("full", "none"):
        raise ConfigError(f"record must be 'full' or 'none', got {record!r}")
    if kernel not in ("numpy", "numba", "auto"):
        raise ConfigError(f"kernel must be 'numpy', 'numba' or 'auto', got {kernel!r}")
    from vei.sim import kernel as compiled

    use_numba = kernel == "numba" or (kernel == "auto" and compiled.available())
    # Group the variants into contiguous blocks of equal (ego mode, rider model); the
    # outputs are put back into the caller's order at the end.
    keys = group_keys(params)
    perm = np.argsort(keys, kind="stable")
    sorted_already = bool(np.all(perm == np.arange(perm.size)))
    run_params = params if sorted_already else params.take(perm)
    fl = batch_flags(run_params, arrays.dt_s)
    b, t_n = params.batch_size, arrays.n_steps
    no = len(arrays.other_ids)
    state = initial_state(arrays, run_params, fl)
    bufs: dict[str, np.ndarray] = {}
    hit_buf = None
    if record == "full":
        for name, _, dtype in _RECORDED:
            bufs[name] = np.empty((t_n, b), dtype=dtype)
        hit_buf = np.empty((t_n, b, no), dtype=bool)
    coll_t = np.full(b, np.nan)
    min_d = np.full(b, np.inf)

    def _rec(st: SimState) -> None:
        k = st.k
        if bufs:
            for name, attr, _ in _RECORDED:
                bufs[name][k] = getattr(st, attr)
            hit_buf[k] = st.hit_other
        newly = st.collided & np.isnan(coll_t)
        if newly.any():
            coll_t[newly] = arrays.t_s[k]
        dx = st.rider_x_m - st.ego_x_m
        dy = st.rider_y_m - st.ego_y_m
        d = np.sqrt(dx * dx + dy * dy)
        np.minimum(min_d, np.where(st.rider_active, d, np.inf), out=min_d)

    if use_numba:
        out = compiled.run(arrays, run_params, state, fl.hist_len, record == "full")
        # Variant-major [B, T] series: store as time-major views so that the common
        # code below ([T, B] buffers, transposed at the end) applies.
        if out["series"] is not None:
            bufs = {name: arr.T for name, arr in out["series"].items()}
            hit_buf = out["hit"].transpose(1, 0, 2)
        coll_t, min_d = out["collision_time_s"], out["min_center_distance_m"]
        state = SimState(**out["final"])
    else:
        _rec(state)
        bar = None
        task = None
        if progress:
            import sys

            if sys.stderr.isatty():
                from rich.progress import Progress

                bar = Progress(transient=True)
                bar.start()
                task = bar.add_task(f"simulating {b} variant(s)", total=t_n - 1)
        try:
            for _ in range(1, t_n):
                state = step(state, run_params, arrays, fl)
                _rec(state)
                if bar is not None:
                    bar.advance(task)
        finally:
            if bar is not None:
                bar.stop()
    if not sorted_already:
        inv = np.empty_like(perm)
        inv[perm] = np.arange(perm.size)
        for name in bufs:
            bufs[name] = bufs[name][:, inv]
        if hit_buf is not None:
            hit_buf = hit_buf[:, inv]
        coll_t, min_d = coll_t[inv], min_d[inv]
        state = SimState(
            **{
                name: (val if name == "k" else val[:, :, inv] if name == "hist" else val[inv])
                for name, val in zip(SimState._fields, state, strict=True)
            }
        )
    series: dict[str, np.ndarray | None] = {
        name: (bufs[name].T if bufs else None) for name, _, _ in _RECORDED
    }
    return SimResult(
        t_s=arrays.t_s.copy(),
        labels=params.labels.copy(),
        params=params,
        scenario_id=arrays.scenario_id,
        rider_id=arrays.rider_id,
        rider_category=arrays.rider_category,
        ego_length_m=arrays.ego_length_m,
        ego_width_m=arrays.ego_width_m,
        rider_length_m=arrays.rider_length_m,
        rider_width_m=arrays.rider_width_m,
        hit_other=None if hit_buf is None else hit_buf.transpose(1, 0, 2),
        collision_time_s=coll_t,
        min_center_distance_m=min_d,
        other_ids=arrays.other_ids,
        other_categories=arrays.other_categories,
        other_length_m=arrays.other_length_m,
        other_width_m=arrays.other_width_m,
        other_x_m=arrays.other_x_m,
        other_y_m=arrays.other_y_m,
        other_yaw_rad=arrays.other_yaw_rad,
        other_speed_mps=arrays.other_speed_mps,
        other_active=arrays.other_active,
        final_state=state,
        **series,
    )


def run_cases(
    scenario: Scenario | ScenarioArrays,
    cases: Sequence[str | CaseConfig],
    *,
    time_shift_s: float = 0.0,
    sim: SimConfig | None = None,
    record: Record = "full",
    kernel: Kernel = "numpy",
) -> SimResult:
    """Run several configurations (names of CASE_PRESETS or CaseConfigs) as one batch.

    Variant i is ``cases[i]`` with the same time shift; ``labels`` are the case names.

    Args:
        scenario: a Scenario (prepared with ``sim``) or already prepared arrays.
        cases: e.g. ``PAPER_CASES``. time_shift_s: the rider's time shift [s].
        sim: engine settings (ignored when arrays are passed).
        record, kernel: as :func:`simulate`.
    Returns:
        SimResult with B = len(cases).
    """
    arrays = scenario if isinstance(scenario, ScenarioArrays) else prepare_scenario(scenario, sim)
    parts = []
    for c in cases:
        case = c if isinstance(c, CaseConfig) else case_preset(c)
        parts.append(VariantParams.from_case(case, arrays, 1, time_shift_s=time_shift_s))
    if not parts:
        raise ConfigError("run_cases needs at least one configuration")
    return simulate(arrays, VariantParams.concat(parts), record=record, kernel=kernel)


__all__ = [
    "CASE_PRESETS",
    "BatchFlags",
    "Block",
    "group_keys",
    "SimResult",
    "batch_flags",
    "initial_state",
    "prepare_scenario",
    "run_cases",
    "simulate",
    "step",
]
