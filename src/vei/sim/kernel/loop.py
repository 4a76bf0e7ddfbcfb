"""numba-compiled loop of the built-in engine (imported only when numba is used).

See :mod:`vei.sim.kernel` for the contract; the layout of the packed arrays is in
:mod:`vei.sim.kernel.layout`. :func:`kernel` spreads the variants over the cores
(``prange``); :func:`variant` runs one variant over all steps. The model pieces it
inlines live in :mod:`vei.sim.kernel.scalar` (interpolation, box overlap, repulsion),
:mod:`vei.sim.kernel.ego` (replay / PID / CAP), :mod:`vei.sim.kernel.sfm` (social
force), :mod:`vei.sim.kernel.riders` (extra riders), :mod:`vei.sim.kernel.decision`
(the rider's yield / go decision), :mod:`vei.sim.kernel.traffic` (reacting cars) and
:mod:`vei.sim.kernel.contacts` (contacts of any two road users).

Compiled per feature set (issue 33). Each optional part of the world is one argument that
is either a tuple of arrays or ``None``: the other road users (``others``), the extra
social-force riders (``xr``), the rider's decisions (``dec``), the reacting cars
(``traffic``) and the fused metrics (``metrics``). numba compiles one specialisation per
combination of their types, and every ``if group is not None:`` is decided before type
inference (numba's dead-branch pruning on argument types), so a run that does not use a
part does not compile it. The parallel shell stays small: numba's parfor passes then only
analyse one call per variant, not the whole inlined step (the shell compiled around the
inlined step cost about 70 s of a 105 s compile). Every compiled function is at module
level so that numba's on-disk cache (``cache=True``) works across processes, one entry per
specialisation; :func:`vei.sim.kernel._build` drops the cache when any of these modules
changes (numba only checks the kernel's own file).
"""

# ruff: noqa: E501, N803, N806
from __future__ import annotations

import math

import numba
import numpy as np

from vei.metrics.fused import run_metrics
from vei.metrics.fused_layout import (
    CH_EA,
    CH_EV,
    CH_EX,
    CH_EY,
    CH_EYAW,
    CH_RACT,
    CH_RCOL,
    CH_RSP,
    CH_RX,
    CH_RY,
    CH_RYAW,
    N_CH,
)
from vei.models import traffic_core
from vei.sim.kernel.contacts import car_contacts, ego_contacts, extra_contacts, rider_contacts
from vei.sim.kernel.decision import capped_velocity, decide_step, reference_speed
from vei.sim.kernel.ego import ego_consts, ego_step_c
from vei.sim.kernel.layout import (
    N_OUT,
    O_A,
    O_RA,
    O_RSP,
    O_RVX,
    O_RVY,
    O_RX,
    O_RY,
    O_RYAW,
    O_S,
    O_U,
    O_V,
    O_X,
    O_Y,
    O_YAW,
    P_AMAX_R,
    P_ARR,
    P_ARRIVE,
    P_AVEH,
    P_BRR,
    P_BVEH,
    P_CLEARM,
    P_DECIDE,
    P_DELAY,
    P_DMAX,
    P_FRONTB,
    P_HORIZON,
    P_KDES,
    P_LOOK,
    P_MASS,
    P_MODE,
    P_OBST,
    P_OBSTA,
    P_OBSTM,
    P_OBSTV,
    P_PAPERV,
    P_REACT,
    P_SFM,
    P_SHIFT,
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
from vei.sim.kernel.policy import policy_ego, policy_state0, put_cars, put_truth
from vei.sim.kernel.riders import extra_riders_step, riders_final, riders_record, riders_state0
from vei.sim.kernel.scalar import idx, ped_forces, rforce, sat
from vei.sim.kernel.sfm import (
    destination_force,
    goal_velocity,
    integrate,
    obstacle_velocity,
    vehicle_force,
)
from vei.sim.kernel.traffic import traffic_final, traffic_state0, traffic_step

__all__ = ["N_OUT", "kernel", "kernel_seq", "variant"]


# parallel=True: variants are independent (per-variant scratch, no reduction across them),
# so the prange loop spreads them over the cores without changing any result. nogil: a
# sweep's parent runs chunks itself while its pool's manager thread feeds the workers.
@numba.njit(cache=True, parallel=True, nogil=True)
def kernel(
    T, dt, hist_len, record, ego, rider, P, init, out, others, xr, dec, traffic, metrics, pol
):  # type: ignore[no-untyped-def]
    """Run every variant of P [N_PARAMS, B] over T steps (see :func:`variant`)."""
    for b in numba.prange(P.shape[1]):
        # one integer type for the variant index: one specialisation of variant(), not two
        variant(
            np.int64(b), T, dt, hist_len, record, ego, rider, P, init, out,
            others, xr, dec, traffic, metrics, pol,
        )  # fmt: skip


# With ego policies (pol: a user's function is a first-class function value, which numba's
# parallel loop cannot take) the variants run in chunks of this serial shell, one chunk per
# call from a pool of threads (nogil: they run in parallel; vei.sim.kernel.run).
@numba.njit(cache=True, nogil=True)
def kernel_seq(lo, hi, T, dt, hist_len, record, ego, rider, P, init, out, others, xr, dec, traffic, metrics, pol):  # type: ignore[no-untyped-def]  # fmt: skip
    """Variants lo <= b < hi of P (see :func:`variant`)."""
    for b in range(lo, hi):
        variant(
            np.int64(b), T, dt, hist_len, record, ego, rider, P, init, out,
            others, xr, dec, traffic, metrics, pol,
        )  # fmt: skip


@numba.njit(cache=True, nogil=True)
def variant(
    b, T, dt, hist_len, record, ego, rider, P, init, out, others, xr, dec, traffic, metrics, pol
):  # type: ignore[no-untyped-def]
    """Variant b of the batch over all T steps of dt [s], written into ``out``.

    Args (arrays documented in :func:`vei.sim.kernel.run`, which packs them):
        hist_len: perception ring length; record: keep the time series.
        ego = (path [10, N]: x y yaw cos sin then their slopes on p_s0 + i p_ds, p_s0, p_ds,
            etab [4, M]: recorded s and speed then slopes on e_t0 + i e_dt, e_t0, e_dt,
            Le, We).
        rider = (rtab [14, M]: x y yaw speed vx vy arc then slopes, r_t0, r_dt, r_tend,
            r_sfm0: the recording time from which an SFM rider is driven, rpath [10, N],
            rp_s0, rp_ds, rp_len, rp_ex, rp_ey, Lr, Wr).
        P [N_PARAMS, B] the parameters. init = (S0 [20, B] floats, B0 [4, B] uint8 (active,
            started, collided, done), SEC0 [6, B] the secondary-collision summaries).
        out = (OUT [B, N_OUT, T or 1], OB [B, 4, T or 1] uint8 (cap, rider active,
            collided, decision), FS [20, B], FB [4, B], FH [4, hist_len, B], coll_t [B],
            min_d [B], SECF [6, B]).
        others: None, or (oX, oY, oYAW, oSP [T, no], oACT [T, no], oL, oW [no], oVEH [no],
            H0 [B, no] the ego's hit latches in and out, OH [B, T or 1, no], RH0, RFH [B, no]
            the rider's hit latches in and out).
        xr: None, or the extra riders (:func:`vei.sim.kernel.pack.riders_group`).
        dec: None, or the conflicts of the decisions: the primary rider's (K, exit,
            s_rider, s_ego, hz_rider, hz_ego), then the extra riders' padded the same way
            (:func:`vei.sim.kernel.pack.decisions_group`).
        traffic: None, or the reacting cars (:func:`vei.sim.kernel.pack.traffic_group`).
        metrics: None, or (t [T], dt, cfg [N_CFG], M [B, N_FUSED]).
        pol: None, or the ego policies (:func:`vei.sim.kernel.policy_pack.policy_group`).
    """
    path, p_s0, p_ds, etab, e_t0, e_dt, Le, We = ego
    rtab, r_t0, r_dt, r_tend, r_sfm0, rpath, rp_s0, rp_ds, rp_len, rp_ex, rp_ey, Lr, Wr = rider
    S0, B0, SEC0 = init
    OUT, OB, FS, FB, FH, coll_t, min_d, SECF = out
    n_p = path.shape[1]
    n_e = etab.shape[1]
    n_r = rtab.shape[1]
    n_rp = rpath.shape[1]
    reach = 0.5 * (math.hypot(Le, We) + math.hypot(Lr, Wr))
    shift = P[P_SHIFT, b]
    sfm = P[P_SFM, b] > 0.5
    mode = int(P[P_MODE, b])
    delay = int(P[P_DELAY, b])
    vd = P[P_VD, b]
    # the primary rider's social-force constants, once per variant (same values)
    p_look, p_sigma, p_paperv = P[P_LOOK, b], P[P_SIGMA, b], P[P_PAPERV, b] > 0.5
    p_v0, p_kdes, p_usevf = P[P_V0, b], P[P_KDES, b], P[P_USEVF, b] > 0.5
    p_frontb, p_aveh, p_bveh = P[P_FRONTB, b] > 0.5, P[P_AVEH, b], P[P_BVEH, b]
    p_mass, p_amax, p_vmax = P[P_MASS, b], P[P_AMAX_R, b], P[P_VMAX, b]
    p_limits = math.isfinite(p_vmax) or math.isfinite(p_amax)
    p_obst, p_obstv = P[P_OBST, b] > 0.5, P[P_OBSTV, b]
    p_obsta, p_obstm, p_tau = P[P_OBSTA, b], P[P_OBSTM, b], p_mass / p_kdes
    r_rad = 0.5 * math.hypot(Lr, Wr)
    p_arrive2 = P[P_ARRIVE, b] ** 2
    ec = ego_consts(P, b, dt, Lr, Wr)  # the ego's per-variant constants, once per variant
    # state
    s = S0[0, b]
    ex = S0[1, b]
    ey = S0[2, b]
    eyaw = S0[3, b]
    v = S0[4, b]
    a_rep = S0[5, b]
    a_act = S0[6, b]
    u = S0[7, b]
    pid_i = S0[8, b]
    pid_e = S0[9, b]
    cap = int(S0[10, b])
    rx = S0[11, b]
    ry = S0[12, b]
    ryaw = S0[13, b]
    rvx = S0[14, b]
    rvy = S0[15, b]
    rsp = S0[16, b]
    r_acc = S0[17, b]
    prog = S0[18, b]
    rdec = int(S0[19, b])
    r_act = B0[0, b] > 0
    r_started = B0[1, b] > 0
    collided = B0[2, b] > 0
    r_done = B0[3, b] > 0
    sec = np.empty(6)  # the secondary collisions' summaries (vei.sim.kernel.contacts.record)
    for f in range(6):
        sec[f] = SEC0[f, b]
    no = 0
    if others is not None:
        oX, oY, oYAW, oSP, oACT, oL, oW, oVEH, H0, OH, RH0, RFH = others
        no = oL.shape[0]
        # squared contact radius of the ego with each replayed other (constant over the run)
        o_rr2 = np.empty(no)
        for j in range(no):
            rr = 0.5 * (math.hypot(Le, We) + math.hypot(oL[j], oW[j]))
            o_rr2[j] = rr * rr
        hit = np.empty(no, dtype=np.bool_)
        rhit = np.empty(no, dtype=np.bool_)
        for j in range(no):
            hit[j] = H0[b, j] > 0
            rhit[j] = RH0[b, j] > 0
        hprev = np.empty(no, dtype=np.bool_)
    if xr is not None:
        (
            R, xtab, xt0, xdt, xtend, xnr, xsfm0, xpath, xps0, xpds, xpn, xplen, xpex, xpey,
            xL, xW, xrad, xmed, xp99, prad, rep_on, ped_idx, ped_rad, XS0, XB0, OX, OXB, XFS, XFB,
        ) = xr  # fmt: skip
        use_rf = rep_on and P[P_USERF, b] > 0.5
        a_rr = P[P_ARR, b]
        b_rr = P[P_BRR, b]
        xs, xb, nxs, nxb, xv0, xvmax = riders_state0(b, P, R, XS0, XB0, xmed, xp99)
        xprev = np.empty(R, dtype=np.bool_)
        xvk = (np.empty(R), np.empty(R))  # the extra riders' speed, yaw at step k
        xst = (xs, xb, nxs, nxb, xv0, xvmax)
        xtrk = (xtab, xt0, xdt, xtend, xnr, xsfm0)
        xpth = (xpath, xps0, xpds, xpn, xplen, xpex, xpey)
        xgeo = (xL, xW, xrad)
    # the rider's yield / go decision (vei.sim.kernel.decision), its constants
    dec_on = False
    if dec is not None:
        dec_on = sfm and dec[0] > 0 and P[P_DECIDE, b] > 0.5
        d_tc, d_hor, d_ydec = P[P_TC, b], P[P_HORIZON, b], P[P_YDEC, b]
        d_stopm, d_clearm = P[P_STOPM, b], P[P_CLEARM, b]
        d_vref = reference_speed(p_v0, p_look, p_sigma)
    # reacting cars (vei.sim.kernel.traffic); they exist only beside the others
    if traffic is not None:
        (
            tC, tidx, tL, tW, tci, tptab, tps0, tpds, tpn, tsrec, tvrec, tarec, tact, tesrec,
            tevrec, tmtab, tm0, tmn, tpair, CS0, CM0, CH0, CW0, OC, OCM, CFS, CFM, CFH, CFW,
        ) = traffic  # fmt: skip
        react_on = tC > 0 and P[P_REACT, b] > 0.5
        cfl, cmode, chit, chw = traffic_state0(b, tC, CS0, CM0, CH0, CW0)
        cv0, cyaw0, cm0 = np.empty(tC), np.empty(tC), np.empty(tC, dtype=np.int64)
        scr = np.empty((4, tC))
        cst = (cfl[0], cfl[1], cfl[2], cfl[3], cfl[4], cfl[5], cmode, scr[0], scr[1], scr[2], scr[3])  # fmt: skip
        tg = (tC, tL, tW, tmtab, tm0, tmn, tpair)
        trec = (tsrec, tvrec, tarec, tact, tesrec, tevrec, oX, oY, oYAW, tidx)
        tpath = (tptab, tps0, tpds, tpn)
        # the cars' engine poses (at k + 1) and velocities (at k) where they react
        cars = ((tci, cfl[3], cfl[4], cfl[5]), (tci, cv0, cyaw0, cm0), tC if react_on else 0)
        carg = (cmode, chit, chw, tidx, tL, tW)
    else:  # none: every other at its recorded pose (the same types, never None: no Optional)
        nocar = np.full(no, -1, dtype=np.int64)
        e0 = np.empty(0)
        cars = ((nocar, e0, e0, e0), (nocar, e0, e0, np.empty(0, dtype=np.int64)), 0)
    hx = np.zeros(hist_len)
    hy = np.zeros(hist_len)
    hyaw = np.zeros(hist_len)
    hact = np.zeros(hist_len)
    hx[0], hy[0], hyaw[0], hact[0] = rx, ry, ryaw, 1.0 if r_act else 0.0
    # Argument groups of the inlined steps (Python compiles a call of > 30 arguments
    # to CALL_FUNCTION_EX, which numba cannot inline).
    hist = (hx, hy, hyaw, hact)
    egeo = (path, p_s0, p_ds, n_p, etab, e_t0, e_dt, n_e, Le, Lr, Wr)
    ct = np.nan
    if collided:
        ct = 0.0
    # the least squared centre distance; its root at the end is the least distance
    # (sqrt is monotone: min of the roots = root of the min, NaN kept, ties the same)
    md2 = np.inf
    if r_act:
        md2 = (rx - ex) ** 2 + (ry - ey) ** 2
    # Fused metrics: this variant's [T] channels (scratch, never [B, T]), scored at the end.
    if metrics is not None:
        ch = np.empty((N_CH, T))
        _channels(ch, 0, ex, ey, eyaw, v, a_rep, rx, ry, ryaw, rsp, r_act, collided)
    pol_on = False
    if pol is not None:  # an ego policy (vei.sim.kernel.policy), its scratch
        pscr = policy_state0(pol, b, mode)
        pol_on = pscr[0]
    for k in range(T - 1):
        t_new = (k + 1) * dt
        # ---------------- ego
        use_c = True
        if pol is not None:
            if pol_on:
                use_c = False
                slot = k % pol[5]
                put_truth(pscr[2], slot, 0, rx, ry, ryaw, rvx, rvy, r_act)
                if xr is not None:
                    for j in range(R):
                        put_truth(pscr[2], slot, 1 + j, xs[0, j], xs[1, j], xs[2, j], xs[3, j], xs[4, j], xb[0, j] > 0)  # fmt: skip
                if traffic is not None:  # the reacting cars where the engine drives them
                    if react_on:
                        put_cars(pscr[2], pscr[5], slot, k, pol[9], tidx, cfl, cmode)
                s_new, v_new, a_act_n, a_rep_n, u, cap = policy_ego(
                    k, dt, pol, pscr, b, ec, vd, delay, s, ex, ey, eyaw, v, a_act, a_rep, cap, collided, egeo, Le, We,
                )  # fmt: skip
        if use_c:
            s_new, v_new, a_act_n, a_rep_n, u, pid_i, pid_e, cap = ego_step_c(
                k, t_new, dt, ec, mode, delay, vd, hist_len,
                s, v, a_act, pid_i, pid_e, cap, collided,
                rx, ry, ryaw, r_act, hist, egeo,
            )  # fmt: skip
        i, w = idx(p_s0, p_ds, n_p, s_new)
        ex_n = path[0, i] + w * path[5, i]
        ey_n = path[1, i] + w * path[6, i]
        eyaw_n = path[2, i] + w * path[7, i]
        # ---------------- rider
        t_rec = t_new - shift
        in_span = t_rec >= r_t0 - 1e-9 and t_rec <= r_tend + 1e-9
        prev_x, prev_y, prev_yaw, prev_sp, prev_act = rx, ry, ryaw, rsp, r_act
        if not sfm:
            if in_span:
                i, w = idx(r_t0, r_dt, n_r, t_rec)
                nrx = rtab[0, i] + w * rtab[7, i]
                nry = rtab[1, i] + w * rtab[8, i]
                nryaw = rtab[2, i] + w * rtab[9, i]
                nrsp = rtab[3, i] + w * rtab[10, i]
                nrvx = rtab[4, i] + w * rtab[11, i]
                nrvy = rtab[5, i] + w * rtab[12, i]
            else:
                j0 = 0 if t_rec < r_t0 else n_r - 1
                nrx, nry, nryaw = rtab[0, j0], rtab[1, j0], rtab[2, j0]
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
                vdx, vdy, pr = goal_velocity(
                    rx, ry, prog, rpath, rp_s0, rp_ds, n_rp, rp_len,
                    p_look, p_sigma, p_paperv, p_v0,
                )  # fmt: skip
                if dec is not None:
                    if dec_on:
                        rdec, vcap = decide_step(
                            rdec, prog, pr, rsp, s, v, dec[:6], d_tc, d_hor, d_ydec,
                            d_stopm, d_clearm, d_vref, p_tau,
                        )  # fmt: skip
                        vdx, vdy = capped_velocity(vdx, vdy, vcap)
                if p_obst and v < p_obstv:  # a standing or slow car in its way
                    vdx, vdy = obstacle_velocity(
                        rx, ry, vdx, vdy, rsp, ex, ey, eyaw, Le, We, r_rad, p_obstm, p_obsta, p_tau,
                    )  # fmt: skip
                fx, fy = destination_force(vdx, vdy, rvx, rvy, p_kdes)
                if p_usevf:
                    vfx, vfy = vehicle_force(rx, ry, ex, ey, eyaw, Le, We, p_frontb, p_aveh, p_bveh)
                    fx = fx + vfx
                    fy = fy + vfy
                if xr is not None:
                    if use_rf:
                        sx = 0.0
                        sy = 0.0
                        for mm in range(R):
                            if xb[0, mm]:
                                hx_, hy_ = rforce(
                                    rx, ry, xs[0, mm], xs[1, mm], prad + xrad[mm], a_rr, b_rr
                                )
                                sx += hx_
                                sy += hy_
                        if others is not None:
                            sx, sy = ped_forces(
                                sx, sy, rx, ry, prad, k, ped_idx, ped_rad, oX, oY, oACT, a_rr, b_rr
                            )
                        fx = fx + sx
                        fy = fy + sy
                x2, y2, vx2, vy2, sp2 = integrate(
                    rx, ry, rvx, rvy, fx, fy, p_mass, p_amax, p_vmax, dt, p_limits
                )  # fmt: skip
                yaw2 = math.atan2(vy2, vx2) if sp2 > 0.05 else ryaw
                arrived = (x2 - rp_ex) ** 2 + (y2 - rp_ey) ** 2 <= p_arrive2
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
                nrx = rtab[0, i] + w * rtab[7, i]
                nry = rtab[1, i] + w * rtab[8, i]
                nryaw = rtab[2, i] + w * rtab[9, i]
                nrsp = rtab[3, i] + w * rtab[10, i]
                nrvx = rtab[4, i] + w * rtab[11, i]
                nrvy = rtab[5, i] + w * rtab[12, i]
                nprog = rtab[6, i] + w * rtab[13, i]
                n_act = True
                # before its SFM entry (a standing run-in) it stands replayed
                r_started = t_rec >= r_sfm0 - 1e-9
        if collided:
            nrx, nry, nryaw = prev_x, prev_y, prev_yaw
            nrvx = nrvy = nrsp = 0.0
            n_act = prev_act
        r_acc = (nrsp - prev_sp) / dt if (n_act and prev_act) else 0.0
        if collided:
            r_acc = 0.0
        # ---------------- extra riders (state at step k; ego contact at k + 1)
        if xr is not None:
            for j in range(R):
                xprev[j] = xb[3, j]
                xvk[0][j], xvk[1][j] = xs[5, j], xs[2, j]
            if R > 0:
                extra_riders_step(
                    k, t_new, dt, P, b, sfm, use_rf, a_rr, b_rr,
                    xst, xtrk, xpth, xgeo, rx, ry, r_act, prad, others, ped_idx, ped_rad,
                    (ex, ey, eyaw, v, s), Le, We, (ex_n, ey_n, eyaw_n), dec,
                )  # fmt: skip
        # ---------------- collision
        if n_act and not collided:
            ddx, ddy = nrx - ex_n, nry - ey_n
            if ddx * ddx + ddy * ddy <= reach * reach:
                if sat(ex_n, ey_n, eyaw_n, Le, We, nrx, nry, nryaw, Lr, Wr):
                    collided = True
                    ct = t_new
                    v_new = 0.0
                    a_act_n = 0.0
                    a_rep_n = 0.0
                    nrvx = nrvy = nrsp = 0.0
                    r_acc = 0.0
        if traffic is not None:
            for j in range(tC):
                cv0[j], cyaw0[j], cm0[j] = cfl[1, j], cfl[5, j], cmode[j]
            if react_on:
                traffic_step(k, dt, P, b, react_on, tg, trec, tpath, cst, s, v, We)
        if others is not None:
            for j in range(no):
                hprev[j] = hit[j]
            for j in range(no):
                if oACT[k + 1, j] and not hit[j]:
                    qx, qy, qyaw = oX[k + 1, j], oY[k + 1, j], oYAW[k + 1, j]
                    if traffic is not None:
                        if react_on and tci[j] >= 0:
                            c = tci[j]
                            qx, qy, qyaw = cfl[3, c], cfl[4, c], cfl[5, c]
                    ddx, ddy = qx - ex_n, qy - ey_n
                    if ddx * ddx + ddy * ddy <= o_rr2[j]:
                        if sat(ex_n, ey_n, eyaw_n, Le, We, qx, qy, qyaw, oL[j], oW[j]):
                            hit[j] = True
        # ---------------- contacts of any two road users, secondary collisions
        # (positions at k + 1, velocities at k; vei.sim.contacts.contact_step's order)
        ego_now = (ex_n, ey_n, eyaw_n, v, eyaw)
        if others is not None:
            ego_contacts(k + 1, t_new, others, hprev, hit, cars, ego_now, sec, Le)
        if xr is not None:
            extra_contacts(t_new, ego_now, xs, xvk, xprev, xb[3], sec, no)
        if others is not None:
            rider_now = (nrx, nry, nryaw, rsp * math.cos(ryaw), rsp * math.sin(ryaw), n_act)
            rider_contacts(k + 1, t_new, others, rhit, cars, rider_now, sec, Lr, Wr)
        if traffic is not None:
            car_contacts(k + 1, t_new, others, hit, rhit, cars, carg, sec)
        if traffic is not None:
            for j in range(tC):  # a car stopped by a contact stands
                if cmode[j] == traffic_core.STOPPED:
                    cfl[1, j] = 0.0
        # ---------------- commit
        s, ex, ey, eyaw, v, a_act, a_rep = s_new, ex_n, ey_n, eyaw_n, v_new, a_act_n, a_rep_n
        rx, ry, ryaw, rvx, rvy, rsp, prog, r_act = nrx, nry, nryaw, nrvx, nrvy, nrsp, nprog, n_act
        if hist_len > 1:
            slot = (k + 1) % hist_len
            hx[slot], hy[slot], hyaw[slot] = rx, ry, ryaw
            hact[slot] = 1.0 if r_act else 0.0
        if r_act:
            dd2 = (rx - ex) * (rx - ex) + (ry - ey) * (ry - ey)
            if dd2 < md2:
                md2 = dd2
        if metrics is not None:
            _channels(ch, k + 1, ex, ey, eyaw, v, a_rep, rx, ry, ryaw, rsp, r_act, collided)
        if record:
            kk = k + 1
            OUT[b, O_S, kk] = s
            OUT[b, O_X, kk] = ex
            OUT[b, O_Y, kk] = ey
            OUT[b, O_YAW, kk] = eyaw
            OUT[b, O_V, kk] = v
            OUT[b, O_A, kk] = a_rep
            OUT[b, O_U, kk] = u
            OUT[b, O_RX, kk] = rx
            OUT[b, O_RY, kk] = ry
            OUT[b, O_RYAW, kk] = ryaw
            OUT[b, O_RSP, kk] = rsp
            OUT[b, O_RVX, kk] = rvx
            OUT[b, O_RVY, kk] = rvy
            OUT[b, O_RA, kk] = r_acc
            OB[b, 0, kk] = cap
            OB[b, 1, kk] = 1 if r_act else 0
            OB[b, 2, kk] = 1 if collided else 0
            OB[b, 3, kk] = rdec
            if others is not None:
                for j in range(no):
                    OH[b, kk, j] = 1 if hit[j] else 0
            if xr is not None:
                riders_record(b, kk, xs, xb, OX, OXB)
            if traffic is not None:
                for j in range(tC):
                    OC[b, 0, kk, j] = cfl[3, j]
                    OC[b, 1, kk, j] = cfl[4, j]
                    OC[b, 2, kk, j] = cfl[5, j]
                    OC[b, 3, kk, j] = cfl[1, j]
                    OCM[b, kk, j] = cmode[j]
    fin = (
        s, ex, ey, eyaw, v, a_rep, a_act, u, pid_i, pid_e, float(cap), rx, ry, ryaw, rvx, rvy,
        rsp, r_acc, prog, float(rdec),
    )  # fmt: skip
    for f in range(20):
        FS[f, b] = fin[f]
    FB[0, b] = 1 if r_act else 0
    FB[1, b] = 1 if r_started else 0
    FB[2, b] = 1 if collided else 0
    FB[3, b] = 1 if r_done else 0
    for h in range(hist_len):
        FH[0, h, b] = hx[h]
        FH[1, h, b] = hy[h]
        FH[2, h, b] = hyaw[h]
        FH[3, h, b] = hact[h]
    coll_t[b] = ct
    min_d[b] = math.sqrt(md2)
    if metrics is not None:
        t_m, dt_m, MCFG, M = metrics
        run_metrics(t_m, dt_m, ch, Le, We, Lr, Wr, MCFG, P[P_MASS, b], P[P_DMAX, b], M[b])
    for f in range(6):
        SECF[f, b] = sec[f]
    if others is not None:
        for j in range(no):
            H0[b, j] = 1 if hit[j] else 0
            RFH[b, j] = 1 if rhit[j] else 0
    if traffic is not None:
        traffic_final(b, cfl, cmode, chit, chw, CFS, CFM, CFH, CFW)
    if xr is not None:
        riders_final(b, xs, xb, XFS, XFB)


@numba.njit(cache=True, inline="always")
def _channels(ch, k, ex, ey, eyaw, v, a, rx, ry, ryaw, rsp, r_act, collided):  # type: ignore[no-untyped-def]
    """Step k of the fused metrics' channels (what record='full' writes for that step)."""
    ch[CH_EX, k] = ex
    ch[CH_EY, k] = ey
    ch[CH_EYAW, k] = eyaw
    ch[CH_EV, k] = v
    ch[CH_EA, k] = a
    ch[CH_RX, k] = rx
    ch[CH_RY, k] = ry
    ch[CH_RYAW, k] = ryaw
    ch[CH_RSP, k] = rsp
    ch[CH_RACT, k] = 1.0 if r_act else 0.0
    ch[CH_RCOL, k] = 1.0 if collided else 0.0
