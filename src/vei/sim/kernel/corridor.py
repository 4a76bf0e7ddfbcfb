"""The ego path's corridor test on a packed path table, compiled on scalars (numba).

Imported only when numba is used. One object's gap along the ego's path
(:func:`vei.models.ego.corridor_check` for one object: the CAP's test and the policy
observation's ``gap_m``) and its signed lateral offset from the path
(:func:`vei.sim.observe.path_lateral`), on the packed path rows of
:func:`vei.sim.kernel.pack.path_rows` (``path`` [10, N]: x y yaw cos sin, then their
slopes, on the grid p_s0 + i p_ds). The geometry is :mod:`vei.models.ego_core`'s; this
module adds the table lookups. The engine kernel's CAP (:mod:`vei.sim.kernel.ego`), its
policies' observation (:mod:`vei.sim.kernel.policy`) and the vector env's observation
(:mod:`vei.gym.kernel`) share it. Inlined (``inline="always"``). SI units (m, rad).
"""

# ruff: noqa: N803
from __future__ import annotations

import math

import numba

from vei.models import ego_core as core
from vei.sim.kernel.scalar import idx

_inline = numba.njit(cache=True, inline="always")
path_foot = _inline(core.path_foot_core)
half_diagonal = _inline(core.half_diagonal_core)
corridor_entry = _inline(core.corridor_entry_core)
box_extent = _inline(core.box_extent_core)
corridor_gap = _inline(core.corridor_gap_core)


@numba.njit(cache=True, inline="always")
def path_point(path, p_s0, p_ds, n_p, s):  # type: ignore[no-untyped-def]
    """(x [m], y [m], cos, sin of the heading) of the path at arc length s [m]."""
    i, w = idx(p_s0, p_ds, n_p, s)
    return (
        path[0, i] + w * path[5, i],
        path[1, i] + w * path[6, i],
        path[3, i] + w * path[8, i],
        path[4, i] + w * path[9, i],
    )


@numba.njit(cache=True, inline="always")
def corridor_at(path, p_s0, p_ds, n_p, s, q, px, py, pyaw, L, W, hd, Le, halfw, rng):  # type: ignore[no-untyped-def]
    """(ahead, gap [m]) of a box L x W [m] (half diagonal hd [m]) at (px, py [m], pyaw
    [rad]) in the corridor of half width halfw [m] ahead of an ego of length Le [m] at arc
    length s [m], within range rng [m]; q = :func:`path_point` at s (the same for every
    object). Not ahead: (False, inf)."""
    s_q, _ = path_foot(s, px, py, q[0], q[1], q[2], q[3])
    fx, fy, pc, ps = path_point(path, p_s0, p_ds, n_p, s_q)
    s_q, lat = path_foot(s_q, px, py, fx, fy, pc, ps)
    d_front, entry = corridor_entry(s_q, lat, s, Le, halfw, hd)
    if entry:
        ext = box_extent(math.cos(pyaw), math.sin(pyaw), pc, ps, L, W)
        return corridor_gap(d_front, ext, rng)
    return False, math.inf


@numba.njit(cache=True, inline="always")
def lateral_at(path, p_s0, p_ds, n_p, s, q, x, y):  # type: ignore[no-untyped-def]
    """Signed lateral offset [m] of (x, y) [m] from the path near arc length s [m] (left
    positive); q = :func:`path_point` at s."""
    s_q = s + (x - q[0]) * q[2] + (y - q[1]) * q[3]
    px, py, pc, ps = path_point(path, p_s0, p_ds, n_p, s_q)
    return (y - py) * pc - (x - px) * ps


__all__ = [
    "box_extent",
    "corridor_at",
    "corridor_entry",
    "corridor_gap",
    "half_diagonal",
    "lateral_at",
    "path_foot",
    "path_point",
]
