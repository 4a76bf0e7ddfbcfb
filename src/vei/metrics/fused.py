"""Per-run scalar metrics compiled with numba, bit-identical to :func:`vei.metrics.summarize`.

The sweep's metrics (collision, TTC zones and safety index, minimum gap and TTC, DRAC,
impact severity, ego speed statistics) of ONE run, from its [T] channels, in one pass
over the steps and without any [B, T] array: what the compiled engine kernel calls at the
end of each variant (``vei.sim.engine.simulate_metrics``), and what :func:`fused_summary`
runs over the rows of a recorded Trace.

Every formula mirrors the NumPy code of :mod:`vei.metrics.ttc`, :mod:`.conflict`,
:mod:`.severity`, :mod:`.kinematics` and :mod:`vei.boxes` operation by operation (same
operands, same order, NaN rules of np.maximum / np.fmin, NumPy's pairwise summation for
the mean and standard deviation; the scalar pieces are in :mod:`vei.metrics.fused_ops`),
so that the results equal
``summarize(as_timeseries_trace(trace), names=..., params=...)`` bit for bit (==, NaN ==
NaN; tests/metrics/test_fused.py). The run is scored as :func:`vei.metrics.timeseries.
as_timeseries_trace` scores it: the rider's velocity is speed * (cos yaw, sin yaw) with a
NaN yaw / speed read as 0, its position is NaN while inactive, the collision flag is
latched and a non-finite ego acceleration is replaced as np.nan_to_num does.

Needs numba (the optional extra ``fast``); ``import vei.metrics`` never imports this module.

Layout (:mod:`vei.metrics.fused_layout`, importable without numba):
    channels ``ch [N_CH, T]`` float64 (rows CH_*): ego x, y [m], yaw [rad], speed [m/s],
    acceleration [m/s^2]; rider x, y [m], yaw [rad], speed [m/s], active (0/1), collided
    (0/1, latched here). ``cfg [N_CFG]`` (rows C_*, :func:`config_vector`). Output row
    ``out [N_FUSED]`` in :data:`FUSED_METRICS` order; collision and drac_unavoidable as
    0/1, impact_side as an index of ``severity.SIDES`` and striking of
    ``severity.STRIKING`` (-1 = '').
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence

import numba
import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.metrics._trace import TraceArrays, arrays, param_of
from vei.metrics.config import MetricsConfig
from vei.metrics.fused_layout import (
    C_AHEAD,
    C_ALERT,
    C_CAR,
    C_CEIL,
    C_MINV,
    C_REACT,
    C_RIDER,
    C_SAFE,
    CH_EA,
    CH_EV,
    CH_EX,
    CH_EY,
    CH_EYAW,
    CH_RACT,
    CH_RCOL,
    CH_RSP,
    CH_RX,
    CH_RY,
    CH_RYAW,
    FUSED_METRICS,
    M_ALERT,
    M_ALL,
    M_ATT,
    M_COLL,
    M_COLL_T,
    M_DRAC,
    M_DVC,
    M_DVR,
    M_FSG,
    M_FST,
    M_GAP,
    M_IMPACT,
    M_INJ,
    M_MEAN,
    M_MIN,
    M_PEAK,
    M_SAFE,
    M_SI,
    M_SIDE,
    M_SIR,
    M_STD,
    M_STL,
    M_STRIKE,
    M_TCOLL,
    M_TTC,
    M_UNAV,
    N_CFG,
    N_CH,
    N_FUSED,
    check_names,
    config_vector,
    metrics_frame,
)  # fmt: skip
from vei.metrics.fused_ops import (
    _corners,
    box_gap_cs,
    maximum,
    minimum,
    nan_to_num,
    on_course,
    pairwise_sum,
    time_to_contact,
)
from vei.metrics.severity import STANDING_MPS as STANDING
from vei.types import Trace

__all__ = [
    "FUSED_METRICS", "N_CFG", "N_CH", "N_FUSED", "config_vector", "fused_summary",
    "metrics_frame", "rows_metrics", "run_metrics",
]  # fmt: skip


@numba.njit(cache=True, error_model="numpy")
def run_metrics(t, dt, ch, Le, We, Lr, Wr, cfg, mass_kg, brake_mps2, out):  # type: ignore[no-untyped-def]
    """The fused metrics of one run into out [N_FUSED] (see the module docstring).

    Args:
        t: [T] step times [s]; dt: the step [s] (t[1] - t[0], 0 when T = 1).
        ch: [N_CH, >= T] channels (only the first T = t.size columns are read).
        Le, We, Lr, Wr: ego / rider box length and width [m].
        cfg: [N_CFG] :func:`config_vector`.
        mass_kg: the run's rider mass [kg]; brake_mps2: its car's full brake [m/s^2].
        out: [N_FUSED] float64, written.
    """
    n = t.size
    safe, alert, ahead_only, min_v = cfg[C_SAFE], cfg[C_ALERT], cfg[C_AHEAD] > 0.5, cfg[C_MINV]
    react = cfg[C_REACT]
    A = np.empty((4, 2))
    Bc = np.empty((4, 2))
    n_safe = 0
    n_att = 0
    n_alert = 0
    n_coll = 0
    n_all = 0
    latched = False
    first = -1
    gap_finite = False
    min_gap = np.nan
    ttc_any = False
    min_ttc = np.nan
    present = False
    # DRAC candidates (ahead, not latched, closing): their gap is exact (g_ok) or, where
    # the lower bound below decided everything else at that step, taken at the end only
    # if the candidate can still be the largest (:func:`_max_drac`).
    m = 0
    cand_k = np.empty(n, dtype=np.int64)
    cand_f = np.empty((_N_CF, n))
    # Lower bound of the box gap: centre distance minus the two half-diagonals, less a
    # margin far above the rounding of box_gap_cs and the 1e-9 tolerance of its overlap
    # test (an overlap it reports is at most ~1.5e-9 m apart): lb <= box_gap_cs(...).
    r_sum = 0.5 * math.hypot(Le, We) + 0.5 * math.hypot(Lr, Wr)
    # the last yaws whose cos / sin were taken (NaN: none yet; NaN never equals)
    last_eyaw, last_ce, last_se = np.nan, np.nan, np.nan
    last_oyaw, last_co, last_so = np.nan, np.nan, np.nan
    peak = 0.0
    v_min = 0.0
    k_seen = -1  # first present step (first seen: vei.metrics.seen, no sensor model)
    n_rel_ok = 0  # present steps before contact with a relative TTC > alert
    for k in range(n):
        ex, ey, eyaw, v = ch[CH_EX, k], ch[CH_EY, k], ch[CH_EYAW, k], ch[CH_EV, k]
        act = ch[CH_RACT, k] != 0.0
        if ch[CH_RCOL, k] != 0.0 and not latched:
            latched = True
            first = k
        decel = 0.0 if latched else -nan_to_num(ch[CH_EA, k])
        peak = decel if k == 0 else maximum(peak, decel)
        v_min = v if k == 0 else minimum(v_min, v)
        if not act:
            continue  # zone inactive; gap, TTC and DRAC are NaN / no candidate
        n_all += 1
        if k_seen < 0:
            k_seen = k
        present = present or not latched
        ryaw, rsp = ch[CH_RYAW, k], ch[CH_RSP, k]
        oyaw = ryaw if np.isfinite(ryaw) else 0.0
        osp = rsp if np.isfinite(rsp) else 0.0
        ox, oy = ch[CH_RX, k], ch[CH_RY, k]
        ok = np.isfinite(ox) and np.isfinite(oy)
        bx, by = (ox, oy) if ok else (1e9, 1e9)
        if not _same(eyaw, last_eyaw):  # cos / sin of the same bits are the same
            last_eyaw = eyaw
            last_ce, last_se = np.cos(eyaw), np.sin(eyaw)
        ce, se = last_ce, last_se
        dx = ox - ex
        dy = oy - ey
        ahead = ce * dx + se * dy > 0.0
        ttc_free = latched or not v > min_v or (ahead_only and not ahead)
        # the exact gap only where the bound leaves the minimum gap, the TTC zone or the
        # minimum TTC open: lb >= min_gap, and a TTC that is 0 / inf or lb / v > safe
        # and >= min_ttc (g / v >= lb / v for v > 0: division rounds monotonically)
        gx, gy = bx - ex, by - ey
        lb = math.sqrt(gx * gx + gy * gy) - r_sum - (1e-6 + 1e-9 * (abs(gx) + abs(gy) + r_sum))
        g_ok = not (math.isfinite(lb) and math.isfinite(eyaw) and lb >= min_gap)
        tl = np.inf
        if not g_ok and not ttc_free:
            tl = lb / v
            g_ok = not (v > 0.0 and tl > safe and tl >= min_ttc)
        g = np.nan
        co, so = 0.0, 0.0
        if g_ok or (ahead and not latched):
            if not _same(oyaw, last_oyaw):
                last_oyaw = oyaw
                last_co, last_so = np.cos(oyaw), np.sin(oyaw)
            co, so = last_co, last_so
        if g_ok:
            g = box_gap_cs(ex, ey, ce, se, Le, We, bx, by, co, so, Lr, Wr)
            if np.isfinite(g):
                gap_finite = True
            if not math.isnan(g) and (math.isnan(min_gap) or g < min_gap):
                min_gap = g
        # the paper's TTC and its zone (tl: the same outcome as g / v, see above)
        ttc = (g / v if g_ok else tl) if v > min_v else np.inf
        if ahead_only and not ahead:
            ttc = np.inf
        if latched:
            ttc = 0.0
        if not math.isnan(ttc):
            ttc_any = True
            if math.isnan(min_ttc) or ttc < min_ttc:
                min_ttc = ttc
        if latched:
            n_coll += 1
        elif ttc > safe:
            n_safe += 1
        elif ttc > alert:
            n_att += 1
        else:
            n_alert += 1
        if not latched:  # the relative TTC's zone (safety_index_rel)
            if not _same(oyaw, last_oyaw):
                last_oyaw = oyaw
                last_co, last_so = np.cos(oyaw), np.sin(oyaw)
            co, so = last_co, last_so
            if _rel_ttc_above(ex, ey, eyaw, ce, se, v, bx, by, oyaw, co, so, osp, lb,
                              alert, Le, We, Lr, Wr, A, Bc):  # fmt: skip
                n_rel_ok += 1
        # DRAC candidates: ahead, closing, apart, before contact; the largest eligible
        # one on a collision course
        if not ahead or latched:
            continue
        ovx = nan_to_num(osp * co)
        ovy = nan_to_num(osp * so)
        v_close = v - (ovx * ce + ovy * se)
        if not v_close > 0.0:
            continue
        if g_ok:
            gd = nan_to_num(g)
            if not (gd > 0.0 and gd / v_close >= react):
                continue
            ub = v_close * v_close / (2.0 * gd)  # numpy's x**2 is x * x; exact
        else:  # an upper bound of the DRAC (gd >= lb > 0), inf where lb <= 0
            ub = v_close * v_close / (2.0 * lb) if lb > 0.0 else np.inf
        cand_k[m] = k
        cand_f[_CF_UB, m] = ub
        cand_f[_CF_G, m] = g  # NaN: not taken yet
        cand_f[_CF_VC, m] = v_close
        cand_f[_CF_CE, m], cand_f[_CF_SE, m] = ce, se
        cand_f[_CF_CO, m], cand_f[_CF_SO, m] = co, so
        cand_f[_CF_RV0, m] = ovx - v * ce
        cand_f[_CF_RV1, m] = ovy - v * se
        cand_f[_CF_YAW, m] = oyaw
        m += 1
    best = _max_drac(ch, cand_k, cand_f, m, Le, We, Lr, Wr, react, A, Bc)
    for j in range(N_FUSED):
        out[j] = np.nan
    hit = first >= 0
    out[M_COLL] = 1.0 if hit else 0.0
    out[M_COLL_T] = t[first] if hit else np.nan
    out[M_SAFE] = float(n_safe) * dt
    out[M_ATT] = float(n_att) * dt
    out[M_ALERT] = float(n_alert) * dt
    out[M_TCOLL] = float(n_coll) * dt
    out[M_ALL] = float(n_all) * dt
    if hit:
        out[M_SI] = 0.0
    elif n_all > 0:
        out[M_SI] = float(n_safe + n_att) / float(n_all)
    out[M_GAP] = min_gap if gap_finite else np.nan
    out[M_TTC] = min_ttc if ttc_any else np.nan
    ceiling = cfg[C_CEIL] if not math.isnan(cfg[C_CEIL]) else brake_mps2
    drac = best if present else np.nan
    out[M_DRAC] = minimum(drac, ceiling)
    out[M_UNAV] = 1.0 if drac > ceiling else 0.0
    out[M_PEAK] = maximum(peak, 0.0)
    out[M_MIN] = v_min
    mean = pairwise_sum(ch[CH_EV], 0, n) / float(n)
    sq = np.empty(n)
    for k in range(n):
        d = ch[CH_EV, k] - mean
        sq[k] = d * d
    out[M_MEAN] = mean
    out[M_STD] = np.sqrt(pairwise_sum(sq, 0, n) / float(n))
    _severity(ch, hit, first, Le, We, cfg, mass_kg, out)
    if hit:
        out[M_SIR] = 0.0
    elif n_all > 0:
        out[M_SIR] = float(n_rel_ok) / float(n_all)
    _first_seen(t, ch, k_seen, hit, first, Le, We, Lr, Wr, react, ceiling, A, Bc, out)


@numba.njit(cache=True, error_model="numpy")
def _rel_ttc_above(ex, ey, eyaw, ce, se, v, bx, by, oyaw, co, so, osp, lb, limit, Le, We, Lr, Wr, A, Bc):  # type: ignore[no-untyped-def]  # fmt: skip
    """The relative-velocity TTC of one step (vei.metrics.ttc.relative_ttc) exceeds
    ``limit`` [s]. Decided without the box sweep where the gap's lower bound lb exceeds
    what the relative speed closes in ``limit`` (with a margin far above the sweep's
    rounding); else the exact time to contact of the same corners and velocity."""
    rv0 = osp * co - v * ce
    rv1 = osp * so - v * se
    return _rel_ttc(ex, ey, eyaw, bx, by, oyaw, rv0, rv1, lb, limit, Le, We, Lr, Wr, A, Bc) > limit


@numba.njit(cache=True, error_model="numpy")
def _rel_ttc(ex, ey, eyaw, bx, by, oyaw, rv0, rv1, lb, limit, Le, We, Lr, Wr, A, Bc):  # type: ignore[no-untyped-def]
    """The relative-velocity TTC of one step as NumPy computes it [s]; +inf without the
    box sweep where lb (a lower bound of the gap, NaN = none) rules out contact within
    ``limit`` (0 = always sweep). An ego pose with a NaN has NaN corners, which NumPy's
    overlap test never separates: 0."""
    if not (np.isfinite(ex) and np.isfinite(ey) and np.isfinite(eyaw)):
        return 0.0
    rs = math.sqrt(rv0 * rv0 + rv1 * rv1)
    if limit > 0.0 and math.isfinite(lb) and lb > rs * limit * (1.0 + 1e-6) + 1e-6:
        return np.inf
    _corners(ex, ey, eyaw, Le, We, A)
    _corners(bx, by, oyaw, Lr, Wr, Bc)
    return time_to_contact(A, Bc, rv0, rv1)


@numba.njit(cache=True, error_model="numpy")
def _first_seen(t, ch, k, hit, first, Le, We, Lr, Wr, react, brake, A, Bc, out):  # type: ignore[no-untyped-def]
    """first_seen_gap_m, first_seen_ttc_s, seen_too_late (vei.metrics.seen; first seen =
    the first present step k, -1 = never) into out."""
    if k < 0:
        out[M_FSG] = np.nan
        out[M_FST] = np.nan
        out[M_STL] = 1.0 if hit else 0.0
        return
    ex, ey, eyaw, v = ch[CH_EX, k], ch[CH_EY, k], ch[CH_EYAW, k], ch[CH_EV, k]
    ryaw, rsp = ch[CH_RYAW, k], ch[CH_RSP, k]
    oyaw = ryaw if np.isfinite(ryaw) else 0.0
    osp = rsp if np.isfinite(rsp) else 0.0
    ox, oy = ch[CH_RX, k], ch[CH_RY, k]
    ok = np.isfinite(ox) and np.isfinite(oy)
    bx, by = (ox, oy) if ok else (1e9, 1e9)
    ce, se = np.cos(eyaw), np.sin(eyaw)
    co, so = np.cos(oyaw), np.sin(oyaw)
    g = box_gap_cs(ex, ey, ce, se, Le, We, bx, by, co, so, Lr, Wr)
    if hit and first <= k:
        ttc = 0.0
    else:
        rv0, rv1 = osp * co - v * ce, osp * so - v * se
        ttc = _rel_ttc(ex, ey, eyaw, bx, by, oyaw, rv0, rv1, np.nan, 0.0, Le, We, Lr, Wr, A, Bc)
    out[M_FSG] = g
    out[M_FST] = ttc
    stop = v * react + v * v / (2.0 * brake)
    late = hit and (t[first] - t[k] <= react + 1e-9)
    close = np.isfinite(ttc) and g < stop
    out[M_STL] = 1.0 if (late or close) else 0.0


@numba.njit(cache=True, error_model="numpy", inline="always")
def _same(a, b):  # type: ignore[no-untyped-def]
    """a and b are the same float bit for bit (NaN never; -0.0 is not 0.0)."""
    return a == b and math.copysign(1.0, a) == math.copysign(1.0, b)


#: Rows of a DRAC candidate's floats: upper bound (the DRAC where the gap is exact), the
#: gap (NaN until taken), closing speed, cos / sin of the ego and rider yaws, relative
#: velocity of the rider (x, y), rider yaw.
_CF_UB, _CF_G, _CF_VC, _CF_CE, _CF_SE, _CF_CO, _CF_SO, _CF_RV0, _CF_RV1, _CF_YAW = range(10)
_N_CF = 10


@numba.njit(cache=True, error_model="numpy")
def _max_drac(ch, cand_k, cand_f, m, Le, We, Lr, Wr, react, A, Bc):  # type: ignore[no-untyped-def]
    """The largest eligible DRAC on a collision course (conflict._max_drac_raw: the
    largest on course, 0 if none), visiting the candidates by descending upper bound
    and stopping once no bound exceeds the best found; a deferred gap is taken as the
    loop would have taken it (the same operands from ch), so every value is exact."""
    best = 0.0
    found = False
    if m == 0:
        return best
    for j in np.argsort(-cand_f[_CF_UB, :m]):
        if found and cand_f[_CF_UB, j] <= best:
            break
        k = cand_k[j]
        ex, ey = ch[CH_EX, k], ch[CH_EY, k]
        v_close = cand_f[_CF_VC, j]
        g = cand_f[_CF_G, j]
        if math.isnan(g):
            ox, oy = ch[CH_RX, k], ch[CH_RY, k]
            ok = np.isfinite(ox) and np.isfinite(oy)
            bx, by = (ox, oy) if ok else (1e9, 1e9)
            g = box_gap_cs(
                ex, ey, cand_f[_CF_CE, j], cand_f[_CF_SE, j], Le, We, bx, by,
                cand_f[_CF_CO, j], cand_f[_CF_SO, j], Lr, Wr,
            )  # fmt: skip
        gd = nan_to_num(g)
        if not (gd > 0.0 and gd / v_close >= react):
            continue
        val = v_close * v_close / (2.0 * gd)
        if found and not val > best:
            continue
        if on_course(
            ex, ey, ch[CH_EYAW, k], Le, We, ch[CH_RX, k], ch[CH_RY, k], cand_f[_CF_YAW, j],
            Lr, Wr, cand_f[_CF_RV0, j], cand_f[_CF_RV1, j], A, Bc,
        ):  # fmt: skip
            best = val
            found = True
    return best


@numba.njit(cache=True, error_model="numpy")
def _severity(ch, hit, first, Le, We, cfg, mass_kg, out):  # type: ignore[no-untyped-def]
    """Impact speed, delta-v, side, striking and injury risk (vei.metrics.severity)."""
    k = first if hit else 0
    pre = max(k - 1, 0)
    act_pre = ch[CH_RACT, pre] != 0.0
    ryaw, rsp = ch[CH_RYAW, pre], ch[CH_RSP, pre]
    oyaw = ryaw if np.isfinite(ryaw) else 0.0
    osp = rsp if np.isfinite(rsp) else 0.0
    ovx, ovy = osp * np.cos(oyaw), osp * np.sin(oyaw)
    pv, pyaw = ch[CH_EV, pre], ch[CH_EYAW, pre]
    evx, evy = pv * np.cos(pyaw), pv * np.sin(pyaw)
    approach = (
        hit and k > 0 and act_pre and np.isfinite(ovx) and np.isfinite(ovy)
        and np.isfinite(evx) and np.isfinite(evy)
    )  # fmt: skip
    ovx, ovy = nan_to_num(ovx), nan_to_num(ovy)
    vr0, vr1 = np.nan, np.nan
    if approach:
        vr0, vr1 = evx - ovx, evy - ovy
    speed = np.sqrt(vr0 * vr0 + vr1 * vr1)
    m_r = cfg[C_RIDER] if not math.isnan(cfg[C_RIDER]) else mass_kg
    car_m = cfg[C_CAR]
    total = car_m + m_r
    out[M_IMPACT] = speed
    out[M_DVR] = car_m / total * speed
    out[M_DVC] = m_r / total * speed
    # M_INJ (the injury risk, exp of the impact speed) is taken after the pass with NumPy's
    # exp, as summarize takes it (fused_layout.metrics_frame): NumPy's SIMD exp and the C
    # library's, which compiled code calls, differ in the last bit on AVX-512 machines.
    out[M_INJ] = np.nan
    # the hit face, from the rider's centre in the ego frame at contact
    act_k = ch[CH_RACT, k] != 0.0
    dx = (ch[CH_RX, k] if act_k else np.nan) - ch[CH_EX, k]
    dy = (ch[CH_RY, k] if act_k else np.nan) - ch[CH_EY, k]
    c, s = np.cos(ch[CH_EYAW, k]), np.sin(ch[CH_EYAW, k])
    rel0 = c * dx + s * dy
    rel1 = -s * dx + c * dy
    hl, hw = 0.5 * Le, 0.5 * We
    vx = c * vr0 + s * vr1
    vy = -s * vr0 + c * vr1
    face = -1
    best = -np.inf
    for f in range(4):
        if f == 0:
            beyond, ap = rel0 > hl, vx
        elif f == 1:
            beyond, ap = rel0 < -hl, -vx
        elif f == 2:
            beyond, ap = rel1 > hw, vy
        else:
            beyond, ap = rel1 < -hw, -vy
        score = ap if (beyond and np.isfinite(ap)) else -np.inf
        if face < 0 or score > best:
            face, best = f, score
    if not np.isfinite(best):
        if np.abs(rel0) / hl >= np.abs(rel1) / hw:
            face = 0 if rel0 >= 0.0 else 1
        else:
            face = 2 if rel1 > 0.0 else 3
    if face == 0:
        n0, n1 = c, s
    elif face == 1:
        n0, n1 = -c, -s
    elif face == 2:
        n0, n1 = -s, c
    else:
        n0, n1 = s, -c  # -left = (-(-s), -c), negation is exact
    out[M_SIDE] = float(face) if hit else -1.0
    car = evx * n0 + evy * n1
    rider = -(ovx * n0 + ovy * n1)
    if not approach or math.isnan(car):
        out[M_STRIKE] = -1.0
    else:
        out[M_STRIKE] = 0.0 if car >= rider else (2.0 if pv < STANDING else 1.0)


@numba.njit(cache=True, error_model="numpy", parallel=True)
def rows_metrics(t, dt, ch, Le, We, Lr, Wr, cfg, mass_kg, brake_mps2, out):  # type: ignore[no-untyped-def]
    """:func:`run_metrics` of B runs: ch [B, N_CH, T], mass_kg / brake_mps2 [B],
    out [B, N_FUSED]."""
    for b in numba.prange(ch.shape[0]):
        run_metrics(t, dt, ch[b], Le, We, Lr, Wr, cfg, mass_kg[b], brake_mps2[b], out[b])


def trace_channels(a: TraceArrays) -> npt.NDArray[np.float64]:
    """[B, N_CH, T] the channels of a trace's runs (C-contiguous float64)."""
    b, n = a.ego_speed.shape
    ch = np.empty((b, N_CH, n))
    ch[:, CH_EX], ch[:, CH_EY] = a.ego_xy[..., 0], a.ego_xy[..., 1]
    ch[:, CH_EYAW], ch[:, CH_EV], ch[:, CH_EA] = a.ego_yaw, a.ego_speed, a.ego_accel
    ch[:, CH_RX], ch[:, CH_RY] = a.other_xy[..., 0], a.other_xy[..., 1]
    ch[:, CH_RYAW] = np.asarray(a.trace.other_yaw_rad, dtype=np.float64)
    ch[:, CH_RSP] = np.asarray(a.trace.other_speed_mps, dtype=np.float64)
    ch[:, CH_RACT], ch[:, CH_RCOL] = a.active, a.collided
    return ch


def fused_summary(
    trace: Trace | TraceArrays,
    cfg: MetricsConfig | None = None,
    *,
    names: Sequence[str] | None = None,
    params: Mapping[str, npt.ArrayLike] | None = None,
) -> pd.DataFrame:
    """The compiled metrics of every run of a recorded trace.

    Equals ``summarize(as_timeseries_trace(trace), cfg, names=names, params=params)`` bit
    for bit (for a trace read from a time series, as_timeseries_trace changes nothing).

    Args:
        trace: B runs. cfg: thresholds (paper defaults when None).
        names: metrics of :data:`FUSED_METRICS` (default: all of them, in that order).
        params: per-run rider mass / full brake as for :func:`vei.metrics.summarize`.
    Returns:
        DataFrame of B rows, one column per name (dtypes as summarize's).
    """
    names = FUSED_METRICS if names is None else tuple(names)
    check_names(names)
    cfg = MetricsConfig() if cfg is None else cfg
    a = arrays(trace, params)
    ch = trace_channels(a)
    b = ch.shape[0]
    mass = np.ascontiguousarray(param_of(a, "rider_mass_kg", None), dtype=np.float64)
    brake = np.ascontiguousarray(param_of(a, "ego_max_decel_mps2", None), dtype=np.float64)
    out = np.empty((b, N_FUSED))
    tr = a.trace
    rows_metrics(
        np.ascontiguousarray(a.t_s), float(a.dt_s), ch,
        float(tr.ego_length_m), float(tr.ego_width_m),
        float(tr.other_length_m), float(tr.other_width_m),
        config_vector(cfg), mass, brake, out,
    )  # fmt: skip
    return metrics_frame(out, names, cfg)
