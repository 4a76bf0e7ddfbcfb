"""Social-force pieces of the compiled kernel: path-following drive, ego repulsion, limits.

Imported only when numba is used. For one rider of one variant: the desired velocity,
destination force, Euler step, the ego's repulsion and the limits' factor are
:mod:`vei.models.sfm_core`'s functions compiled on scalars (the NumPy step runs them on
arrays); this module only gates them by branches (a limit where it binds, the direction
from the ego's centre when the rider is on the source point) and follows the goal on the
rider's path. Shared by the
primary rider (:mod:`vei.sim.kernel.loop`) and the extra riders
(:mod:`vei.sim.kernel.riders`), inlined into the kernel's loop (``inline="always"``).
SI units (m, s, m/s, N, kg).
"""

# ruff: noqa: N803
from __future__ import annotations

import math

import numba

from vei.models import decision_core as dcore
from vei.models import sfm_core as core
from vei.sim.kernel.scalar import idx  # also registers the cores' select on scalars

_inline = numba.njit(cache=True, inline="always")
desired_velocity = _inline(core.desired_velocity_core)
destination_force = _inline(core.destination_force_core)
point_mass = _inline(core.point_mass_core)
cap_factor = _inline(core.cap_factor_core)
influential_point = _inline(core.influential_point_core)
repulsion = _inline(core.repulsion_core)
away_from_centre = _inline(core.away_from_centre_core)
capped_velocity = _inline(dcore.capped_velocity_core)
obstacle_speed = _inline(core.obstacle_speed_core)


@numba.njit(cache=True, inline="always")
def drive_force(x0, y0, vx0, vy0, prog0, rpath, ps0, pds, pn, plen, look, sigma, paperv, v0, kdes):  # type: ignore[no-untyped-def]
    """Desired-velocity force of a rider following its path.

    Args: position [m], velocity [m/s] and path progress prog0 [m] of the rider; its path
    rpath [10, pn] (x y yaw cos sin, then slopes) on the arc grid ps0 + i pds, length plen
    [m]; lookahead look [m]; sigma [m] the softening; paperv the paper's v_des (1/q instead
    of 1/sqrt(q)); v0 [m/s] the desired speed; kdes [N s/m] the relaxation gain.
    Returns (fx, fy, pr): the force [N] and the new progress [m] (never backwards).
    """
    vdx, vdy, pr = goal_velocity(x0, y0, prog0, rpath, ps0, pds, pn, plen, look, sigma, paperv, v0)
    fx, fy = destination_force(vdx, vdy, vx0, vy0, kdes)
    return fx, fy, pr


@numba.njit(cache=True, inline="always")
def goal_velocity(x0, y0, prog0, rpath, ps0, pds, pn, plen, look, sigma, paperv, v0):  # type: ignore[no-untyped-def]
    """The desired velocity of a rider following its path (the first half of
    :func:`drive_force`; arguments alike). Returns (vdx, vdy, pr): the desired velocity
    [m/s] and the new progress [m]."""
    i, w = idx(ps0, pds, pn, prog0)
    qx = rpath[0, i] + w * rpath[5, i]
    qy = rpath[1, i] + w * rpath[6, i]
    qc = rpath[3, i] + w * rpath[8, i]
    qs = rpath[4, i] + w * rpath[9, i]
    pr = max(prog0 + (x0 - qx) * qc + (y0 - qy) * qs, prog0)
    i, w = idx(ps0, pds, pn, min(pr + look, plen))
    gx = rpath[0, i] + w * rpath[5, i]
    gy = rpath[1, i] + w * rpath[6, i]
    vdx, vdy = desired_velocity(x0, y0, gx, gy, v0, sigma, paperv)
    return vdx, vdy, pr


@numba.njit(cache=True, inline="always")
def vehicle_force(x0, y0, ex, ey, eyaw, Le, We, front, aveh, bveh):  # type: ignore[no-untyped-def]
    """Repulsion of the ego's box on a rider at (x0, y0) [m] (sfm_core's laws).

    Args: ego centre [m], yaw [rad], length Le and width We [m]; front: from the front
    bumper's centre (else from the closest point of the box); aveh [N], bveh [1/m].
    Returns (fx, fy) [N]: aveh exp(-bveh d) away from the source point at distance d
    (from the ego's centre, or along the ego's heading, when d = 0).
    """
    c, sn = math.cos(eyaw), math.sin(eyaw)
    bx, by = influential_point(x0, y0, ex, ey, c, sn, 0.5 * Le, 0.5 * We, front)
    mag, nx_, ny_, tiny = repulsion(x0, y0, bx, by, aveh, bveh)
    if tiny:  # the rider on the source point: rare, so behind a branch here
        nx_, ny_ = away_from_centre(x0, y0, ex, ey, c, sn)
    return mag * nx_, mag * ny_


@numba.njit(cache=True, inline="always")
def integrate(x0, y0, vx0, vy0, fx, fy, m, amax, vmax, dt, limits):  # type: ignore[no-untyped-def]
    """Semi-implicit Euler step of a rider under force (fx, fy) [N], with its limits.

    Args: position [m], velocity [m/s], mass m [kg]; amax [m/s^2] the force cap (as
    amax m), vmax [m/s] the speed cap, applied only when ``limits``; dt [s].
    Returns (x2, y2, vx2, vy2, sp2): new position [m], velocity and speed [m/s].
    """
    if limits:
        fmag = math.sqrt(fx * fx + fy * fy)
        fmax = amax * m
        if fmag > fmax:
            sc = cap_factor(fmag, fmax)
            fx, fy = fx * sc, fy * sc
    x2, y2, vx2, vy2 = point_mass(x0, y0, vx0, vy0, fx, fy, m, dt)
    sp2 = math.sqrt(vx2 * vx2 + vy2 * vy2)
    if limits and sp2 > vmax:
        sc = cap_factor(sp2, vmax)
        vx2, vy2, sp2 = vx2 * sc, vy2 * sc, sp2 * sc
        x2, y2 = x0 + vx2 * dt, y0 + vy2 * dt
    return x2, y2, vx2, vy2, sp2


@numba.njit(cache=True, inline="always")
def obstacle_velocity(x0, y0, vdx, vdy, sp, ex, ey, eyaw, Le, We, rad, margin, decel, tau):  # type: ignore[no-untyped-def]
    """The desired velocity (vdx, vdy) [m/s] of a rider at (x0, y0) [m], speed sp [m/s],
    capped for the ego's box (centre, yaw, Le x We [m]) in its way
    (:func:`vei.models.sfm_core.obstacle_speed_core`: widened by the rider's radius rad
    [m], a stop ``margin`` [m] short at ``decel`` [m/s^2], relaxation time tau [s])."""
    cap = obstacle_speed(
        x0, y0, vdx, vdy, sp, ex, ey, math.cos(eyaw), math.sin(eyaw), 0.5 * Le, 0.5 * We,
        rad, margin, decel, tau,
    )  # fmt: skip
    if cap == math.inf:
        return vdx, vdy
    return capped_velocity(vdx, vdy, cap)
