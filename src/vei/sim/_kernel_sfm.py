"""Social-force pieces of the compiled kernel: path-following drive, ego repulsion, limits.

Imported only when numba is used. For one rider of one variant: the desired velocity,
destination force and Euler step are :mod:`vei.models.sfm_core`'s functions compiled on
scalars (the NumPy step runs them on arrays); the goal on the path, the ego repulsion and
the limits follow :mod:`vei.models.sfm` formula for formula (see sfm_core for why they
stay written twice). Shared by the
primary rider (:mod:`vei.sim._kernel_numba`) and the extra riders
(:mod:`vei.sim._kernel_riders`), inlined into the kernel's loop (``inline="always"``).
SI units (m, s, m/s, N, kg).
"""

# ruff: noqa: N803
from __future__ import annotations

import math

import numba

from vei.models import sfm_core as core
from vei.sim._kernel_scalar import idx  # also registers the cores' select on scalars

_inline = numba.njit(cache=True, inline="always")
desired_velocity = _inline(core.desired_velocity_core)
destination_force = _inline(core.destination_force_core)
point_mass = _inline(core.point_mass_core)


@numba.njit(cache=True, inline="always")
def drive_force(x0, y0, vx0, vy0, prog0, rpath, ps0, pds, pn, plen, look, sigma, paperv, v0, kdes):  # type: ignore[no-untyped-def]
    """Desired-velocity force of a rider following its path.

    Args: position [m], velocity [m/s] and path progress prog0 [m] of the rider; its path
    rpath [10, pn] (x y yaw cos sin, then slopes) on the arc grid ps0 + i pds, length plen
    [m]; lookahead look [m]; sigma [m] the softening; paperv the paper's v_des (1/q instead
    of 1/sqrt(q)); v0 [m/s] the desired speed; kdes [N s/m] the relaxation gain.
    Returns (fx, fy, pr): the force [N] and the new progress [m] (never backwards).
    """
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
    fx, fy = destination_force(vdx, vdy, vx0, vy0, kdes)
    return fx, fy, pr


@numba.njit(cache=True, inline="always")
def vehicle_force(x0, y0, ex, ey, eyaw, Le, We, front, aveh, bveh):  # type: ignore[no-untyped-def]
    """Repulsion of the ego's box on a rider at (x0, y0) [m].

    Args: ego centre [m], yaw [rad], length Le and width We [m]; front: from the front
    bumper's centre (else from the closest point of the box); aveh [N], bveh [1/m].
    Returns (fx, fy) [N]: aveh exp(-bveh d) away from the source point at distance d
    (from the ego's centre, or along the ego's heading, when d = 0).
    """
    c, sn = math.cos(eyaw), math.sin(eyaw)
    hl, hw = 0.5 * Le, 0.5 * We
    if front:
        bx = ex + hl * c
        by = ey + hl * sn
    else:
        ddx, ddy = x0 - ex, y0 - ey
        lx = min(max(ddx * c + ddy * sn, -hl), hl)
        ly = min(max(-ddx * sn + ddy * c, -hw), hw)
        bx = ex + lx * c - ly * sn
        by = ey + lx * sn + ly * c
    dx2, dy2 = x0 - bx, y0 - by
    d = math.sqrt(dx2 * dx2 + dy2 * dy2)
    mag = aveh * math.exp(-bveh * d)
    if d < 1e-9:
        e2x, e2y = x0 - ex, y0 - ey
        de = math.sqrt(e2x * e2x + e2y * e2y)
        if de > 1e-9:
            nx_, ny_ = e2x / de, e2y / de
        else:
            nx_, ny_ = c, sn
    else:
        nx_, ny_ = dx2 / d, dy2 / d
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
            sc = fmax / fmag if fmag > 0 else 1.0
            fx, fy = fx * sc, fy * sc
    x2, y2, vx2, vy2 = point_mass(x0, y0, vx0, vy0, fx, fy, m, dt)
    sp2 = math.sqrt(vx2 * vx2 + vy2 * vy2)
    if limits:
        if sp2 > vmax:
            sc = vmax / sp2 if sp2 > 0 else 1.0
            vx2, vy2, sp2 = vx2 * sc, vy2 * sc, sp2 * sc
            x2, y2 = x0 + vx2 * dt, y0 + vy2 * dt
    return x2, y2, vx2, vy2, sp2
