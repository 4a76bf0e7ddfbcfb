"""Scalar operations of the fused metrics (:mod:`vei.metrics.fused`), each computing what
its NumPy counterpart computes, operation by operation, so that results are bit-identical:
np.nan_to_num, np.maximum / np.minimum (NaN propagates; a tie gives the second operand),
NumPy's pairwise summation, and the oriented-box geometry of :mod:`vei.boxes` (box gap,
overlap, corners, corner-set overlap, time to contact) for one pair of boxes.

numba-compiled (``cache=True``); imported only where numba is used. Compiled into the
engine kernel too (``vei.sim.kernel.cache.KERNEL_SOURCES``).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math

import numba
import numpy as np

_DBL_MAX = np.finfo(np.float64).max
_EPS = 1e-12


@numba.njit(cache=True, error_model="numpy", inline="always")
def nan_to_num(x):  # type: ignore[no-untyped-def]
    """np.nan_to_num of a scalar: NaN -> 0, +-inf -> +-max float."""
    if math.isnan(x):
        return 0.0
    if math.isinf(x):
        return _DBL_MAX if x > 0 else -_DBL_MAX
    return x


@numba.njit(cache=True, error_model="numpy", inline="always")
def maximum(a, b):  # type: ignore[no-untyped-def]
    """np.maximum of two floats as NumPy's loop computes it: NaN propagates, a tie (e.g.
    -0.0 vs 0.0) gives the second operand (np.maximum(-0.0, 0.0) is 0.0)."""
    return a if (a > b or math.isnan(a)) else b


@numba.njit(cache=True, error_model="numpy", inline="always")
def minimum(a, b):  # type: ignore[no-untyped-def]
    """np.minimum of two floats as NumPy's loop computes it: NaN propagates, a tie gives
    the second operand."""
    return a if (a < b or math.isnan(a)) else b


@numba.njit(cache=True, error_model="numpy")
def _block_sum(x, lo, n):  # type: ignore[no-untyped-def]
    """A leaf of :func:`pairwise_sum` (n <= 128): n < 8 a plain loop from 0, else eight
    accumulators combined ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7)), then the tail."""
    if n < 8:
        res = 0.0
        for i in range(n):
            res += x[lo + i]
        return res
    r0 = x[lo]
    r1 = x[lo + 1]
    r2 = x[lo + 2]
    r3 = x[lo + 3]
    r4 = x[lo + 4]
    r5 = x[lo + 5]
    r6 = x[lo + 6]
    r7 = x[lo + 7]
    i = 8
    stop = n - (n % 8)
    while i < stop:
        r0 += x[lo + i]
        r1 += x[lo + i + 1]
        r2 += x[lo + i + 2]
        r3 += x[lo + i + 3]
        r4 += x[lo + i + 4]
        r5 += x[lo + i + 5]
        r6 += x[lo + i + 6]
        r7 += x[lo + i + 7]
        i += 8
    res = ((r0 + r1) + (r2 + r3)) + ((r4 + r5) + (r6 + r7))
    while i < n:
        res += x[lo + i]
        i += 1
    return res


@numba.njit(cache=True, error_model="numpy")
def pairwise_sum(x, lo, n):  # type: ignore[no-untyped-def]
    """NumPy's pairwise summation of x[lo:lo + n] (numpy/_core/src/umath/loops_utils.h):
    blocks of <= 128 by :func:`_block_sum`; a longer range splits at n2 = n // 2 - (n // 2)
    % 8 and adds the two halves' sums. A row reduction (``arr.sum(axis=1)`` of a
    C-contiguous float64 array) is 0 + this (checked against NumPy in the tests).
    Iterative (an explicit stack): numba's on-disk cache cannot link a recursive function
    into a cached caller."""
    if n <= 128:
        return _block_sum(x, lo, n)
    s_lo = np.empty(192, dtype=np.int64)
    s_n = np.empty(192, dtype=np.int64)
    s_join = np.empty(192, dtype=np.bool_)
    vals = np.empty(96)
    sp = 0
    vp = 0
    s_lo[0], s_n[0], s_join[0] = lo, n, False
    sp = 1
    while sp > 0:
        sp -= 1
        a, m, join = s_lo[sp], s_n[sp], s_join[sp]
        if join:  # both halves done: left + right
            vp -= 1
            vals[vp - 1] = vals[vp - 1] + vals[vp]
        elif m <= 128:
            vals[vp] = _block_sum(x, a, m)
            vp += 1
        else:
            n2 = m // 2
            n2 -= n2 % 8
            s_lo[sp], s_n[sp], s_join[sp] = a, m, True
            s_lo[sp + 1], s_n[sp + 1], s_join[sp + 1] = a + n2, m - n2, False
            s_lo[sp + 2], s_n[sp + 2], s_join[sp + 2] = a, n2, False
            sp += 3
    return vals[0]


@numba.njit(cache=True, error_model="numpy")
def box_gap(ax, ay, ayaw, al, aw, bx, by, byaw, bl, bw):  # type: ignore[no-untyped-def]
    """:func:`vei.boxes.box_gap` of two scalar boxes (the same operations in order) [m]."""
    ca, sa, cb, sb = np.cos(ayaw), np.sin(ayaw), np.cos(byaw), np.sin(byaw)
    return box_gap_cs(ax, ay, ca, sa, al, aw, bx, by, cb, sb, bl, bw)


@numba.njit(cache=True, error_model="numpy", inline="always")
def overlap_cs(ax, ay, ca, sa, al, aw, bx, by, cb, sb, bl, bw):  # type: ignore[no-untyped-def]
    """:func:`vei.boxes.overlap_core` of scalar boxes given the cos / sin of their yaws
    (the same operations in order; the caller's cos / sin are the ones it would take)."""
    dx, dy = bx - ax, by - ay
    hla, hwa, hlb, hwb = 0.5 * al, 0.5 * aw, 0.5 * bl, 0.5 * bw
    cd = np.abs(ca * cb + sa * sb)
    sd = np.abs(sa * cb - ca * sb)
    eps = 1e-9
    if np.abs(dx * ca + dy * sa) > hla + hlb * cd + hwb * sd + eps:
        return False
    if np.abs(-dx * sa + dy * ca) > hwa + hlb * sd + hwb * cd + eps:
        return False
    if np.abs(dx * cb + dy * sb) > hlb + hla * cd + hwa * sd + eps:
        return False
    if np.abs(-dx * sb + dy * cb) > hwb + hla * sd + hwa * cd + eps:
        return False
    return True


@numba.njit(cache=True, error_model="numpy", inline="always")
def box_gap_cs(ax, ay, ca, sa, al, aw, bx, by, cb, sb, bl, bw):  # type: ignore[no-untyped-def]
    """:func:`box_gap` given the cos / sin of the two yaws (each taken once per step)."""
    dx = bx - ax
    dy = by - ay
    ha, wa = 0.5 * al, 0.5 * aw
    hb, wb = 0.5 * bl, 0.5 * bw
    best = np.inf
    for pair in range(2):
        if pair == 0:
            c1, s1, h1, w1, c2, s2, h2, w2, sign = ca, sa, ha, wa, cb, sb, hb, wb, 1.0
        else:
            c1, s1, h1, w1, c2, s2, h2, w2, sign = cb, sb, hb, wb, ca, sa, ha, wa, -1.0
        ru = sign * (dx * c1 + dy * s1)
        rv = sign * (-dx * s1 + dy * c1)
        cu, cv = c2 * c1 + s2 * s1, -c2 * s1 + s2 * c1
        for corner in range(4):
            el = h2 if corner < 2 else -h2
            ew = w2 if corner % 2 == 0 else -w2
            pu = maximum(np.abs(ru + (el * cu - ew * cv)) - h1, 0.0)
            pv = maximum(np.abs(rv + (el * cv + ew * cu)) - w1, 0.0)
            best = minimum(best, pu * pu + pv * pv)
    if overlap_cs(ax, ay, ca, sa, al, aw, bx, by, cb, sb, bl, bw):
        return 0.0
    return np.sqrt(best)


@numba.njit(cache=True, error_model="numpy")
def _corners(x, y, yaw, length, width, out):  # type: ignore[no-untyped-def]
    """:func:`vei.boxes.box_corners` of one box into out [4, 2]."""
    hl, hw = 0.5 * length, 0.5 * width
    c, s = np.cos(yaw), np.sin(yaw)
    for i in range(4):
        lx = -hl if (i == 0 or i == 3) else hl
        ly = -hw if i < 2 else hw
        out[i, 0] = x + c * lx - s * ly
        out[i, 1] = y + s * lx + c * ly


@numba.njit(cache=True, error_model="numpy")
def _corners_overlap(A, Bc):  # type: ignore[no-untyped-def]
    """:func:`vei.boxes.corners_overlap` of two corner sets [4, 2]."""
    for which in range(2):
        C = A if which == 0 else Bc
        for k in range(2):
            e0 = C[k + 1, 0] - C[k, 0]
            e1 = C[k + 1, 1] - C[k, 1]
            x0, x1 = -e1, e0
            amax = -np.inf
            amin = np.inf
            bmax = -np.inf
            bmin = np.inf
            for i in range(4):
                pa = A[i, 0] * x0 + A[i, 1] * x1
                pb = Bc[i, 0] * x0 + Bc[i, 1] * x1
                amax = max(amax, pa)
                amin = min(amin, pa)
                bmax = max(bmax, pb)
                bmin = min(bmin, pb)
            scale = max(np.sqrt(x0 * x0 + x1 * x1), _EPS)
            tol = 1e-9 * scale
            if amax < bmin - tol or bmax < amin - tol:
                return False
    return True


@numba.njit(cache=True, error_model="numpy")
def time_to_contact(A, Bc, v0, v1):  # type: ignore[no-untyped-def]
    """:func:`vei.boxes.time_to_contact` of corner sets A, B [4, 2] with B moving at
    (v0, v1) relative to A [s]: 0 overlapping, inf never."""
    best = np.inf
    for which in range(2):
        if which == 0:
            V, E, sign = Bc, A, 1.0
        else:
            V, E, sign = A, Bc, -1.0
        w0 = sign * v0
        w1 = sign * v1
        hit = np.inf
        for i in range(4):
            for j in range(4):
                jn = (j + 1) % 4
                e0 = E[jn, 0] - E[j, 0]
                e1 = E[jn, 1] - E[j, 1]
                denom = w0 * e1 - w1 * e0
                if not np.abs(denom) > _EPS:
                    continue
                ap0 = E[j, 0] - V[i, 0]
                ap1 = E[j, 1] - V[i, 1]
                s = (ap0 * e1 - ap1 * e0) / denom
                u = (ap0 * w1 - ap1 * w0) / denom
                if s >= 0.0 and u >= -1e-12 and u <= 1.0 + 1e-12:
                    hit = minimum(hit, s)
        best = minimum(best, hit)
    if _corners_overlap(A, Bc):
        return 0.0
    return best


@numba.njit(cache=True, error_model="numpy")
def on_course(ex, ey, eyaw, Le, We, ox, oy, oyaw, Lr, Wr, rv0, rv1, A, Bc):  # type: ignore[no-untyped-def]
    """conflict.on_course of one step: the boxes meet if both keep their velocities."""
    _corners(ex, ey, eyaw, Le, We, A)
    _corners(ox, oy, oyaw, Lr, Wr, Bc)
    return np.isfinite(time_to_contact(A, Bc, rv0, rv1))
