"""Reacting cars and contacts in the compiled kernel (vei.sim.traffic, vei.sim.contacts on
scalars).

Imported only when numba is used. For one variant: the reacting cars' step (the laws of
:mod:`vei.models.traffic_core` compiled on scalars, leaders from the state at step k),
the ego's contacts with the others at their engine poses, the rider's contacts with the
others, a driven car's contacts with any other, and the run's secondary collisions, in
the order and with the formulas of the NumPy step. Inlined into the kernel's loop. SI
units (m, s, m/s, m/s^2, rad).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math

import numba
import numpy as np

from vei.models import traffic_core as core
from vei.sim.kernel.layout import (
    P_CA,
    P_CB,
    P_CBMAX,
    P_CDELTA,
    P_CREACT,
    P_CS0,
    P_CT,
    P_CTRIG,
    P_CV0,
)
from vei.sim.kernel.scalar import idx, sat

_inline = numba.njit(cache=True, inline="always")
idm_accel = _inline(core.idm_accel_core)
car_accel = _inline(core.car_accel_core)
notices = _inline(core.notices_core)
leader_gap = _inline(core.leader_gap_core)
#: vei.sim.traffic.MAP_DS_M (the leader maps' grid step [m]).
MAP_DS_M = 0.5


@numba.njit(cache=True, inline="always")
def map_at(mtab, m0, mn, li, j, s):  # type: ignore[no-untyped-def]
    """The leader map li onto car j at the leader's arc s [m] (vei.sim.traffic.map_at):
    (arc on j's path [m], lateral offset [m], cos of the heading difference, half-extent [m])."""
    n = mn[li]
    f = (s - m0[li]) / MAP_DS_M
    if f < 0.0:
        f = 0.0
    elif f > n - 1.0:
        f = n - 1.0
    i = int(f)
    if i > max(n - 2, 0):
        i = max(n - 2, 0)
    w = f - i
    i1 = min(i + 1, n - 1)
    return (
        mtab[li, j, 0, i] + w * (mtab[li, j, 0, i1] - mtab[li, j, 0, i]),
        mtab[li, j, 1, i] + w * (mtab[li, j, 1, i1] - mtab[li, j, 1, i]),
        mtab[li, j, 2, i] + w * (mtab[li, j, 2, i1] - mtab[li, j, 2, i]),
        mtab[li, j, 3, i] + w * (mtab[li, j, 3, i1] - mtab[li, j, 3, i]),
    )


@numba.njit(cache=True, inline="always")
def nearest_leader(tg, j, own_s, s_e, v_e, cs_l, cv_l, act_l, We):  # type: ignore[no-untyped-def]
    """(gap [m], leader speed along j's path [m/s]) of the nearest road user on car j's
    path ahead: the ego at arc s_e / speed v_e, car m at cs_l[m] / cv_l[m] where act_l[m]."""
    C, tL, tW, mtab, m0, mn, pair = tg
    gap = math.inf
    vl = 0.0
    for li in range(C + 1):
        if not pair[li, j] or li == j + 1:
            continue
        if li == 0:
            sl, v = s_e, v_e
            wl = We
        else:
            if not act_l[li - 1]:
                continue
            sl, v = cs_l[li - 1], cv_l[li - 1]
            wl = tW[li - 1]
        sig, lat, cosd, ext = map_at(mtab, m0, mn, li, j, sl)
        g = leader_gap(sig, lat, ext, own_s, 0.5 * tL[j], 0.5 * (tW[j] + wl))
        if g < gap:
            gap = g
            vl = v * cosd
    return gap, vl


@numba.njit(cache=True, inline="always")
def traffic_step(k, dt, P, b, on, tg, trec, tpath, cst, s_e, v_e, We):  # type: ignore[no-untyped-def]
    """Advance the C reacting cars of variant b from step k to k + 1, in place.

    tg = (C, lengths, widths, leader maps, their grid starts and sizes, pairs); trec =
    (s_rec, v_rec, a_rec [T, C], active [T, C], ego s_rec, v_rec [T], oX, oY, oYAW [T, no],
    idx [C]); tpath = (rows [C, 10, N], grid starts, steps, sizes [C]); cst = (s, v, timer,
    x, y, yaw [C] floats, mode [C] ints, own_s, own_v, own_rs, own_rv scratch [C]); the ego
    at step k: arc s_e [m], speed v_e [m/s], width We [m]. on: cars_react.
    """
    C = tg[0]
    srec, vrec, arec, tact, esrec, evrec, oX, oY, oYAW, tidx = trec
    ptab, ps0, pds, pn = tpath
    cs, cv, ctm, cx, cy, cyaw, cmode, own_s, own_v, rs, rv = cst
    for m in range(C):
        if cmode[m] >= core.IDM:
            own_s[m], own_v[m] = cs[m], cv[m]
        else:
            own_s[m], own_v[m] = srec[k, m], vrec[k, m]
        rs[m], rv[m] = srec[k, m], vrec[k, m]
    v0, th, s0, a, bb, de = (
        P[P_CV0, b],
        P[P_CT, b],
        P[P_CS0, b],
        P[P_CA, b],
        P[P_CB, b],
        P[P_CDELTA, b],
    )
    for j in range(C):
        if not tact[k, j]:
            continue
        gap_a, vl_a = nearest_leader(tg, j, own_s[j], s_e, v_e, own_s, own_v, tact[k], We)
        gap_r, vl_r = nearest_leader(tg, j, srec[k, j], esrec[k], evrec[k], rs, rv, tact[k], We)
        a_act = idm_accel(own_v[j], vl_a, gap_a, v0, th, s0, a, bb, de)
        a_rec = idm_accel(vrec[k, j], vl_r, gap_r, v0, th, s0, a, bb, de)
        m = cmode[j]
        tm = ctm[j]
        if m == core.REPLAY and on and notices(a_act, a_rec, P[P_CTRIG, b]):
            m = core.REACTING
            tm = P[P_CREACT, b]
        sj, vj = cs[j], cv[j]
        if m == core.REACTING:
            tm = tm - dt
            if tm <= 1e-9:
                m = core.IDM
                sj, vj = srec[k, j], vrec[k, j]
        if m == core.IDM:
            acc = car_accel(arec[k, j], vrec[k, j], vj, a_act, th, a, P[P_CBMAX, b])
            vj = max(vj + acc * dt, 0.0)
            sj = sj + vj * dt
        if m == core.STOPPED:
            vj = 0.0
        cmode[j] = m
        ctm[j] = tm
        cs[j], cv[j] = sj, vj
    kn = min(k + 1, srec.shape[0] - 1)
    for j in range(C):
        if cmode[j] <= core.REACTING:
            cs[j], cv[j] = srec[kn, j], vrec[kn, j]
            o = tidx[j]
            cx[j], cy[j], cyaw[j] = oX[kn, o], oY[kn, o], oYAW[kn, o]
        else:
            i, w = idx(ps0[j], pds[j], pn[j], cs[j])
            cx[j] = ptab[j, 0, i] + w * ptab[j, 5, i]
            cy[j] = ptab[j, 1, i] + w * ptab[j, 6, i]
            cyaw[j] = ptab[j, 2, i] + w * ptab[j, 7, i]


@numba.njit(cache=True, inline="always")
def other_pos(k1, q, oX, oY, oYAW, cpos, C):  # type: ignore[no-untyped-def]
    """(x, y, yaw) of replayed other q at step k1, a reacting car where the engine moves it
    (cpos = (index of q among the cars [no] or -1, cx, cy, cyaw [C]); C = 0: none)."""
    ci, cx, cy, cyaw = cpos
    c = ci[q] if C > 0 else -1
    if c >= 0:
        return cx[c], cy[c], cyaw[c]
    return oX[k1, q], oY[k1, q], oYAW[k1, q]


@numba.njit(cache=True, inline="always")
def other_vel(k, q, oSP, oYAW, cvel, C):  # type: ignore[no-untyped-def]
    """(vx, vy) of replayed other q at step k: speed times heading; a reacting car's
    engine speed where it is driven (cvel = (car index [no] or -1, speed, yaw, mode [C]
    at step k)), its recorded speed while it replays."""
    ci, cv, cyaw, cm = cvel
    c = ci[q] if C > 0 else -1
    if c >= 0:
        yaw = cyaw[c]
        sp = cv[c] if cm[c] > core.REACTING else oSP[k, q]
    else:
        yaw, sp = oYAW[k, q], oSP[k, q]
    return sp * math.cos(yaw), sp * math.sin(yaw)


@numba.njit(cache=True, inline="always")
def strike(ax, ay, avx, avy, bx, by, bvx, bvy):  # type: ignore[no-untyped-def]
    """(a strikes b, impact speed [m/s]) of a contact (vei.sim.contacts._strike)."""
    dx, dy = bx - ax, by - ay
    d = max(math.hypot(dx, dy), 1e-9)
    ca = (avx * dx + avy * dy) / d
    cb = -(bvx * dx + bvy * dy) / d
    return ca >= cb, math.hypot(avx - bvx, avy - bvy)


@numba.njit(cache=True, inline="always")
def record(sec, t, a_code, b_code, a_strikes, speed, rear):  # type: ignore[no-untyped-def]
    """Count one new contact into sec = [count, first t, striker, struck, max speed, rear]."""
    if sec[0] == 0.0:
        sec[1] = t
        sec[2] = a_code if a_strikes else b_code
        sec[3] = b_code if a_strikes else a_code
    sec[0] += 1.0
    if not (sec[4] >= speed):  # np.fmax: NaN loses
        sec[4] = speed
    if rear:
        sec[5] = 1.0


@numba.njit(cache=True, inline="always")
def contacts(  # type: ignore[no-untyped-def]
    k1, t, oth, cpos, cvel, C, ego, rider, hits, xs, xv0, xhits, rhit, car, sec, dims, on,
):  # fmt: skip
    """The contacts at step k1 = k + 1 and the run's secondary collisions, in place
    (vei.sim.contacts.contact_step on scalars, the same order): positions at k1,
    velocities at k (the step before).

    oth = (oX, oY, oYAW, oSP [T, no], oACT [T, no], oL, oW [no], veh [no] bool);
    cpos = (car index of each other [no] or -1, cx, cy, cyaw [C]) at k1, cvel = (the same
    index, speed, yaw, mode [C]) at k; ego = (x, y, yaw at k1, speed, yaw at k); rider =
    (x, y, yaw at k1, vx, vy at k, active at k1); hits = (hit before, hit after [no]) of
    the ego with the others; xs [8, R] the extra riders at k1, xv0 = (speed, yaw [R]) at
    k, xhits = (before, after [R]) their ego-contact latches; rhit [no] the rider's
    latches; car = (mode [C], car_hit [C], car_hit_with [C], idx [C], lengths, widths
    [C]); sec [6] the summaries (count, first t, striker, struck, max speed, rear end);
    dims = (Lr, Wr, Le); on: cars_react. Where a driven car touched anything its mode
    becomes STOPPED; the caller then sets its speed to 0 (after the contacts, as the NumPy
    step does).
    """
    oX, oY, oYAW, oSP, oACT, oL, oW, veh = oth
    ex, ey, eyaw, ev, eyaw0 = ego
    rx, ry, ryaw, rvx, rvy, ract = rider
    h0, h1 = hits
    x0, x1 = xhits
    xsp0, xyaw0 = xv0
    cmode, chit, chw, tidx, tL, tW = car
    Lr, Wr, Le = dims
    no = oL.shape[0]
    k = k1 - 1
    Cc = C if on else 0  # the cars' engine poses only where they react (else recorded)
    evx, evy = ev * math.cos(eyaw0), ev * math.sin(eyaw0)
    c_e, s_e = math.cos(eyaw), math.sin(eyaw)
    for j in range(no):
        if h1[j] and not h0[j]:
            qx, qy, qyaw = other_pos(k1, j, oX, oY, oYAW, cpos, Cc)
            qvx, qvy = other_vel(k, j, oSP, oYAW, cvel, Cc)
            a_st, sp = strike(ex, ey, evx, evy, qx, qy, qvx, qvy)
            behind = (qx - ex) * c_e + (qy - ey) * s_e < -0.5 * Le
            same = math.cos(qyaw - eyaw) > math.cos(math.pi / 6)
            record(sec, t, 0.0, 2.0 + j, a_st, sp, (not a_st) and behind and same and veh[j])
    for m in range(x1.shape[0]):
        if x1[m] and not x0[m]:
            xsp, xyaw = xsp0[m], xyaw0[m]
            a_st, sp = strike(
                ex, ey, evx, evy, xs[0, m], xs[1, m], xsp * math.cos(xyaw), xsp * math.sin(xyaw)
            )
            record(sec, t, 0.0, 2.0 + no + m, a_st, sp, False)
    if ract:
        for j in range(no):
            if rhit[j] or not oACT[k1, j]:
                continue
            qx, qy, qyaw = other_pos(k1, j, oX, oY, oYAW, cpos, Cc)
            reach = 0.5 * (math.hypot(Lr, Wr) + math.hypot(oL[j], oW[j]))
            if (qx - rx) ** 2 + (qy - ry) ** 2 > reach * reach:
                continue
            if sat(rx, ry, ryaw, Lr, Wr, qx, qy, qyaw, oL[j], oW[j]):
                rhit[j] = True
                qvx, qvy = other_vel(k, j, oSP, oYAW, cvel, Cc)
                a_st, sp = strike(rx, ry, rvx, rvy, qx, qy, qvx, qvy)
                record(sec, t, 1.0, 2.0 + j, a_st, sp, False)
    if C > 0 and on:
        for j in range(C):
            oj = tidx[j]
            driven = cmode[j] == core.IDM and oACT[k1, oj]
            if driven:
                px, py, pyaw = other_pos(k1, oj, oX, oY, oYAW, cpos, Cc)
                pvx, pvy = other_vel(k, oj, oSP, oYAW, cvel, Cc)
                for q in range(no):
                    if q == oj or chit[j] or not oACT[k1, q]:
                        continue
                    qx, qy, qyaw = other_pos(k1, q, oX, oY, oYAW, cpos, Cc)
                    rr = 0.5 * (math.hypot(tL[j], tW[j]) + math.hypot(oL[q], oW[q]))
                    if (qx - px) ** 2 + (qy - py) ** 2 > rr * rr:
                        continue
                    if sat(px, py, pyaw, tL[j], tW[j], qx, qy, qyaw, oL[q], oW[q]):
                        chit[j] = True
                        chw[j] = q
                        cq = cpos[0][q]
                        if cq < 0 or not chit[cq]:
                            qvx, qvy = other_vel(k, q, oSP, oYAW, cvel, Cc)
                            a_st, sp = strike(px, py, pvx, pvy, qx, qy, qvx, qvy)
                            record(sec, t, 2.0 + oj, 2.0 + q, a_st, sp, False)
            if (chit[j] or h1[oj] or rhit[oj]) and cmode[j] == core.IDM:
                cmode[j] = core.STOPPED


@numba.njit(cache=True, inline="always")
def traffic_state0(b, C, no, CS0, CM0, CH0, CW0, RH0, SEC0):  # type: ignore[no-untyped-def]
    """Variant b's reacting-car and contact state at k = 0 from the packed initial arrays:
    (car floats [6, C], modes [C], car_hit [C], car_hit_with [C], rider_hit_other [no],
    the secondary summaries [6])."""
    cfl = np.empty((6, C))
    cmode = np.empty(C, dtype=np.int64)
    chit = np.empty(C, dtype=np.bool_)
    chw = np.empty(C, dtype=np.int64)
    for j in range(C):
        for f in range(6):
            cfl[f, j] = CS0[f, b, j]
        cmode[j] = CM0[b, j]
        chit[j] = CH0[b, j] > 0
        chw[j] = CW0[b, j]
    rhit = np.empty(no, dtype=np.bool_)
    for j in range(no):
        rhit[j] = RH0[b, j] > 0
    sec = np.empty(6)
    for f in range(6):
        sec[f] = SEC0[f, b]
    return cfl, cmode, chit, chw, rhit, sec


@numba.njit(cache=True, inline="always")
def traffic_final(b, cfl, cmode, chit, chw, rhit, sec, CFS, CFM, CFH, CFW, RFH, SECF):  # type: ignore[no-untyped-def]
    """Write variant b's final reacting-car and contact state into the packed outputs."""
    for j in range(cfl.shape[1]):
        for f in range(6):
            CFS[f, b, j] = cfl[f, j]
        CFM[b, j] = cmode[j]
        CFH[b, j] = 1 if chit[j] else 0
        CFW[b, j] = chw[j]
    for j in range(rhit.shape[0]):
        RFH[b, j] = 1 if rhit[j] else 0
    for f in range(6):
        SECF[f, b] = sec[f]
