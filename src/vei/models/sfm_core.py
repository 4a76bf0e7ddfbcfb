"""The rider's social-force laws shared by both engines: desired velocity, destination force,
semi-implicit Euler step.

Like :mod:`vei.models.ego_core`: NumPy ufuncs, arithmetic and
:func:`vei.models.ego_core.select` only, so that the same source runs vectorised on arrays
(:mod:`vei.models.sfm`, the NumPy engine and its extra riders) and compiled by numba on
scalars (:mod:`vei.sim._kernel_sfm`, the compiled kernel's primary and extra riders), in the
compiled kernel's order of operations (pinned by tests/sim/test_kernel_regression.py).

The vehicle repulsion, the rider-rider repulsion and the force / speed limits stay written
twice (:mod:`vei.models.sfm` and :mod:`vei.sim._kernel_sfm` / ``_kernel_scalar``): the
compiled kernel skips their work by branches (no exp beyond the cutoff, no rescaling
division unless a limit binds) that a branch-free form would put on every step's critical
path (a sqrt and a division before the velocity update).

Units: positions [m], velocities [m/s], forces [N], masses [kg], times [s].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vei.models.ego_core import select


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
