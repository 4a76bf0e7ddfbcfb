"""The extra riders' step in the compiled kernel (several e-scooters, vei.sim.riders).

Imported only when numba is used. For one variant, each extra rider is replayed from its
recording or (``sfm``) driven by the social force along its path, repelled by the ego, the
primary rider, the other extra riders and the pedestrians; then its ego contact latch is
updated. The same formulas and order as :mod:`vei.sim.riders` in the NumPy reference;
inlined into the kernel's loop (``inline="always"``: a call with ~50 arguments per variant
and step would cost several times the step). SI units (m, s, m/s, N).
"""

# ruff: noqa: N803
from __future__ import annotations

import math

import numba
import numpy as np

from vei.sim.kernel.decision import capped_velocity, decide_step, reference_speed
from vei.sim.kernel.layout import (
    P_AMAX_R,
    P_ARRIVE,
    P_AVEH,
    P_BVEH,
    P_CLEARM,
    P_DECIDE,
    P_FRONTB,
    P_HORIZON,
    P_KDES,
    P_LOOK,
    P_MASS,
    P_OBST,
    P_OBSTA,
    P_OBSTM,
    P_OBSTV,
    P_PAPERV,
    P_SFR,
    P_SIGMA,
    P_STOPM,
    P_TC,
    P_USEVF,
    P_V0,
    P_VMAX,
    P_YDEC,
)
from vei.sim.kernel.scalar import idx, ped_forces, rforce, sat
from vei.sim.kernel.sfm import (
    destination_force,
    goal_velocity,
    integrate,
    obstacle_velocity,
    vehicle_force,
)


@numba.njit(cache=True, inline="always")
def track_pose(xs, j, xtab, i, w, with_prog):  # type: ignore[no-untyped-def]
    """Set extra rider j's recorded pose in xs from its table xtab [R, 14, M] at cell (i, w).

    Rows of xs [9, R]: x, y, yaw [m, rad], vx, vy [m/s], speed [m/s], accel, progress [m],
    decision
    (progress only when ``with_prog``).
    """
    xs[0, j] = xtab[j, 0, i] + w * xtab[j, 7, i]
    xs[1, j] = xtab[j, 1, i] + w * xtab[j, 8, i]
    xs[2, j] = xtab[j, 2, i] + w * xtab[j, 9, i]
    xs[5, j] = xtab[j, 3, i] + w * xtab[j, 10, i]
    xs[3, j] = xtab[j, 4, i] + w * xtab[j, 11, i]
    xs[4, j] = xtab[j, 5, i] + w * xtab[j, 12, i]
    if with_prog:
        xs[7, j] = xtab[j, 6, i] + w * xtab[j, 13, i]


@numba.njit(cache=True, inline="always")
def extra_riders_step(  # type: ignore[no-untyped-def]
    k, t_new, dt, P, b, sfm, use_rf, a_rr, b_rr,
    xst, xtrk, xpth, xgeo, rx, ry, r_act, prad, others, ped_idx, ped_rad,
    ego, Le, We, ego_n, dec,
):  # fmt: skip
    """Advance the R extra riders of variant b from step k to k + 1 (time t_new [s]), in place.

    Args: xst = (xs, xb, nxs, nxb, xv0, xvmax): xs [9, R] floats (x, y, yaw, vx, vy,
    speed, accel, progress, decision) and xb [4, R] bools (active, started, done, hit) of step k,
    updated to k + 1 (nxs, nxb scratch of the same shapes), xv0, xvmax [R] desired and
    maximum speeds [m/s]; xtrk = (xtab, xt0, xdt, xtend, xnr, xsfm0) their recorded tables
    [R, 14, M] with start, step and end times [s], lengths and SFM entry times [s]; xpth = (xpath, xps0, xpds,
    xpn, xplen, xpex, xpey) their paths [R, 10, N] (arc grid, length, end point [m]);
    xgeo = (xL, xW, xrad) footprints and radii [R] [m]; the primary rider's position, active
    flag and radius prad [m] at step k; others None (no other road users) or the kernel's
    others group (oX, oY, oYAW, oSP, oACT [T, no], ...), ped_idx [n] the pedestrians among
    them and ped_rad [n] their radii [m]; the ego at step k, ego = (x, y, yaw: repulsion;
    speed [m/s]: obstacle braking and decisions; arc length [m]: decisions), and at k + 1,
    ego_n = (x, y, yaw: contact), Le x We [m]; dec None, or the kernel's decision
    group (its rows 6-11: each extra rider's conflicts, vei.sim.kernel.pack.decisions_group).
    """
    xs, xb, nxs, nxb, xv0, xvmax = xst
    xtab, xt0, xdt, xtend, xnr, xsfm0 = xtrk
    xpath, xps0, xpds, xpn, xplen, xpex, xpey = xpth
    xL, xW, xrad = xgeo
    ex, ey, eyaw, ev, es = ego
    ex_n, ey_n, eyaw_n = ego_n
    R = xs.shape[1]
    nf = xs.shape[0]
    for j in range(R):
        for f in range(nf):
            nxs[f, j] = xs[f, j]
        for f in range(4):
            nxb[f, j] = xb[f, j]
        n_j = xnr[j]
        in_span = t_new >= xt0[j] - 1e-9 and t_new <= xtend[j] + 1e-9
        if not sfm:
            if in_span:
                i, w = idx(xt0[j], xdt[j], n_j, t_new)
                track_pose(nxs, j, xtab, i, w, False)
            else:
                j0 = 0 if t_new < xt0[j] else n_j - 1
                nxs[0, j] = xtab[j, 0, j0]
                nxs[1, j] = xtab[j, 1, j0]
                nxs[2, j] = xtab[j, 2, j0]
                nxs[3, j] = 0.0
                nxs[4, j] = 0.0
                nxs[5, j] = 0.0
            nxb[0, j] = in_span
            if xb[1, j] and not in_span:
                nxb[2, j] = True
            nxb[1, j] = xb[1, j] or in_span
        else:
            if xb[0, j] and xb[1, j]:
                x0, y0, vx0, vy0, prog0 = xs[0, j], xs[1, j], xs[3, j], xs[4, j], xs[7, j]
                vdx, vdy, pr = goal_velocity(
                    x0, y0, prog0, xpath[j], xps0[j], xpds[j], xpn[j], xplen[j],
                    P[P_LOOK, b], P[P_SIGMA, b], P[P_PAPERV, b] > 0.5, xv0[j],
                )  # fmt: skip
                if dec is not None:  # its own yield / go decision at its conflicts
                    if P[P_DECIDE, b] > 0.5 and dec[6][j] > 0:
                        conf = (dec[6][j], dec[7][j], dec[8][j], dec[9][j], dec[10][j], dec[11][j])
                        d_new, vcap = decide_step(
                            int(xs[8, j]), prog0, pr, xs[5, j], es, ev, conf,
                            P[P_TC, b], P[P_HORIZON, b], P[P_YDEC, b], P[P_STOPM, b],
                            P[P_CLEARM, b], reference_speed(xv0[j], P[P_LOOK, b], P[P_SIGMA, b]),
                            P[P_MASS, b] / P[P_KDES, b],
                        )  # fmt: skip
                        nxs[8, j] = d_new
                        vdx, vdy = capped_velocity(vdx, vdy, vcap)
                if P[P_OBST, b] > 0.5 and ev < P[P_OBSTV, b]:  # a standing / slow car ahead
                    vdx, vdy = obstacle_velocity(
                        x0, y0, vdx, vdy, xs[5, j], ex, ey, eyaw, Le, We,
                        0.5 * math.hypot(xL[j], xW[j]), P[P_OBSTM, b], P[P_OBSTA, b],
                        P[P_MASS, b] / P[P_KDES, b],
                    )  # fmt: skip
                fx, fy = destination_force(vdx, vdy, vx0, vy0, P[P_KDES, b])
                if P[P_USEVF, b] > 0.5:
                    vfx, vfy = vehicle_force(
                        x0, y0, ex, ey, eyaw, Le, We, P[P_FRONTB, b] > 0.5, P[P_AVEH, b], P[P_BVEH, b]
                    )  # fmt: skip
                    fx = fx + vfx
                    fy = fy + vfy
                if use_rf:
                    sx = 0.0
                    sy = 0.0
                    if r_act:
                        hx_, hy_ = rforce(x0, y0, rx, ry, xrad[j] + prad, a_rr, b_rr)
                        sx += hx_
                        sy += hy_
                    for mm in range(R):
                        if mm != j and xb[0, mm]:
                            hx_, hy_ = rforce(
                                x0, y0, xs[0, mm], xs[1, mm], xrad[j] + xrad[mm], a_rr, b_rr
                            )
                            sx += hx_
                            sy += hy_
                    if others is not None:
                        sx, sy = ped_forces(
                            sx, sy, x0, y0, xrad[j], k, ped_idx, ped_rad,
                            others[0], others[1], others[4], a_rr, b_rr,
                        )  # fmt: skip
                    fx = fx + sx
                    fy = fy + sy
                x2, y2, vx2, vy2, sp2 = integrate(
                    x0, y0, vx0, vy0, fx, fy, P[P_MASS, b], P[P_AMAX_R, b], xvmax[j], dt, True
                )
                yaw2 = math.atan2(vy2, vx2) if sp2 > 0.05 else xs[2, j]
                arrived = (x2 - xpex[j]) ** 2 + (y2 - xpey[j]) ** 2 <= P[P_ARRIVE, b] ** 2
                leaving = arrived and t_new > xtend[j] + 1e-9
                nxs[0, j] = x2
                nxs[1, j] = y2
                nxs[2, j] = yaw2
                if leaving:
                    nxs[3, j] = 0.0
                    nxs[4, j] = 0.0
                    nxs[5, j] = 0.0
                    nxb[2, j] = True
                else:
                    nxs[3, j] = vx2
                    nxs[4, j] = vy2
                    nxs[5, j] = sp2
                nxs[7, j] = pr
                nxb[0, j] = not leaving
            if in_span and not xb[1, j]:
                i, w = idx(xt0[j], xdt[j], n_j, t_new)
                track_pose(nxs, j, xtab, i, w, True)
                nxb[0, j] = True
                nxb[1, j] = t_new >= xsfm0[j] - 1e-9
        if nxb[0, j] and xb[0, j]:
            nxs[6, j] = (nxs[5, j] - xs[5, j]) / dt
        else:
            nxs[6, j] = 0.0
        if nxb[0, j] and not xb[3, j]:
            ddx, ddy = nxs[0, j] - ex_n, nxs[1, j] - ey_n
            rr = 0.5 * (math.hypot(Le, We) + math.hypot(xL[j], xW[j]))
            if ddx * ddx + ddy * ddy <= rr * rr:
                if sat(ex_n, ey_n, eyaw_n, Le, We, nxs[0, j], nxs[1, j], nxs[2, j], xL[j], xW[j]):
                    nxb[3, j] = True
    for j in range(R):
        for f in range(nf):
            xs[f, j] = nxs[f, j]
        for f in range(4):
            xb[f, j] = nxb[f, j]


@numba.njit(cache=True, inline="always")
def riders_state0(b, P, R, XS0, XB0, xmed, xp99):  # type: ignore[no-untyped-def]
    """Variant b's R extra riders at k = 0: (xs [9, R], xb [4, R], their scratch for the
    next step, desired speeds xv0 [R], speed limits xvmax [R] [m/s]: from each rider's own
    recording (median moving speed, 99th percentile) where the variant's
    speed_from_recording is on and the recording has one, else the variant's v0 / vmax)."""
    nf = XS0.shape[0]
    xs = np.empty((nf, R))
    xb = np.empty((4, R), dtype=np.bool_)
    nxs = np.empty((nf, R))
    nxb = np.empty((4, R), dtype=np.bool_)
    xv0 = np.empty(R)
    xvmax = np.empty(R)
    for j in range(R):
        for f in range(nf):
            xs[f, j] = XS0[f, b, j]
        for f in range(4):
            xb[f, j] = XB0[f, b, j] > 0
        med = xmed[j]
        if P[P_SFR, b] > 0.5 and math.isfinite(med):
            lk = P[P_LOOK, b]
            xv0[j] = med * math.hypot(lk, P[P_SIGMA, b]) / lk
            xvmax[j] = max(xp99[j], med)
        else:
            xv0[j] = P[P_V0, b]
            xvmax[j] = P[P_VMAX, b]
    return xs, xb, nxs, nxb, xv0, xvmax


@numba.njit(cache=True, inline="always")
def riders_record(b, kk, xs, xb, OX, OXB):  # type: ignore[no-untyped-def]
    """Step kk of variant b's extra-rider series: OX [B, 5, T, R] (x, y, yaw, speed,
    accel), OXB [B, 2, T, R] (active, hit)."""
    for j in range(xs.shape[1]):
        OX[b, 0, kk, j] = xs[0, j]
        OX[b, 1, kk, j] = xs[1, j]
        OX[b, 2, kk, j] = xs[2, j]
        OX[b, 3, kk, j] = xs[5, j]
        OX[b, 4, kk, j] = xs[6, j]
        OXB[b, 0, kk, j] = 1 if xb[0, j] else 0
        OXB[b, 1, kk, j] = 1 if xb[3, j] else 0


@numba.njit(cache=True, inline="always")
def riders_final(b, xs, xb, XFS, XFB):  # type: ignore[no-untyped-def]
    """Variant b's final extra-rider state into XFS [9, B, R] and XFB [4, B, R]."""
    for j in range(xs.shape[1]):
        for f in range(xs.shape[0]):
            XFS[f, b, j] = xs[f, j]
        for f in range(4):
            XFB[f, b, j] = 1 if xb[f, j] else 0
