"""The NumPy reference step of the built-in engine (pure: new state out, nothing mutated).

See :mod:`vei.sim.engine` for the order of operations within one step.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.boxes import boxes_overlap
from vei.errors import ConfigError
from vei.models import ego as ego_model
from vei.models import ego_core
from vei.models import sfm as sfm_model
from vei.sim.batch import BatchFlags, Block, batch_flags
from vei.sim.contacts import (
    collide_ego_others,
    contact_step,
    initial_contact_state,
    others_now,
)
from vei.sim.decisions import decide_block
from vei.sim.observe import Demand
from vei.sim.obstacles import obstacle_block
from vei.sim.pedestrians import (
    PED_FIELDS,
    initial_pedestrian_state,
    pedestrian_step,
    rider_from_pedestrians,
)
from vei.sim.riders import (
    EXTRA_BOOL_FIELDS,
    EXTRA_FLOAT_FIELDS,
    initial_extra_state,
    pedestrian_sources,
    repulsion,
    step_extras,
)
from vei.sim.state import (
    EGO_CAP,
    EGO_POLICY,
    EGO_REPLAY_SPEED,
    ScenarioArrays,
    SimState,
    VariantParams,
)
from vei.sim.traffic import CAR_FLOAT_FIELDS, initial_traffic_state, traffic_step

FloatArray = npt.NDArray[np.float64]
_CAR_FIELDS = (*CAR_FLOAT_FIELDS, "car_mode")
_EXTRA_FIELDS = EXTRA_FLOAT_FIELDS + EXTRA_BOOL_FIELDS

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
    # an SFM rider on a standing run-in is present but replayed until its SFM entry
    started = inside & (~params.rider_sfm | (t_rec >= arrays.rider_sfm_entry_s - _SPAN_EPS))
    hist = np.zeros((4, fl.hist_len, b))
    hist[:, 0, :] = np.stack([rx, ry, ryaw, inside.astype(np.float64)])
    no = len(arrays.other_ids)
    hit = collide_ego_others(arrays, 0, ex, ey, eyaw, np.zeros((b, no), dtype=bool))
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
        rider_started=started,
        rider_done=np.zeros(b, dtype=bool),
        collided=collided,
        hit_other=hit,
        hist=hist,
        **initial_extra_state(arrays.riders, b, params.rider_sfm),
        rider_decision=np.zeros(b, dtype=np.int8),
        **initial_traffic_state(arrays, b),
        **initial_contact_state(b, no, arrays.traffic.n),
        **initial_pedestrian_state(arrays, b),
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
    state: SimState,
    params: VariantParams,
    arrays: ScenarioArrays,
    flags: BatchFlags | None = None,
    action: Demand | None = None,
) -> SimState:
    """Advance all B variants by one step (pure: returns a new state, mutates nothing).

    Args:
        state: SimState at step k. params: [B] variants. arrays: the scenario's arrays.
        flags: ``batch_flags(params, arrays.dt_s)``, precomputed once (optional).
        action: the demands of the policy variants (ego_mode 3) at step k, [B] arrays
            (vei.sim.observe.PolicyDriver.act); required when the batch has any.
    Returns:
        SimState at step k + 1.
    """
    fl = flags or batch_flags(params, arrays.dt_s)
    if fl.any_policy and action is None:
        raise ConfigError(
            "the batch has policy variants (ego_mode 'policy'): step() needs their demand "
            "(vei.sim.observe.PolicyDriver.act(state))"
        )

    def _act(blk: Block) -> Demand | None:
        if action is None or blk.policy is None:
            return None
        sl = slice(blk.start, blk.stop)
        return Demand(action.accel_mps2[sl], action.command[sl], action.fsm_state[sl])

    if len(fl.blocks) == 1:
        blk = fl.blocks[0]
        return SimState(k=state.k + 1, **_step_block(state, arrays, blk, fl.hist_len, _act(blk)))
    outs = [
        _step_block(_slice_state(state, blk.start, blk.stop), arrays, blk, fl.hist_len, _act(blk))
        for blk in fl.blocks
    ]
    merged = {
        name: np.concatenate([o[name] for o in outs], axis=-1 if name == "hist" else 0)
        for name in outs[0]
    }
    return SimState(k=state.k + 1, **merged)


def _step_block(
    st: SimState, arrays: ScenarioArrays, blk: Block, hist_len: int, act: Demand | None = None
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
    elif blk.ego_mode == EGO_POLICY:
        u, a_cmd = _policy_demand(act, p)
        if act.fsm_state is not None:
            cap_state = np.where(collided, cap_state, act.fsm_state) if any_coll else act.fsm_state
        a_act = ego_model.actuator_step(st.ego_act_mps2, a_cmd, p.actuator_lag_s, dt)
        v_new = ego_model.speed_step(v, a_act, dt)
        s_new = st.ego_s_m + v_new * dt
        a_rep = np.asarray(ego_core.reported_accel_core(v, v_new, a_act, dt))
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
        a_rep = np.asarray(ego_core.reported_accel_core(v, v_new, a_act, dt))
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
        r_dec = st.rider_decision
    else:
        rx, ry, ryaw = st.rider_x_m.copy(), st.rider_y_m.copy(), st.rider_yaw_rad.copy()
        rvx, rvy, rsp = st.rider_vx_mps.copy(), st.rider_vy_mps.copy(), st.rider_speed_mps.copy()
        r_prog, r_active = st.rider_prog_m.copy(), st.rider_active.copy()
        r_dec = st.rider_decision.copy()
        moving = st.rider_active & st.rider_started
        if any_coll:
            moving = moving & ~collided
        idx = np.flatnonzero(moving)
        if idx.size:
            sel = None if idx.size == b else idx
            _social_force_update(
                st, arrays, blk, sel, t_rec, dt,
                (rx, ry, ryaw, rvx, rvy, rsp, r_prog, r_active, r_dec),
            )  # fmt: skip
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
                # before its SFM entry (a standing run-in) the rider stands replayed
                go = t_rec[entering] >= arrays.rider_sfm_entry_s - _SPAN_EPS
                r_started = r_started.copy()
                r_started[entering] = go
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
    cars = {f: getattr(st, f) for f in _CAR_FIELDS}
    peds = {f: getattr(st, f) for f in PED_FIELDS}
    poses = None
    if arrays.peds.n and blk.peds is not False:  # pedestrians (vei.sim.pedestrians)
        moving = cars if arrays.traffic.n and blk.traffic is not False else None
        peds = pedestrian_step(st, arrays, p, blk.peds, dt, moving)
    if arrays.traffic.n and blk.traffic is not False:  # reacting cars (vei.sim.traffic)
        cars = traffic_step(st, arrays, p, blk.traffic, dt)
    moved_cars = cars if arrays.traffic.n and blk.traffic is not False else None
    moved_peds = peds if arrays.peds.n and blk.peds is not False else None
    if moved_cars is not None or moved_peds is not None:
        kn = min(k + 1, arrays.n_steps - 1)
        poses = others_now(arrays, kn, b, moved_cars, moved_peds)[:3]
    hit_other = collide_ego_others(arrays, k + 1, ex, ey, eyaw, st.hit_other, poses)

    extras = {}
    if arrays.riders.n:
        extras = step_extras(st, arrays, p, blk.rider_sfm, t_new, (ex, ey, eyaw))
    hist = st.hist
    if hist_len > 1:
        hist = hist.copy()
        slot = (k + 1) % hist_len
        hist[0, slot] = rx
        hist[1, slot] = ry
        hist[2, slot] = ryaw
        hist[3, slot] = r_active
    out = {
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
        **(extras or {f: getattr(st, f) for f in _EXTRA_FIELDS}),
        "rider_decision": r_dec,
        **cars,
        **peds,
    }
    # contacts between any two road users, the secondary collisions (vei.sim.contacts)
    out.update(contact_step(st, out, arrays, blk.traffic, blk.peds))
    return out


def _policy_demand(act: Demand | None, p: VariantParams) -> tuple[FloatArray, FloatArray]:
    """(u [b], demanded acceleration [b]) of a policy block: a command is mapped with the
    actuator limits, an acceleration clipped to [-max_decel, max_accel]."""
    if act is None:
        raise ConfigError("a policy block needs its demand (step(..., action=...))")
    cmd = act.command
    given = ~np.isnan(cmd)
    amax, dmax = p.max_accel_mps2_ego, p.max_decel_mps2_ego
    if given.all():
        u = np.clip(cmd, -1.0, 1.0)
        return u, ego_model.command_to_accel(u, amax, dmax)
    a_cmd = np.clip(act.accel_mps2, -dmax, amax)
    u = ego_model.accel_to_command(a_cmd, amax, dmax)
    if given.any():
        u = np.where(given, np.clip(np.where(given, cmd, 0.0), -1.0, 1.0), u)
        a_cmd = np.where(given, ego_model.command_to_accel(u, amax, dmax), a_cmd)
    return u, a_cmd


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

    ``out`` = (x, y, yaw, vx, vy, speed, progress, active, decision) arrays of this step
    (fresh copies, modified in place at ``sel``). Where the block's riders decide
    (``blk.decide``, vei.sim.decisions) their desired velocity is capped by their yield
    decision's speed.
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
    if blk.decide is not False and arrays.conflicts.n:
        vdx, vdy = decide_block(st, arrays, blk, sel, prog0, prog, vdx, vdy, out[8])
    if blk.obstacle is not False:  # braking for a standing or slow car in its way
        vdx, vdy = obstacle_block(st, arrays, blk, sel, x0, y0, vdx, vdy)
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
    rr = arrays.riders
    if rr.enabled:  # several riders: repulsion from the extra riders and pedestrians
        sources = [
            (
                st.extra_x_m[:, m] if sel is None else st.extra_x_m[sel, m],
                st.extra_y_m[:, m] if sel is None else st.extra_y_m[sel, m],
                st.extra_active[:, m] if sel is None else st.extra_active[sel, m],
                float(rr.radius_m[m]),
            )
            for m in range(rr.n)
        ]
        ps = p if sel is None else p.take(sel)
        peds = pedestrian_sources(arrays, st.k)
        if blk.peds is not False and arrays.peds.n:  # the simulated ones act instead
            off = ~np.asarray(_sub(blk.peds, sel), dtype=bool)
            peds = [(qx, qy, np.logical_and(a, off), r) for qx, qy, a, r in peds]
        hx, hy = repulsion(x0, y0, rr.primary_radius_m, ps, sources + peds)
        fx, fy = fx + hx, fy + hy
    if blk.peds is not False and arrays.peds.n:  # social-force pedestrians repel the rider
        fx, fy = rider_from_pedestrians(st, arrays, blk, sel, x0, y0, fx, fy)
    mass = g(p.mass_kg, sel)
    if blk.rider_limits:
        fx, fy = sfm_model.cap_force(fx, fy, g(p.max_accel_mps2, sel) * mass)
    nx, ny, nvx, nvy = sfm_model.point_mass_step(x0, y0, vx0, vy0, fx, fy, mass, dt)
    nsp = np.sqrt(nvx * nvx + nvy * nvy)
    if blk.rider_limits:
        nx, ny, nvx, nvy, nsp = sfm_model.cap_speed(
            x0, y0, nx, ny, nvx, nvy, nsp, g(p.max_speed_mps, sel), dt
        )
    nyaw = np.where(nsp > 0.05, np.arctan2(nvy, nvx), g(st.rider_yaw_rad, sel))
    # Leaves once at the final point of its path and the recording's span is over.
    fxe, fye = float(rp.end_x_m), float(rp.end_y_m)
    arrived = (nx - fxe) ** 2 + (ny - fye) ** 2 <= np.square(g(p.arrive_radius_m, sel))
    leaving = arrived & (g(t_rec, sel) > arrays.rider_track.t_end_s + _SPAN_EPS)
    rx, ry, ryaw, rvx, rvy, rsp, r_prog, r_active = out[:8]
    s = slice(None) if sel is None else sel
    rx[s] = nx
    ry[s] = ny
    ryaw[s] = nyaw
    rvx[s] = np.where(leaving, 0.0, nvx)
    rvy[s] = np.where(leaving, 0.0, nvy)
    rsp[s] = np.where(leaving, 0.0, nsp)
    r_prog[s] = prog
    r_active[s] = ~leaving
