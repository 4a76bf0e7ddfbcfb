"""Contacts of any two road users in the compiled kernel (vei.sim.contacts on scalars).

Imported only when numba is used. For one variant and step: the ego's new contacts with
the others at their engine poses, its new contacts with the extra riders, the rider's
contacts with the others, a driven car's contacts with any other, and the run's secondary
collisions, in the order and with the formulas of the NumPy step (one function per part:
the kernel calls each only where the scene has its road users, :mod:`vei.sim.kernel.loop`).
Inlined into the kernel's loop. SI units (m, s, m/s, rad).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math

import numba

from vei.models import traffic_core as core
from vei.sim.kernel.scalar import sat


@numba.njit(cache=True, inline="always")
def other_pos(k1, q, oX, oY, oYAW, cars):  # type: ignore[no-untyped-def]
    """(x, y, yaw) of replayed other q at step k1, a reacting car where the engine moves it
    (cars = ((index of q among the cars [no] or -1, cx, cy, cyaw [C]) at k1, (the same
    index, speed, yaw, mode [C]) at k, C where the cars react else 0))."""
    ci, cx, cy, cyaw = cars[0]
    c = ci[q] if cars[2] > 0 else -1
    if c >= 0:
        return cx[c], cy[c], cyaw[c]
    return oX[k1, q], oY[k1, q], oYAW[k1, q]


@numba.njit(cache=True, inline="always")
def other_vel(k, q, oSP, oYAW, cars):  # type: ignore[no-untyped-def]
    """(vx, vy) of replayed other q at step k: speed times heading; a reacting car's
    engine speed where it is driven (cars[1] = (car index [no] or -1, speed, yaw, mode [C]
    at step k)), its recorded speed while it replays."""
    ci, cv, cyaw, cm = cars[1]
    c = ci[q] if cars[2] > 0 else -1
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
def ego_contacts(k1, t, others, h0, h1, cars, ego, sec, Le):  # type: ignore[no-untyped-def]
    """The ego's new contacts with the others at step k1 (latches h0 before, h1 after
    [no]) into the secondary summaries sec [6] (first of vei.sim.contacts.contact_step's
    parts). others = (oX, oY, oYAW, oSP [T, no], oACT [T, no], oL, oW [no], veh [no] bool,
    ...); cars: :func:`other_pos`; ego = (x, y, yaw at k1, speed, yaw at k); Le [m]."""
    oX, oY, oYAW, oSP, veh = others[0], others[1], others[2], others[3], others[7]
    ex, ey, eyaw, ev, eyaw0 = ego
    k = k1 - 1
    evx, evy = ev * math.cos(eyaw0), ev * math.sin(eyaw0)
    c_e, s_e = math.cos(eyaw), math.sin(eyaw)
    for j in range(h1.shape[0]):
        if h1[j] and not h0[j]:
            qx, qy, qyaw = other_pos(k1, j, oX, oY, oYAW, cars)
            qvx, qvy = other_vel(k, j, oSP, oYAW, cars)
            a_st, sp = strike(ex, ey, evx, evy, qx, qy, qvx, qvy)
            behind = (qx - ex) * c_e + (qy - ey) * s_e < -0.5 * Le
            same = math.cos(qyaw - eyaw) > math.cos(math.pi / 6)
            record(sec, t, 0.0, 2.0 + j, a_st, sp, (not a_st) and behind and same and veh[j])


@numba.njit(cache=True, inline="always")
def extra_contacts(t, ego, xs, xv0, x0, x1, sec, no):  # type: ignore[no-untyped-def]
    """The ego's new contacts with the extra riders (latches x0 before, x1 after [R]; xs
    [8, R] their state at k1, xv0 = (speed, yaw [R]) at k) into sec [6]; no the number of
    others (the riders' codes follow theirs)."""
    ex, ey, eyaw, ev, eyaw0 = ego
    evx, evy = ev * math.cos(eyaw0), ev * math.sin(eyaw0)
    xsp0, xyaw0 = xv0
    for m in range(x1.shape[0]):
        if x1[m] and not x0[m]:
            xsp, xyaw = xsp0[m], xyaw0[m]
            a_st, sp = strike(
                ex, ey, evx, evy, xs[0, m], xs[1, m], xsp * math.cos(xyaw), xsp * math.sin(xyaw)
            )
            record(sec, t, 0.0, 2.0 + no + m, a_st, sp, False)


@numba.njit(cache=True, inline="always")
def rider_contacts(k1, t, others, rhit, cars, rider, sec, Lr, Wr):  # type: ignore[no-untyped-def]
    """The rider's new contacts with the others at step k1 (latches rhit [no], updated)
    into sec [6]; rider = (x, y, yaw at k1, vx, vy at k, active at k1), Lr x Wr [m]."""
    oX, oY, oYAW, oSP, oACT, oL, oW = (
        others[0], others[1], others[2], others[3], others[4], others[5], others[6],
    )  # fmt: skip
    rx, ry, ryaw, rvx, rvy, ract = rider
    k = k1 - 1
    if not ract:
        return
    for j in range(rhit.shape[0]):
        if rhit[j] or not oACT[k1, j]:
            continue
        qx, qy, qyaw = other_pos(k1, j, oX, oY, oYAW, cars)
        reach = 0.5 * (math.hypot(Lr, Wr) + math.hypot(oL[j], oW[j]))
        if (qx - rx) ** 2 + (qy - ry) ** 2 > reach * reach:
            continue
        if sat(rx, ry, ryaw, Lr, Wr, qx, qy, qyaw, oL[j], oW[j]):
            rhit[j] = True
            qvx, qvy = other_vel(k, j, oSP, oYAW, cars)
            a_st, sp = strike(rx, ry, rvx, rvy, qx, qy, qvx, qvy)
            record(sec, t, 1.0, 2.0 + j, a_st, sp, False)


@numba.njit(cache=True, inline="always")
def car_contacts(k1, t, others, h1, rhit, cars, car, sec):  # type: ignore[no-untyped-def]
    """A driven car's contacts with any other at step k1 into sec [6] (the last part of
    vei.sim.contacts.contact_step; only where the cars react, cars[2] > 0). car = (mode
    [C], car_hit [C], car_hit_with [C], idx [C], lengths, widths [C]). Where a driven car
    touched anything its mode becomes STOPPED; the caller then sets its speed to 0 (after
    the contacts, as the NumPy step does)."""
    if cars[2] == 0:
        return
    oX, oY, oYAW, oSP, oACT, oL, oW = (
        others[0], others[1], others[2], others[3], others[4], others[5], others[6],
    )  # fmt: skip
    cmode, chit, chw, tidx, tL, tW = car
    no = oL.shape[0]
    k = k1 - 1
    for j in range(tidx.shape[0]):
        oj = tidx[j]
        driven = cmode[j] == core.IDM and oACT[k1, oj]
        if driven:
            px, py, pyaw = other_pos(k1, oj, oX, oY, oYAW, cars)
            pvx, pvy = other_vel(k, oj, oSP, oYAW, cars)
            for q in range(no):
                if q == oj or chit[j] or not oACT[k1, q]:
                    continue
                qx, qy, qyaw = other_pos(k1, q, oX, oY, oYAW, cars)
                rr = 0.5 * (math.hypot(tL[j], tW[j]) + math.hypot(oL[q], oW[q]))
                if (qx - px) ** 2 + (qy - py) ** 2 > rr * rr:
                    continue
                if sat(px, py, pyaw, tL[j], tW[j], qx, qy, qyaw, oL[q], oW[q]):
                    chit[j] = True
                    chw[j] = q
                    cq = cars[0][0][q]
                    if cq < 0 or not chit[cq]:
                        qvx, qvy = other_vel(k, q, oSP, oYAW, cars)
                        a_st, sp = strike(px, py, pvx, pvy, qx, qy, qvx, qvy)
                        record(sec, t, 2.0 + oj, 2.0 + q, a_st, sp, False)
        if (chit[j] or h1[oj] or rhit[oj]) and cmode[j] == core.IDM:
            cmode[j] = core.STOPPED
