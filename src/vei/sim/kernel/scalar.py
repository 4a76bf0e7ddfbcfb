"""Scalar numba helpers of the compiled kernel: interpolation index, box overlap (vei.boxes),
rider-rider repulsion (vei.models.sfm_core), and the scalar forms of the model cores'
select / maximum / minimum.

Imported only when numba is used (by :mod:`vei.sim.kernel.loop` and the other kernel
helper modules). Every function is compiled at module level with ``cache=True`` so that
numba's on-disk cache works across processes. Scalars in SI units (m, s, rad, N).
"""

# ruff: noqa: N803
from __future__ import annotations

import numba
from numba import types
from numba.extending import overload

from vei.boxes import closest_point_core, overlap_core
from vei.models import ego_core as core
from vei.models import sfm_core

# The model cores (vei.models.ego_core, sfm_core) are written with these three helpers;
# on scalars numba compiles them to what the hand-written kernel used.


@overload(core.select)
def _select_scalar(cond, a, b):  # type: ignore[no-untyped-def]
    """numba: :func:`vei.models.ego_core.select` on scalars is ``a if cond else b``."""
    if isinstance(cond, types.Boolean) and all(isinstance(t, types.Number) for t in (a, b)):

        def impl(cond, a, b):  # type: ignore[no-untyped-def]
            if cond:
                return a
            return b

        return impl
    return None


@overload(core.maximum)
def _maximum_scalar(a, b):  # type: ignore[no-untyped-def]
    """numba: :func:`vei.models.ego_core.maximum` on scalars is Python's ``max(a, b)``."""
    if all(isinstance(t, types.Number) for t in (a, b)):
        return lambda a, b: max(a, b)
    return None


@overload(core.minimum)
def _minimum_scalar(a, b):  # type: ignore[no-untyped-def]
    """numba: :func:`vei.models.ego_core.minimum` on scalars is Python's ``min(a, b)``."""
    if all(isinstance(t, types.Number) for t in (a, b)):
        return lambda a, b: min(a, b)
    return None


@overload(closest_point_core)
def _closest_point_scalar(px, py, cx, cy, c, s, hl, hw):  # type: ignore[no-untyped-def]
    """numba: :func:`vei.boxes.closest_point_core` on scalars, compiled from its own source
    (a core that calls it, vei.models.sfm_core.influential_point_core, then compiles)."""
    if all(isinstance(t, types.Number) for t in (px, py, cx, cy, c, s, hl, hw)):
        return closest_point_core
    return None


@overload(sfm_core.ray_box_distance_core)
def _ray_box_scalar(  # type: ignore[no-untyped-def]
    px_m, py_m, ux, uy, ex_m, ey_m, cos_yaw, sin_yaw, half_length_m, half_width_m
):
    """numba: :func:`vei.models.sfm_core.ray_box_distance_core` on scalars, compiled from
    its own source (the obstacle cap that calls it, obstacle_speed_core, then compiles)."""
    args = (px_m, py_m, ux, uy, ex_m, ey_m, cos_yaw, sin_yaw, half_length_m, half_width_m)
    if all(isinstance(t, types.Number) for t in args):
        return sfm_core.ray_box_distance_core
    return None


_rider_gap = numba.njit(cache=True, inline="always")(sfm_core.rider_gap_core)
_rider_repulsion = numba.njit(cache=True, inline="always")(sfm_core.rider_repulsion_core)


@numba.njit(cache=True)
def rforce(px, py, qx, qy, rs, a, bb):  # type: ignore[no-untyped-def]
    """Rider repulsion on p from q (vei.models.sfm.rider_force, the same cores).

    Args: positions p, q [m]; rs the sum of both radii [m]; a the strength [N]; bb the
    decay [1/m]. Returns the force (fx, fy) [N]: a exp(-bb gap) along q -> p; zero (and
    no exp taken) where :func:`vei.models.sfm_core.rider_gap_core` says it does not act.
    """
    dx, dy, dc, gap, acts = _rider_gap(px, py, qx, qy, rs)
    if not acts:
        return 0.0, 0.0
    inv = _rider_repulsion(dc, gap, a, bb)
    return inv * dx, inv * dy


@numba.njit(cache=True, inline="always")
def ped_forces(sx, sy, x0, y0, r0, k, ped_idx, ped_rad, oX, oY, oACT, a, bb):  # type: ignore[no-untyped-def]
    """Add the repulsion of the active pedestrians at step k to (sx, sy) [N], in order.

    Args: x0, y0 [m] and r0 [m] the repelled rider's position and radius; ped_idx [n] their
    columns in the others' arrays oX, oY, oACT [T, no]; ped_rad [n] their radii [m]; a [N],
    bb [1/m] the force parameters. Returns the new (sx, sy), summed one pedestrian at a time
    in index order (the order of the NumPy reference).
    """
    for q in range(ped_idx.shape[0]):
        jj = ped_idx[q]
        if oACT[k, jj]:
            hx_, hy_ = rforce(x0, y0, oX[k, jj], oY[k, jj], r0 + ped_rad[q], a, bb)
            sx += hx_
            sy += hy_
    return sx, sy


@numba.njit(cache=True)
def idx(t0: float, dt: float, n: int, q: float) -> tuple[int, float]:
    """Linear-interpolation cell of q on the grid t0 + i dt (i < n), clamped to the grid.

    Returns (i, w): the left node i in [0, n - 2] and the weight w in [0, 1] (the value is
    table[i] + w * slope[i], slopes per cell).
    """
    f = (q - t0) * (1.0 / dt)
    if f < 0.0:
        f = 0.0
    elif f > n - 1.0:
        f = n - 1.0
    i = int(f)
    if i > n - 2:
        i = max(n - 2, 0)
    return i, f - i


#: True when the oriented boxes a and b overlap (separating-axis test, 1e-9 m slack): the
#: NumPy engine's own :func:`vei.boxes.overlap_core`, compiled (args: centres [m], yaws
#: [rad], lengths and widths [m] of the two boxes).
sat = numba.njit(cache=True)(overlap_core)
