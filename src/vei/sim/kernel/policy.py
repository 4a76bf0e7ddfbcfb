"""Ego policies inside the compiled kernel: ``aeb``, ``idm`` and users' compiled policies.

Imported only when numba is used. One policy step of one variant from step k: the
observation of :class:`vei.policy.observation.Observation` built from the perception ring
(every road user's ground truth, delayed by the variant's perception delay; ideal
perception), the policy's demand (the built-in ``aeb`` / ``idm`` as in
:mod:`vei.policy.aeb` / :mod:`vei.policy.idm`, or a user's function of
:mod:`vei.policy.compiled`), and the ego's response to it as the NumPy step's policy
branch (:func:`vei.sim.step._policy_demand`, clipped demand, actuator lag, speed).
Same formulas and order of operations as the NumPy path, on scalars. SI units.

The kernel's ``pol`` group (:func:`vei.sim.kernel.policy_pack.policy_group`):
(fns, kind [B], PP [N_PP, B], ST0 [B, S], OBJ [4, N] (the road users' lengths, widths
[m], category codes, half diagonals [m]), Hp the ring length, the ego path's length [m], BAD [B] int64 (the
first step a user's function returned a non-finite value, -1: none), BADV [B] (that
value), OTR [6, T, no] the replayed others' truth per step (x, y, yaw, vx, vy, active));
the ring [Hp, 6, N] holds the truth of the primary and the extra riders and, where the
variant's cars react, of the reacting cars (:func:`put_cars`: a driven car at its engine
pose, as vei.sim.observe.ground_truth); the other others are read from OTR at the delayed
step. fns is a 1-tuple of the user's function (numba first-class
function type: one compiled kernel for every user function; such runs go through
vei.sim.kernel.loop.kernel_seq) or None (built-in policies only: numba's parallel loop).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math

import numba
import numpy as np
from numba import types
from numba.extending import overload

from vei.models import traffic_core
from vei.policy.aeb import AEB_FULL, AEB_PARTIAL, HOLD_SPEED_MPS, MIN_CLOSING_SPEED_MPS
from vei.policy.compiled import (
    E_ACCEL,
    E_COLLIDED,
    E_CRUISE,
    E_DT,
    E_LENGTH,
    E_MAX_ACCEL,
    E_MAX_DECEL,
    E_PATH_LEN,
    E_S,
    E_SPEED,
    E_T,
    E_WIDTH,
    N_EGO,
    N_OBJ,
    O_AGE,
    O_CATEGORY,
    O_GAP,
    O_LATERAL,
    O_LENGTH,
    O_VALID,
    O_VX,
    O_VY,
    O_WIDTH,
    O_X,
    O_Y,
    O_YAW,
)  # fmt: skip
from vei.policy.idm import MIN_GAP_M
from vei.sim.kernel.corridor import corridor_at, lateral_at, path_point
from vei.sim.kernel.ego import (
    accel_to_command,
    actuator,
    command_to_accel,
    pid_core,
    reported_accel,
    speed,
)
from vei.sim.kernel.policy_pack import (
    KIND_AEB,
    KIND_IDM,
    KIND_USER,
    PP_AEB_FULL_A,
    PP_AEB_PART_A,
    PP_FULL,
    PP_IDM_A,
    PP_IDM_B,
    PP_IDM_DELTA,
    PP_IDM_S0,
    PP_IDM_T,
    PP_PARTIAL,
    PP_WARN,
)  # fmt: skip

_INF = np.inf


def user_call(fns, ego, objs, state):  # type: ignore[no-untyped-def]
    """The user's function fns[0] on (ego, objs, state) -> demanded acceleration [m/s^2];
    0.0 when fns is None (a run of built-in policies only: no function value in the
    kernel's arguments, so numba's parallel loop can run it). Compiled by its overload."""
    return 0.0 if fns is None else fns[0](ego, objs, state)


@overload(user_call, jit_options={"cache": True})
def _user_call(fns, ego, objs, state):  # type: ignore[no-untyped-def]
    if isinstance(fns, types.NoneType):
        return lambda fns, ego, objs, state: 0.0
    return lambda fns, ego, objs, state: fns[0](ego, objs, state)


@numba.njit(cache=True, inline="always")
def put_truth(ring, slot, j, x, y, yaw, vx, vy, act):  # type: ignore[no-untyped-def]
    """Road user j's ground truth (pose, velocity [m/s], active) into slot ``slot`` of the
    ring [Hp, 6, N]. (Each array an inlined function takes costs two atomic reference
    count updates per call: the per-step functions here take only the arrays they use.)"""
    ring[slot, 0, j] = x
    ring[slot, 1, j] = y
    ring[slot, 2, j] = yaw
    ring[slot, 3, j] = vx
    ring[slot, 4, j] = vy
    ring[slot, 5, j] = 1.0 if act else 0.0


@numba.njit(cache=True, inline="always")
def put_cars(ring, eng, slot, k, OTR, tidx, cfl, cmode):  # type: ignore[no-untyped-def]
    """The reacting cars' ground truth of step k into slot ``slot`` of the ring [Hp, 6, N]
    (vei.sim.observe.ground_truth): a car the engine drives (cmode > REACTING) at its pose
    (cfl rows 3-5) with its speed (cfl row 1) along its heading, a replaying one as its
    recording OTR [6, T, no]; presence is the recording's. tidx [C]: the cars' indices
    among the others; eng [no]: marks their columns as read from the ring."""
    nr = ring.shape[2] - OTR.shape[2]
    for c in range(tidx.shape[0]):
        jo = tidx[c]
        eng[jo] = True
        if cmode[c] > traffic_core.REACTING:
            yaw, sp = cfl[5, c], cfl[1, c]
            put_truth(ring, slot, nr + jo, cfl[3, c], cfl[4, c], yaw, sp * math.cos(yaw),
                      sp * math.sin(yaw), OTR[5, k, jo] > 0.5)  # fmt: skip
        else:
            for r in range(6):
                ring[slot, r, nr + jo] = OTR[r, k, jo]


@numba.njit(cache=True)
def policy_state0(pol, b, mode):  # type: ignore[no-untyped-def]
    """Variant b's policy scratch: (on, memory, ring [Hp, 6, N], objs [N_OBJ, N], ego
    [N_EGO], eng [no]); on: the variant runs a policy here (ego mode 3); eng: the replayed
    others the ring holds (reacting cars, :func:`put_cars`), the rest read from OTR."""
    kind, ST0, Hp = pol[1], pol[3], pol[5]
    n = pol[4].shape[1]
    on = mode == 3 and kind[b] > 0
    if kind[b] == KIND_USER:
        mem = ST0[b].copy()
    else:
        mem = np.zeros(4)  # aeb: stage, PID integral, previous error, PID started
    no = pol[9].shape[2]
    eng = np.zeros(no, dtype=np.bool_)
    return on, mem, np.zeros((Hp, 6, n)), np.zeros((N_OBJ, n)), np.zeros(N_EGO), eng


@numba.njit(cache=True, inline="always")
def _observe(
    k, dt, full, OBJ, ring, OTR, eng, objs, Hp, delay, s, ex, ey, eyaw, v, collided, path, p_s0,
    p_ds, n_p, Le, halfw, rng,
):  # type: ignore[no-untyped-def]  # fmt: skip
    """The object rows of the observation at step k (vei.sim.observe.build_observation on
    the truth of step k - delay: the ring's, OTR's for the replayed others the ring does
    not hold (eng [no] False)) into objs; full: every row, else valid, rel_vx, gap only
    (what aeb and idm read)."""
    lag_k = k - delay
    slot = lag_k % Hp
    ok = lag_k >= 0
    c, sn = math.cos(eyaw), math.sin(eyaw)
    evx, evy = v * c, v * sn
    nr = OBJ.shape[1] - OTR.shape[2]  # the primary and the extra riders (in the ring)
    q = path_point(path, p_s0, p_ds, n_p, s)  # the first projection of every object
    for j in range(OBJ.shape[1]):
        jo = j - nr
        in_ring = j < nr or eng[jo]
        if in_ring:
            valid = ok and ring[slot, 5, j] > 0.5
        else:
            valid = ok and OTR[5, lag_k, jo] > 0.5
        if full:
            objs[O_LENGTH, j] = OBJ[0, j]
            objs[O_WIDTH, j] = OBJ[1, j]
            objs[O_CATEGORY, j] = OBJ[2, j]
        if not valid:
            objs[O_VALID, j] = 0.0
            objs[O_VX, j] = 0.0
            objs[O_GAP, j] = _INF
            if full:
                objs[O_X, j] = 0.0
                objs[O_Y, j] = 0.0
                objs[O_YAW, j] = 0.0
                objs[O_VY, j] = 0.0
                objs[O_AGE, j] = _INF
                objs[O_LATERAL, j] = _INF
            continue
        if in_ring:
            ox, oy, oyaw = ring[slot, 0, j], ring[slot, 1, j], ring[slot, 2, j]
            dvx, dvy = ring[slot, 3, j] - evx, ring[slot, 4, j] - evy
        else:
            ox, oy, oyaw = OTR[0, lag_k, jo], OTR[1, lag_k, jo], OTR[2, lag_k, jo]
            dvx, dvy = OTR[3, lag_k, jo] - evx, OTR[4, lag_k, jo] - evy
        objs[O_VALID, j] = 1.0
        objs[O_VX, j] = dvx * c + dvy * sn
        gap = _INF
        if not collided:  # vei.models.ego.corridor_check for one object
            ahead, g = corridor_at(
                path, p_s0, p_ds, n_p, s, q, ox, oy, oyaw, OBJ[0, j], OBJ[1, j], OBJ[3, j], Le,
                halfw, rng,
            )  # fmt: skip
            if ahead:
                gap = g
        objs[O_GAP, j] = gap
        if full:
            dx, dy = ox - ex, oy - ey
            objs[O_X, j] = dx * c + dy * sn
            objs[O_Y, j] = -dx * sn + dy * c
            objs[O_YAW, j] = math.pi - ((math.pi - (oyaw - eyaw)) % (2.0 * math.pi))
            objs[O_VY, j] = -dvx * sn + dvy * c
            objs[O_AGE, j] = delay * dt
            objs[O_LATERAL, j] = lateral_at(path, p_s0, p_ds, n_p, s, q, ox, oy)


@numba.njit(cache=True, inline="always")
def _aeb(objs, mem, PP, n, b, v, vd, dt, ec):  # type: ignore[no-untyped-def]
    """(demanded acceleration [m/s^2], stage) of vei.policy.aeb.AEB.act for one variant;
    its memory mem = (stage, PID integral, previous error, PID started) updated."""
    ttc = _INF
    in_path = False
    for j in range(n):
        if objs[O_VALID, j] > 0.5:
            g = objs[O_GAP, j]
            if math.isfinite(g):
                in_path = True
                closing = -objs[O_VX, j]
                if closing > MIN_CLOSING_SPEED_MPS:
                    ttc = min(ttc, g / closing)
    raw = 0
    if ttc <= PP[PP_FULL, b]:
        raw = 3
    elif ttc <= PP[PP_PARTIAL, b]:
        raw = 2
    elif ttc <= PP[PP_WARN, b]:
        raw = 1
    prev = int(mem[0])
    stage = raw
    if prev >= AEB_PARTIAL and in_path and (math.isfinite(ttc) or v < HOLD_SPEED_MPS):
        stage = max(prev, raw)
    amax, dmax, decay, ki, lim, kp, kd = ec[0], ec[1], ec[10], ec[11], ec[12], ec[13], ec[14]
    err = vd - v
    pid_i, pid_e = (mem[1], mem[2]) if mem[3] > 0.5 else (0.0, err)
    u, pid_i = pid_core(err, pid_i, pid_e, dt, decay, lim, kp, ki, kd)
    pid_e = err
    if prev >= AEB_PARTIAL and stage < AEB_PARTIAL:  # released: restart the PID
        pid_i = 0.0
        pid_e = err
    mem[0], mem[1], mem[2], mem[3] = stage, pid_i, pid_e, 1.0
    if stage == AEB_FULL:
        return -PP[PP_AEB_FULL_A, b], stage
    if stage == AEB_PARTIAL:
        return -PP[PP_AEB_PART_A, b], stage
    return command_to_accel(min(max(u, -1.0), 1.0), amax, dmax), stage


@numba.njit(cache=True, inline="always")
def _idm(objs, PP, n, b, v, vd):  # type: ignore[no-untyped-def]
    """Demanded acceleration [m/s^2] of vei.policy.idm.IDM.act for one variant."""
    gap = _INF
    jb = 0
    for j in range(n):
        g = objs[O_GAP, j] if objs[O_VALID, j] > 0.5 else _INF
        if g < gap:
            gap, jb = g, j
    lead = math.isfinite(gap)
    v_lead = v + objs[O_VX, jb]
    dv = v - v_lead if lead else 0.0
    a = PP[PP_IDM_A, b]
    free = 1.0 - (v / vd) ** PP[PP_IDM_DELTA, b]
    s_star = PP[PP_IDM_S0, b] + max(
        0.0, v * PP[PP_IDM_T, b] + v * dv / (2.0 * math.sqrt(a * PP[PP_IDM_B, b]))
    )
    s = max(gap if lead else 1.0, MIN_GAP_M)
    inter = (s_star / s) ** 2 if lead else 0.0
    return a * (free - inter)


@numba.njit(cache=True, inline="always")
def policy_ego(  # type: ignore[no-untyped-def]
    k, dt, pol, scr, b, ec, vd, delay, s, ex, ey, eyaw, v, a_act, a_rep, cap, collided, egeo, Le, We,
):  # fmt: skip
    """The ego of a policy variant from step k to k + 1: observe, the policy's demand, the
    ego's response (vei.sim.step's policy branch). scr = policy_state0's (on, mem, ring,
    objs, ego, eng). Returns (s_new, v_new, a_act_n, a_rep_n, u, cap) like ego_step_c's first
    five and the recorded policy state (cap_state)."""
    kind = pol[1][b]
    amax, dmax, halfw, rng, alpha = ec[0], ec[1], ec[2], ec[3], ec[15]
    _observe(k, dt, kind == KIND_USER, pol[4], scr[2], pol[9], scr[5], scr[3], pol[5], delay, s, ex, ey,
             eyaw, v, collided, egeo[0], egeo[1], egeo[2], egeo[3], Le, halfw, rng)  # fmt: skip
    fsm = 0
    if kind == KIND_AEB:
        acc, fsm = _aeb(scr[3], scr[1], pol[2], pol[4].shape[1], b, v, vd, dt, ec)
    elif kind == KIND_IDM:
        acc = _idm(scr[3], pol[2], pol[4].shape[1], b, v, vd)
    else:
        scr[4][E_T], scr[4][E_DT], scr[4][E_SPEED], scr[4][E_ACCEL] = k * dt, dt, v, a_rep
        scr[4][E_S], scr[4][E_PATH_LEN], scr[4][E_CRUISE] = s, pol[6], vd
        scr[4][E_MAX_ACCEL], scr[4][E_MAX_DECEL], scr[4][E_LENGTH] = amax, dmax, Le
        scr[4][E_WIDTH], scr[4][E_COLLIDED] = We, 1.0 if collided else 0.0
        acc = user_call(pol[0], scr[4], scr[3], scr[1])
        if not math.isfinite(acc):
            if pol[7][b] < 0:
                pol[7][b], pol[8][b] = k, acc
            acc = 0.0
    a_cmd = min(max(acc, -dmax), amax)
    u = accel_to_command(a_cmd, amax, dmax)
    a_act_n = actuator(a_act, a_cmd, alpha)
    v_new = speed(v, a_act_n, dt)
    s_new = s + v_new * dt
    a_rep_n = reported_accel(v, v_new, a_act_n, dt)
    if collided:
        return s, 0.0, 0.0, 0.0, 0.0, cap
    return s_new, v_new, a_act_n, a_rep_n, u, fsm


__all__ = ["policy_ego", "policy_state0", "put_cars", "put_truth", "user_call"]
