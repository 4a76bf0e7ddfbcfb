"""The rider's social-force laws shared by both engines: desired velocity, destination force,
semi-implicit Euler step, the ego's repulsion, the limits' factor.

Like :mod:`vei.models.ego_core`: NumPy ufuncs, arithmetic and
:func:`vei.models.ego_core.select` only, so that the same source runs vectorised on arrays
(:mod:`vei.models.sfm`, the NumPy engine and its extra riders) and compiled by numba on
scalars (:mod:`vei.sim.kernel.sfm`, the compiled kernel's primary and extra riders), in the
compiled kernel's order of operations (pinned by tests/sim/kernel/test_kernel_regression.py).

The ego's repulsion (influential point, magnitude and direction) and the force / speed
limits are here too. Their rare cases are separate functions that the caller gates: the
direction away from the ego's centre where the rider is on the influential point
(:func:`away_from_centre_core`: the compiled kernel calls it behind ``if tiny``, the NumPy
step where any variant needs it), and the limits' factor (:func:`cap_factor_core`, taken
where a limit binds: behind a branch in the kernel, by ``np.where`` in the NumPy step).
The repulsion between riders / pedestrians is split the same way: :func:`rider_gap_core`
says where it acts (beyond :data:`RIDER_FORCE_CUTOFF_M` it does not), and
:func:`rider_repulsion_core` is taken there (behind a branch in the kernel, so the exp is
skipped for far agents; masked in :func:`vei.models.sfm.rider_force`).

Units: positions [m], velocities [m/s], forces [N], masses [kg], times [s].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vei.boxes import closest_point_core
from vei.models.ego_core import maximum, minimum, select

#: Distance below which a direction is undefined [m] (the rider on the influential point,
#: or on the ego's centre, or two riders' centres).
TINY_M = 1e-9

#: Gap [m] beyond which another rider / pedestrian exerts no repulsion (less than
#: A_r exp(-10 b_r): 2e-6 N at the defaults).
RIDER_FORCE_CUTOFF_M = 10.0


def desired_velocity_core(
    px_m: Any, py_m: Any, gx_m: Any, gy_m: Any, v0_mps: Any, sigma_m: Any, paper_form: Any
) -> tuple[Any, Any]:
    """Desired velocity towards the goal g: ``v0 d / q`` (paper form) or ``v0 d / sqrt(q)``.

    q = |d|^2 + sigma^2 with d = g - p [m]. Returns (vx, vy) [m/s].
    """
    dx = gx_m - px_m
    dy = gy_m - py_m
    q = dx * dx + dy * dy + sigma_m * sigma_m
    f = v0_mps / select(paper_form, q, np.sqrt(q))
    return f * dx, f * dy


def destination_force_core(
    vdes_x_mps: Any, vdes_y_mps: Any, vx_mps: Any, vy_mps: Any, k_des_nspm: Any
) -> tuple[Any, Any]:
    """Destination force ``f_des = k_des (v_des - v)`` [N]."""
    return k_des_nspm * (vdes_x_mps - vx_mps), k_des_nspm * (vdes_y_mps - vy_mps)


def point_mass_core(
    px_m: Any, py_m: Any, vx_mps: Any, vy_mps: Any, fx_n: Any, fy_n: Any, mass_kg: Any, dt_s: Any
) -> tuple[Any, Any, Any, Any]:
    """Semi-implicit Euler step ``v' = v + F / m dt; p' = p + v' dt``. Returns (px, py, vx, vy)."""
    inv_m = 1.0 / mass_kg
    vx = vx_mps + fx_n * inv_m * dt_s
    vy = vy_mps + fy_n * inv_m * dt_s
    return px_m + vx * dt_s, py_m + vy * dt_s, vx, vy


def cap_factor_core(magnitude: Any, cap: Any) -> Any:
    """The factor ``cap / magnitude`` that brings a vector of ``magnitude`` > ``cap`` (> 0)
    down to the cap: the rider's force cap (max_accel m [N]) and speed cap [m/s]. Callers
    apply it only where the magnitude exceeds the cap (elsewhere the vector is unchanged);
    a zero magnitude gives ``cap`` (never used: it cannot exceed a positive cap)."""
    return cap / select(magnitude > 0.0, magnitude, 1.0)


def influential_point_core(
    px_m: Any, py_m: Any, ex_m: Any, ey_m: Any, cos_yaw: Any, sin_yaw: Any,
    half_length_m: Any, half_width_m: Any, front_bumper: Any,
) -> tuple[Any, Any]:  # fmt: skip
    """The ego's point that repels a rider at p [m]: the centre of the front bumper
    (``front_bumper``) or the point of the ego's box (centre e, heading (cos, sin), half
    length / width [m]) closest to p (:func:`vei.boxes.closest_point_core`). Returns
    (qx, qy) [m]."""
    qx, qy = closest_point_core(
        px_m, py_m, ex_m, ey_m, cos_yaw, sin_yaw, half_length_m, half_width_m
    )
    fx = ex_m + half_length_m * cos_yaw
    fy = ey_m + half_length_m * sin_yaw
    return select(front_bumper, fx, qx), select(front_bumper, fy, qy)


def repulsion_core(
    px_m: Any, py_m: Any, qx_m: Any, qy_m: Any, a_n: Any, b_per_m: Any
) -> tuple[Any, Any, Any, Any]:
    """``a exp(-b d)`` [N] and the unit vector from q to p, d = |p - q| [m].

    Returns (magnitude [N], nx, ny, tiny): where ``tiny`` (d < :data:`TINY_M`) the
    direction is undefined (returned as (dx, dy)) and the caller replaces it
    (:func:`away_from_centre_core`).
    """
    dx = px_m - qx_m
    dy = py_m - qy_m
    d = np.sqrt(dx * dx + dy * dy)
    tiny = d < TINY_M
    safe = select(tiny, 1.0, d)
    return a_n * np.exp(-b_per_m * d), dx / safe, dy / safe, tiny


def away_from_centre_core(
    px_m: Any, py_m: Any, ex_m: Any, ey_m: Any, cos_yaw: Any, sin_yaw: Any
) -> tuple[Any, Any]:
    """Unit vector from the ego's centre e to p [m], or the ego's heading (cos, sin) where
    they coincide: the direction of the ego's repulsion on a rider inside its box."""
    ex = px_m - ex_m
    ey = py_m - ey_m
    de = np.sqrt(ex * ex + ey * ey)
    ok = de > TINY_M
    safe = select(ok, de, 1.0)
    return select(ok, ex / safe, cos_yaw), select(ok, ey / safe, sin_yaw)


def rider_gap_core(
    px_m: Any, py_m: Any, qx_m: Any, qy_m: Any, radii_m: Any
) -> tuple[Any, Any, Any, Any, Any]:
    """Where an agent at q [m] repels a rider at p [m]: (dx, dy) = p - q [m], the centre
    distance dc [m], the gap ``dc - radii`` [m] between their discs (radii: the sum of both
    radii; negative where they overlap) and ``acts``: the centres apart (dc >=
    :data:`TINY_M`, else the direction is undefined) and the gap within
    :data:`RIDER_FORCE_CUTOFF_M`."""
    dx = px_m - qx_m
    dy = py_m - qy_m
    dc = np.sqrt(dx * dx + dy * dy)
    gap = dc - radii_m
    acts = np.logical_and(dc >= TINY_M, gap <= RIDER_FORCE_CUTOFF_M)
    return dx, dy, dc, gap, acts


def rider_repulsion_core(dc_m: Any, gap_m: Any, a_n: Any, b_per_m: Any) -> Any:
    """The factor [N/m] that turns p - q into the repulsion ``a exp(-b gap) (p - q) / dc``
    [N] where :func:`rider_gap_core` says it acts (dc > 0 there; not clipped where the discs
    overlap)."""
    return a_n * np.exp(-b_per_m * gap_m) / dc_m


def ray_box_distance_core(  # type: ignore[no-untyped-def]
    px_m, py_m, ux, uy, ex_m, ey_m, cos_yaw, sin_yaw, half_length_m, half_width_m
):
    """Distance [m] from p along the unit direction u to an oriented box (centre e,
    heading (cos, sin), half length / width): 0 where p is inside, +inf where the ray
    misses it (the slab test in the box's frame). Not annotated: numba compiles it from
    its own source where a compiled core calls it (vei.sim.kernel.scalar's overload,
    whose signature must equal this one)."""
    rx = px_m - ex_m
    ry = py_m - ey_m
    lx = rx * cos_yaw + ry * sin_yaw
    ly = -rx * sin_yaw + ry * cos_yaw
    dx = ux * cos_yaw + uy * sin_yaw
    dy = -ux * sin_yaw + uy * cos_yaw
    flat_x = np.abs(dx) < 1e-12
    flat_y = np.abs(dy) < 1e-12
    sdx = select(flat_x, 1.0, dx)
    sdy = select(flat_y, 1.0, dy)
    ax = (-half_length_m - lx) / sdx
    bx = (half_length_m - lx) / sdx
    ay = (-half_width_m - ly) / sdy
    by = (half_width_m - ly) / sdy
    in_x = np.abs(lx) <= half_length_m
    in_y = np.abs(ly) <= half_width_m
    lo_x = select(flat_x, select(in_x, -np.inf, np.inf), minimum(ax, bx))
    hi_x = select(flat_x, select(in_x, np.inf, -np.inf), maximum(ax, bx))
    lo_y = select(flat_y, select(in_y, -np.inf, np.inf), minimum(ay, by))
    hi_y = select(flat_y, select(in_y, np.inf, -np.inf), maximum(ay, by))
    t_in = maximum(lo_x, lo_y)
    t_out = minimum(hi_x, hi_y)
    hit = np.logical_and(t_in <= t_out, t_out >= 0.0)
    return select(hit, maximum(t_in, 0.0), np.inf)


def obstacle_speed_core(
    px_m: Any, py_m: Any, vdx_mps: Any, vdy_mps: Any, speed_mps: Any,
    ex_m: Any, ey_m: Any, cos_yaw: Any, sin_yaw: Any, half_length_m: Any, half_width_m: Any,
    rider_radius_m: Any, margin_m: Any, decel_mps2: Any, tau_s: Any,
) -> Any:  # fmt: skip
    """The speed cap [m/s] of a rider at p riding towards its desired velocity vd, for a
    car's box (centre e, heading, half length / width [m]) in its way: the box is widened
    by the rider's radius (half its diagonal), d is the distance along vd to it
    (:func:`ray_box_distance_core`), and the cap ``sqrt(2 a max(d - margin - v tau, 0))``
    lets it stop ``margin_m`` short (a = ``decel_mps2``, tau the relaxation time m / k_des
    over which it follows a new desired speed). +inf where vd misses the box or is 0."""
    vd = np.sqrt(vdx_mps * vdx_mps + vdy_mps * vdy_mps)
    moving = vd > TINY_M
    safe = select(moving, vd, 1.0)
    d = ray_box_distance_core(
        px_m, py_m, vdx_mps / safe, vdy_mps / safe, ex_m, ey_m, cos_yaw, sin_yaw,
        half_length_m + rider_radius_m, half_width_m + rider_radius_m,
    )  # fmt: skip
    room = d - margin_m - speed_mps * tau_s
    cap = np.sqrt(2.0 * decel_mps2 * maximum(room, 0.0))
    return select(moving, cap, np.inf)
