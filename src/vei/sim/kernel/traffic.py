"""Reacting cars in the compiled kernel (vei.sim.traffic on scalars).

Imported only when numba is used. For one variant: the reacting cars' step (the laws of
:mod:`vei.models.traffic_core` compiled on scalars, leaders from the state at step k) and
their state in and out of the packed arrays, in the order and with the formulas of the
NumPy step; their contacts are :mod:`vei.sim.kernel.contacts`'. Inlined into the
kernel's loop. SI units (m, s, m/s, m/s^2, rad).
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
from vei.sim.kernel.scalar import idx

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
def traffic_state0(b, C, CS0, CM0, CH0, CW0):  # type: ignore[no-untyped-def]
    """Variant b's reacting-car state at k = 0 from the packed initial arrays:
    (car floats [6, C], modes [C], car_hit [C], car_hit_with [C])."""
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
    return cfl, cmode, chit, chw


@numba.njit(cache=True, inline="always")
def traffic_final(b, cfl, cmode, chit, chw, CFS, CFM, CFH, CFW):  # type: ignore[no-untyped-def]
    """Write variant b's final reacting-car state into the packed outputs."""
    for j in range(cfl.shape[1]):
        for f in range(6):
            CFS[f, b, j] = cfl[f, j]
        CFM[b, j] = cmode[j]
        CFH[b, j] = 1 if chit[j] else 0
        CFW[b, j] = chw[j]
