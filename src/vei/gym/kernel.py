"""The vector environment's compiled step and observation (numba; imported only when used).

The model is the built-in engine's for a policy-driven ego (ego_mode 'policy') with the
primary rider replayed or social-force driven (with its obstacle braking and yield / go
decision) and every other road user replayed
(:func:`vei.sim.step.step`, order of operations in :mod:`vei.sim.engine`), one step of B
environments each at its own step index k (autoreset puts them out of step, which the
engine's shared ``SimState.k`` cannot express). The laws are not written again: the ego's
actuator, speed and reported acceleration are :mod:`vei.models.ego_core`'s functions and
the rider's social force, obstacle braking, integration and limits
:mod:`vei.sim.kernel.sfm`'s and its decision :mod:`vei.sim.kernel.decision`'s (the
engine's compiled kernel's), compiled here on scalars; the box overlap is
:mod:`vei.boxes`'s; the observation's corridor gap and lateral offset are
:mod:`vei.sim.kernel.corridor`'s (the engine kernel's CAP and policies use them too). A test
checks every state field and observation entry against the engine's NumPy step.

Packed arrays (:mod:`vei.gym.core` builds them), S scenarios, B environments:
  FS [15, B] float state: s x y yaw v a_rep a_act rx ry ryaw rvx rvy rsp racc prog;
  BS [5, B] uint8: rider active, started, done, collided, decision (0 FREE, 1 GO, 2 YIELD);
  HIT [B, O] uint8 (others touched);
  K [B] step index, SC [B] scenario index, SHIFT [B] the rider's time shift [s].
  Scenario tables padded to the longest: EP [S, 10, Np] ego path (x y yaw cos sin, then
  slopes) on s0 + i ds; RT [S, 14, M] rider track (x y yaw speed vx vy arc, then slopes) on
  t0 + i dt, rt_sfm0 [S] the recording time [s] from which an SFM rider is driven (it is
  replayed before: its run-in); RP [S, 10, N] rider path; others OX, OY, OYAW, OSP [S, T, O], OACT [S, T, O];
  CF [S, 5, Kc] the rider's conflicts with the ego path (zone exit, crossing along the
  rider's and the ego's path, half-lengths [m]; vei.sim.decisions.Conflicts), cf_n [S].
"""

# ruff: noqa: N803, N806, E501
from __future__ import annotations

import math

import numba
import numpy as np

from vei.boxes import overlap_core
from vei.models import ego_core as core
from vei.sim.kernel.corridor import corridor_at, half_diagonal, lateral_at, path_point
from vei.sim.kernel.decision import decide_step, reference_speed
from vei.sim.kernel.layout import (
    P_AMAX,
    P_AMAX_R,
    P_ARR,
    P_ARRIVE,
    P_AVEH,
    P_BRR,
    P_BVEH,
    P_CLEARM,
    P_DECIDE,
    P_DMAX,
    P_FRONTB,
    P_HALFW,
    P_HORIZON,
    P_KDES,
    P_LOOK,
    P_MASS,
    P_OBST,
    P_OBSTA,
    P_OBSTM,
    P_OBSTV,
    P_PAPERV,
    P_RANGE,
    P_SFM,
    P_SIGMA,
    P_STOPM,
    P_TC,
    P_USERF,
    P_USEVF,
    P_V0,
    P_VD,
    P_VMAX,
    P_YDEC,
)
from vei.sim.kernel.scalar import idx, ped_forces, rforce
from vei.sim.kernel.sfm import (
    capped_velocity,
    destination_force,
    goal_velocity,
    integrate,
    obstacle_velocity,
    vehicle_force,
)

_inline = numba.njit(cache=True, inline="always")
actuator = _inline(core.actuator_core)
speed = _inline(core.speed_core)
reported_accel = _inline(core.reported_accel_core)
sat = numba.njit(cache=True)(overlap_core)

# Float state rows.
F_S, F_X, F_Y, F_YAW, F_V, F_AREP, F_AACT = 0, 1, 2, 3, 4, 5, 6
F_RX, F_RY, F_RYAW, F_RVX, F_RVY, F_RSP, F_RACC, F_PROG = 7, 8, 9, 10, 11, 12, 13, 14
N_FS = 15
# Bool / small-integer state rows (B_DEC: the rider's decision, 0 FREE, 1 GO, 2 YIELD).
B_ACT, B_STARTED, B_DONE, B_COLL, B_DEC = 0, 1, 2, 3, 4
N_BS = 5
#: Rows of PREV [N_PREV, B] (step_envs writes them, the post-passes read them): the ego's
#: x, y, yaw [m, rad], speed [m/s], arc length [m], the primary rider's x, y [m], active
#: (0 / 1), speed [m/s] and yaw [rad], all at step k (before the step).
N_PREV = 10
# Reward terms (columns of TERMS).
T_CONTACTS, T_IMPACT, T_PROGRESS, T_COMFORT = 0, 1, 2, 3


@numba.njit(cache=True, inline="always")
def _path_xyyaw(EP, sc, s0, ds, n, s):  # type: ignore[no-untyped-def]
    i, w = idx(s0, ds, n, s)
    return (
        EP[sc, 0, i] + w * EP[sc, 5, i],
        EP[sc, 1, i] + w * EP[sc, 6, i],
        EP[sc, 2, i] + w * EP[sc, 7, i],
    )


@numba.njit(cache=True, nogil=True, _nrt=False)
def step_envs(  # type: ignore[no-untyped-def]
    run, A, dt, FS, BS, HIT, K, SC, SHIFT,
    P, ALPHA, DIM,
    EP, ep_s0, ep_ds, ep_n,
    RT, rt_t0, rt_dt, rt_tend, rt_n, rt_sfm0,
    RP, rp_s0, rp_ds, rp_n, rp_len, rp_ex, rp_ey,
    OX, OY, OYAW, OACT, OL, OW, n_o,
    CF, cf_n, xr, PREV,
    TERMS,
):  # fmt: skip
    """Advance the environments with ``run[b]`` by one step with demand A[b] [m/s^2].

    Writes the new state in place (FS, BS, HIT, K, the extra riders' XS, XB) and TERMS[b] =
    (new contacts (the rider, the others, the extra riders), impact speed [m/s] of a new
    rider contact or NaN, progress [m] (up to v_d dt), a_rep^2 dt [m^2/s^3]).

    ``xr``: None (no extra riders: not compiled), or the extra social-force riders
    (vei.gym.packed.ExtraRiders.group() then XS [B, 9, R] floats, XB [B, 4, R] bools:
    vei.sim.riders' EXTRA_FLOAT_FIELDS / EXTRA_BOOL_FIELDS, their scratch NXS [9, R],
    NXB [4, R]): they repel the primary rider here (their step-k state), and
    :func:`vei.gym.riders_kernel.step_riders` steps them next (the engine kernel's order).
    PREV [N_PREV, B] (:data:`N_PREV`) receives the ego's and the rider's step-k state, which
    the post-passes (the extra riders, the reacting cars of :mod:`vei.gym.cars_kernel`) read.
    OACT: the others' presence for the ego's contact test; where cars react the caller
    blanks their columns (their poses are the post-pass's, which tests them).
    """
    B = A.shape[0]
    if xr is not None:
        (
            x_n, XTAB, xt0, xdt, xtend, xnr, xsfm0, XPATH, xps0, xpds, xpn, xplen, xpex, xpey,
            xL, xW, xrad, xv0, xvmax, prad, rep_on, PED, PRAD, n_ped, XDN, XDC, XS, XB, NXS, NXB,
        ) = xr  # fmt: skip
    for b in range(B):
        if not run[b]:
            continue
        sc = SC[b]
        k = K[b]
        t_new = (k + 1) * dt
        Le, We, Lr, Wr = DIM[sc, 0], DIM[sc, 1], DIM[sc, 2], DIM[sc, 3]
        s, v, a_act = FS[F_S, b], FS[F_V, b], FS[F_AACT, b]
        ex, ey, eyaw = FS[F_X, b], FS[F_Y, b], FS[F_YAW, b]
        rx, ry, ryaw = FS[F_RX, b], FS[F_RY, b], FS[F_RYAW, b]
        rvx, rvy, rsp, prog = FS[F_RVX, b], FS[F_RVY, b], FS[F_RSP, b], FS[F_PROG, b]
        r_act = BS[B_ACT, b] > 0
        r_started = BS[B_STARTED, b] > 0
        r_done = BS[B_DONE, b] > 0
        collided = BS[B_COLL, b] > 0
        rdec = int(BS[B_DEC, b])
        # ---- ego: the policy's demand, clipped, through the actuator (vei.sim.step)
        amax, dmax = P[P_AMAX, sc], P[P_DMAX, sc]
        a_cmd = min(max(A[b], -dmax), amax)
        a_act_n = actuator(a_act, a_cmd, ALPHA[sc])
        v_new = speed(v, a_act_n, dt)
        s_new = s + v_new * dt
        a_rep_n = reported_accel(v, v_new, a_act_n, dt)
        if collided:
            s_new, v_new, a_act_n, a_rep_n = s, 0.0, 0.0, 0.0
        ex_n, ey_n, eyaw_n = _path_xyyaw(EP, sc, ep_s0[sc], ep_ds[sc], ep_n[sc], s_new)
        # ---- rider (vei.sim.kernel.loop, the primary rider)
        shift = SHIFT[b]
        t_rec = t_new - shift
        r_t0, r_dt, r_tend, n_r = rt_t0[sc], rt_dt[sc], rt_tend[sc], rt_n[sc]
        in_span = t_rec >= r_t0 - 1e-9 and t_rec <= r_tend + 1e-9
        prev_x, prev_y, prev_yaw, prev_sp, prev_act = rx, ry, ryaw, rsp, r_act
        if P[P_SFM, sc] <= 0.5:
            if in_span:
                i, w = idx(r_t0, r_dt, n_r, t_rec)
                nrx = RT[sc, 0, i] + w * RT[sc, 7, i]
                nry = RT[sc, 1, i] + w * RT[sc, 8, i]
                nryaw = RT[sc, 2, i] + w * RT[sc, 9, i]
                nrsp = RT[sc, 3, i] + w * RT[sc, 10, i]
                nrvx = RT[sc, 4, i] + w * RT[sc, 11, i]
                nrvy = RT[sc, 5, i] + w * RT[sc, 12, i]
            else:
                j0 = 0 if t_rec < r_t0 else n_r - 1
                nrx, nry, nryaw = RT[sc, 0, j0], RT[sc, 1, j0], RT[sc, 2, j0]
                nrsp = nrvx = nrvy = 0.0
            n_act = in_span
            if r_started and not in_span:
                r_done = True
            r_started = r_started or in_span
            nprog = prog
        else:
            nrx, nry, nryaw, nrvx, nrvy, nrsp, nprog, n_act = (
                rx,
                ry,
                ryaw,
                rvx,
                rvy,
                rsp,
                prog,
                r_act,
            )
            if r_act and r_started and not collided:
                look, vmax, amax_r = P[P_LOOK, sc], P[P_VMAX, sc], P[P_AMAX_R, sc]
                sigma, v0, kdes = P[P_SIGMA, sc], P[P_V0, sc], P[P_KDES, sc]
                tau = P[P_MASS, sc] / kdes
                vdx, vdy, pr = goal_velocity(
                    rx, ry, prog, RP[sc], rp_s0[sc], rp_ds[sc], rp_n[sc], rp_len[sc],
                    look, sigma, P[P_PAPERV, sc] > 0.5, v0,
                )  # fmt: skip
                if cf_n[sc] > 0 and P[P_DECIDE, sc] > 0.5:  # yield / go (vei.sim.decisions)
                    conf = (cf_n[sc], CF[sc, 0], CF[sc, 1], CF[sc, 2], CF[sc, 3], CF[sc, 4])
                    rdec, vcap = decide_step(
                        rdec, prog, pr, rsp, s, v, conf, P[P_TC, sc], P[P_HORIZON, sc],
                        P[P_YDEC, sc], P[P_STOPM, sc], P[P_CLEARM, sc],
                        reference_speed(v0, look, sigma), tau,
                    )  # fmt: skip
                    vdx, vdy = capped_velocity(vdx, vdy, vcap)
                if P[P_OBST, sc] > 0.5 and v < P[P_OBSTV, sc]:  # a standing / slow car ahead
                    vdx, vdy = obstacle_velocity(
                        rx, ry, vdx, vdy, rsp, ex, ey, eyaw, Le, We, 0.5 * math.hypot(Lr, Wr),
                        P[P_OBSTM, sc], P[P_OBSTA, sc], tau,
                    )  # fmt: skip
                fx, fy = destination_force(vdx, vdy, rvx, rvy, kdes)
                if P[P_USEVF, sc] > 0.5:
                    vfx, vfy = vehicle_force(
                        rx, ry, ex, ey, eyaw, Le, We, P[P_FRONTB, sc] > 0.5, P[P_AVEH, sc], P[P_BVEH, sc]
                    )  # fmt: skip
                    fx = fx + vfx
                    fy = fy + vfy
                if xr is not None:  # repelled by the extra riders and pedestrians at step k
                    if rep_on[sc] and P[P_USERF, sc] > 0.5:
                        a_rr, b_rr = P[P_ARR, sc], P[P_BRR, sc]
                        sx = 0.0
                        sy = 0.0
                        for mm in range(x_n[sc]):
                            if XB[b, 0, mm]:
                                hx_, hy_ = rforce(
                                    rx, ry, XS[b, 0, mm], XS[b, 1, mm], prad[sc] + xrad[sc, mm],
                                    a_rr, b_rr,
                                )  # fmt: skip
                                sx += hx_
                                sy += hy_
                        if n_ped[sc] > 0:  # (its views cost a reference count each)
                            sx, sy = ped_forces(
                                sx, sy, rx, ry, prad[sc], k, PED[sc, : n_ped[sc]],
                                PRAD[sc, : n_ped[sc]], OX[sc], OY[sc], OACT[sc], a_rr, b_rr,
                            )  # fmt: skip
                        fx = fx + sx
                        fy = fy + sy
                limits = math.isfinite(vmax) or math.isfinite(amax_r)
                x2, y2, vx2, vy2, sp2 = integrate(
                    rx, ry, rvx, rvy, fx, fy, P[P_MASS, sc], amax_r, vmax, dt, limits
                )  # fmt: skip
                yaw2 = math.atan2(vy2, vx2) if sp2 > 0.05 else ryaw
                arrived = (x2 - rp_ex[sc]) ** 2 + (y2 - rp_ey[sc]) ** 2 <= P[P_ARRIVE, sc] ** 2
                leaving = arrived and t_rec > r_tend + 1e-9
                nrx, nry, nryaw = x2, y2, yaw2
                if leaving:
                    nrvx = nrvy = nrsp = 0.0
                else:
                    nrvx, nrvy, nrsp = vx2, vy2, sp2
                nprog = pr
                n_act = not leaving
                if r_act and not n_act:
                    r_done = True
            if not r_started and in_span:
                i, w = idx(r_t0, r_dt, n_r, t_rec)
                nrx = RT[sc, 0, i] + w * RT[sc, 7, i]
                nry = RT[sc, 1, i] + w * RT[sc, 8, i]
                nryaw = RT[sc, 2, i] + w * RT[sc, 9, i]
                nrsp = RT[sc, 3, i] + w * RT[sc, 10, i]
                nrvx = RT[sc, 4, i] + w * RT[sc, 11, i]
                nrvy = RT[sc, 5, i] + w * RT[sc, 12, i]
                nprog = RT[sc, 6, i] + w * RT[sc, 13, i]
                n_act = True
                # before its SFM entry (a standing run-in) it stands replayed
                r_started = t_rec >= rt_sfm0[sc] - 1e-9
        if collided:
            nrx, nry, nryaw = prev_x, prev_y, prev_yaw
            nrvx = nrvy = nrsp = 0.0
            n_act = prev_act
        r_acc = (nrsp - prev_sp) / dt if (n_act and prev_act) else 0.0
        if collided:
            r_acc = 0.0
        contacts = 0.0
        # the step-k state the post-passes see (vei.gym.riders_kernel, vei.gym.cars_kernel)
        PREV[0, b], PREV[1, b], PREV[2, b], PREV[3, b], PREV[4, b] = ex, ey, eyaw, v, s
        PREV[5, b], PREV[6, b], PREV[7, b] = rx, ry, 1.0 if r_act else 0.0
        PREV[8, b], PREV[9, b] = rsp, ryaw
        # ---- collision
        impact = np.nan
        if n_act and not collided:
            reach = 0.5 * (math.hypot(Le, We) + math.hypot(Lr, Wr))
            ddx, ddy = nrx - ex_n, nry - ey_n
            if ddx * ddx + ddy * ddy <= reach * reach:
                if sat(ex_n, ey_n, eyaw_n, Le, We, nrx, nry, nryaw, Lr, Wr):
                    collided = True
                    contacts += 1.0
                    if prev_act and k >= 0:  # the approach of the last step (severity)
                        impact = math.hypot(v * math.cos(eyaw) - rvx, v * math.sin(eyaw) - rvy)
                    v_new = 0.0
                    a_act_n = 0.0
                    a_rep_n = 0.0
                    nrvx = nrvy = nrsp = 0.0
                    r_acc = 0.0
        for j in range(n_o[sc]):
            if OACT[sc, k + 1, j] and HIT[b, j] == 0:
                rr = 0.5 * (math.hypot(Le, We) + math.hypot(OL[sc, j], OW[sc, j]))
                ddx, ddy = OX[sc, k + 1, j] - ex_n, OY[sc, k + 1, j] - ey_n
                if ddx * ddx + ddy * ddy <= rr * rr:
                    if sat(ex_n, ey_n, eyaw_n, Le, We, OX[sc, k + 1, j], OY[sc, k + 1, j],
                           OYAW[sc, k + 1, j], OL[sc, j], OW[sc, j]):  # fmt: skip
                        HIT[b, j] = 1
                        contacts += 1.0
        TERMS[b, T_CONTACTS] = contacts
        TERMS[b, T_IMPACT] = impact
        TERMS[b, T_PROGRESS] = min(s_new - s, P[P_VD, sc] * dt)
        TERMS[b, T_COMFORT] = a_rep_n * a_rep_n * dt
        FS[F_S, b], FS[F_X, b], FS[F_Y, b], FS[F_YAW, b] = s_new, ex_n, ey_n, eyaw_n
        FS[F_V, b], FS[F_AREP, b], FS[F_AACT, b] = v_new, a_rep_n, a_act_n
        FS[F_RX, b], FS[F_RY, b], FS[F_RYAW, b] = nrx, nry, nryaw
        FS[F_RVX, b], FS[F_RVY, b], FS[F_RSP, b] = nrvx, nrvy, nrsp
        FS[F_RACC, b], FS[F_PROG, b] = r_acc, nprog
        BS[B_ACT, b] = 1 if n_act else 0
        BS[B_STARTED, b] = 1 if r_started else 0
        BS[B_DONE, b] = 1 if r_done else 0
        BS[B_COLL, b] = 1 if collided else 0
        BS[B_DEC, b] = rdec
        K[b] = k + 1


@numba.njit(cache=True, inline="always")
def _wrap(a):  # type: ignore[no-untyped-def]
    """vei.policy.observation.wrap_angle: pi - mod(pi - a, 2 pi) in (-pi, pi]."""
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@numba.njit(cache=True, inline="always")
def _slot(  # type: ignore[no-untyped-def]
    OUT, b, base, j, k, sc, collided, ego, dims, halfw, rng, cap, RD, cat_r, geo, oth, xo, nx, co,
):  # fmt: skip
    """Write the 9 entries of one road-user slot (object j: 0 the rider, j > 0 replayed
    other j - 1, -1 empty) of environment b at OUT[b, base:base + 9]. Argument groups:
    ego = (x, y, yaw, cos, sin, vx, vy, s), dims = (Le, Lr, Wr), geo = this scenario's
    ego path (rows [10, N], grid start, step, size, its point at s), oth = the others'
    tables (a call of > 30 arguments cannot be inlined), indexed in place. The
    rider as perceived is RD[:, b] (x y yaw vx vy active), the others at step k (both
    delayed by the perception delay); with extra riders (xo not None, nx of them here)
    objects 1..nx are they, as perceived in xo[0][b] [6, R], and the others follow; with
    reacting cars (co not None: each other's car index [S, O] or -1, the cars as perceived
    CP [B, 5, C]: x y yaw vx vy) a car's pose and velocity are its environment's."""
    ex, ey, eyaw, c, sn, evx, evy, s_e = ego
    Le, Lr, Wr = dims
    valid = False
    ox = oy = oyaw = ovx = ovy = ol = ow = ocat = 0.0
    if j == 0:
        valid = RD[5, b] > 0.5
        ox, oy, oyaw = RD[0, b], RD[1, b], RD[2, b]
        ovx, ovy = RD[3, b], RD[4, b]
        ol, ow, ocat = Lr, Wr, cat_r[sc]
    elif j <= nx:
        if xo is not None:
            jx = j - 1
            valid = xo[0][b, 5, jx] > 0.5
            ox, oy, oyaw = xo[0][b, 0, jx], xo[0][b, 1, jx], xo[0][b, 2, jx]
            ovx, ovy = xo[0][b, 3, jx], xo[0][b, 4, jx]
            ol, ow, ocat = xo[1][sc, jx], xo[2][sc, jx], xo[3][sc, jx]
    else:
        jj = j - 1 - nx
        valid = oth[4][sc, k, jj]
        ox, oy, oyaw = oth[0][sc, k, jj], oth[1][sc, k, jj], oth[2][sc, k, jj]
        sp = oth[3][sc, k, jj]
        ovx, ovy = sp * math.cos(oyaw), sp * math.sin(oyaw)
        ol, ow, ocat = oth[5][sc, jj], oth[6][sc, jj], oth[7][sc, jj]
        if co is not None:
            cj = co[0][sc, jj]
            if cj >= 0:
                ox, oy, oyaw = co[1][b, 0, cj], co[1][b, 1, cj], co[1][b, 2, cj]
                ovx, ovy = co[1][b, 3, cj], co[1][b, 4, cj]
    if not valid:
        for f in range(9):
            OUT[b, base + f] = 0.0
        OUT[b, base + 6] = cap
        return
    dx, dy = ox - ex, oy - ey
    dvx, dvy = ovx - evx, ovy - evy
    OUT[b, base + 0] = 1.0
    OUT[b, base + 1] = min(max(dx * c + dy * sn, -cap), cap)
    OUT[b, base + 2] = min(max(-dx * sn + dy * c, -cap), cap)
    OUT[b, base + 3] = dvx * c + dvy * sn
    OUT[b, base + 4] = -dvx * sn + dvy * c
    OUT[b, base + 5] = _wrap(oyaw - eyaw)
    # the corridor gap (vei.models.ego.corridor_check), not while collided, and the
    # lateral offset (vei.sim.observe.path_lateral): vei.sim.kernel.corridor on geo =
    # (this scenario's path rows [10, N], grid start, step, size) and q = its point at s_e
    path, p_s0, p_ds, n_p, q = geo
    gap = np.inf
    if not collided:
        ahead, g = corridor_at(path, p_s0, p_ds, n_p, s_e, q, ox, oy, oyaw, ol, ow,
                               half_diagonal(ol, ow), Le, halfw, rng)  # fmt: skip
        if ahead:
            gap = g
    OUT[b, base + 6] = min(gap, cap)
    lat2 = lateral_at(path, p_s0, p_ds, n_p, s_e, q, ox, oy)
    OUT[b, base + 7] = min(max(lat2, -cap), cap)
    OUT[b, base + 8] = ocat


@numba.njit(cache=True, inline="always")
def _position(xo, co, b, jj, nx, sc, kd, OX, OY, OACT):  # type: ignore[no-untyped-def]
    """(perceived, x, y) of candidate jj of the slots: extra rider jj < nx as perceived
    (xo[0]), else other jj - nx at step kd (a reacting car where co says: _slot)."""
    if xo is not None:
        if jj < nx:
            return xo[0][b, 5, jj] > 0.5, xo[0][b, 0, jj], xo[0][b, 1, jj]
    jo = jj - nx
    if co is not None:
        cj = co[0][sc, jo]
        if cj >= 0:
            return OACT[sc, kd, jo], co[1][b, 0, cj], co[1][b, 1, cj]
    return OACT[sc, kd, jo], OX[sc, kd, jo], OY[sc, kd, jo]


@numba.njit(cache=True, nogil=True, _nrt=False)
def observe_envs(  # type: ignore[no-untyped-def]
    dt, FS, BS, K, SC, P, DIM, T_n, path_end, cat_r, RD, delay,
    EP, ep_s0, ep_ds, ep_n,
    OX, OY, OYAW, OSP, OACT, OL, OW, OCAT, n_o,
    ROAD, rd_x0, rd_y0, rd_cell, rd_nx, rd_ny, road_on,
    KMAX, cap, xo, co, OUT,
):  # fmt: skip
    """The observation vectors OUT [B, D] (layout: vei.gym.features) of every environment
    at its current step. The road users as perceived ``delay`` steps ago (the engine's
    vei.sim.observe.PolicyDriver: nothing before step ``delay``): the rider's state then
    is RD [6, B] (x y yaw vx vy active; the current one without a delay), the others'
    the tables' at k - delay; the ego's own state is the current one; ``rider_on_road``
    is the rider's current position's where the rider is perceived. No sensor model.
    ``xo``: None, or the extra riders as perceived (XD [B, 6, R]: x y yaw vx vy active
    ``delay`` steps ago) with their lengths, widths, category codes [S, R] and numbers [S]:
    the objects after the rider, before the others (vei.sim.observe.ground_truth's order).
    ``co``: None, or the reacting cars as perceived (each other's car index tci [S, O], -1:
    not a car; CP [B, 5, C] x y yaw vx vy ``delay`` steps ago): they replace the tables'."""
    B = FS.shape[1]
    oth = (OX, OY, OYAW, OSP, OACT, OL, OW, OCAT)
    for b in range(B):
        sc = SC[b]
        k = K[b]
        kd = k - delay  # the step the road users are perceived at (< 0: nothing yet)
        ex, ey, eyaw = FS[F_X, b], FS[F_Y, b], FS[F_YAW, b]
        v, s_e = FS[F_V, b], FS[F_S, b]
        collided = BS[B_COLL, b] > 0
        Le, Lr, Wr = DIM[sc, 0], DIM[sc, 2], DIM[sc, 3]
        c, sn = math.cos(eyaw), math.sin(eyaw)
        evx, evy = v * c, v * sn
        OUT[b, 0] = v
        OUT[b, 1] = FS[F_AREP, b]
        OUT[b, 2] = P[P_VD, sc]
        OUT[b, 3] = path_end[sc] - s_e
        OUT[b, 4] = (T_n[sc] - 1 - k) * dt
        OUT[b, 5] = 1.0 if collided else 0.0
        # slots: 0 = the rider, then the nearest valid others (ties by index), found by
        # repeated "next after (d2, j)" scans: no per-environment allocation.
        no = n_o[sc] if kd >= 0 else 0
        nx = 0
        if xo is not None:
            nx = xo[4][sc] if kd >= 0 else 0
        halfw, rng = P[P_HALFW, sc], P[P_RANGE, sc]
        ego = (ex, ey, eyaw, c, sn, evx, evy, s_e)
        path = EP[sc]  # one view per environment (each costs a reference count)
        geo = (
            path,
            ep_s0[sc],
            ep_ds[sc],
            ep_n[sc],
            path_point(path, ep_s0[sc], ep_ds[sc], ep_n[sc], s_e),
        )
        dims = (Le, Lr, Wr)
        prev_d2 = -1.0
        prev_j = -1
        for q in range(KMAX):
            j = -1
            if q == 0:
                j = 0 if kd >= 0 else -1
            else:
                bd = np.inf
                for jj in range(nx + no):
                    ok, px, py = _position(xo, co, b, jj, nx, sc, kd, OX, OY, OACT)
                    if ok:
                        dx, dy = px - ex, py - ey
                        rxx = dx * c + dy * sn
                        ryy = -dx * sn + dy * c
                        dd = rxx * rxx + ryy * ryy
                        later = dd > prev_d2 or (dd == prev_d2 and jj > prev_j)
                        if later and dd < bd:
                            bd = dd
                            j = jj + 1
                if j > 0:
                    prev_d2 = bd
                    prev_j = j - 1
            if j < 0:
                base = 6 + 9 * q
                for f in range(9):
                    OUT[b, base + f] = 0.0
                OUT[b, base + 6] = cap
            else:
                _slot(OUT, b, 6 + 9 * q, j, kd, sc, collided, ego, dims, halfw, rng, cap, RD,
                      cat_r, geo, oth, xo, nx, co)  # fmt: skip
        if road_on:
            on = 0.0
            if kd >= 0 and RD[5, b] > 0.5:
                jx = math.floor((FS[F_RX, b] - rd_x0[sc]) / rd_cell[sc])
                iy = math.floor((FS[F_RY, b] - rd_y0[sc]) / rd_cell[sc])
                if iy >= 0 and iy < rd_ny[sc] and jx >= 0 and jx < rd_nx[sc]:
                    on = float(ROAD[sc, int(iy), int(jx)])
            OUT[b, OUT.shape[1] - 1] = on


__all__ = ["N_BS", "N_FS", "N_PREV", "observe_envs", "step_envs"]
