"""Conflict measures: minimum gap, post-encroachment time (PET) and deceleration rate to
avoid a crash (DRAC).

- Gap: the box-to-box distance of the two footprints (m), per step.
- PET: the paths' conflict point is the first crossing of the two centre paths (the ego
  over the whole run, the other road user over its active span, earliest along the
  other's path). Each agent occupies the point while its centre is within half its
  length of it along its own path; PET = (time the second arrives) - (time the first
  leaves), 0 if the occupancies overlap or the run collides, NaN if the paths never cross.
- DRAC (deceleration rate to avoid a crash): v_close^2 / (2 gap), with v_close = v_ego -
  (v_other . ego heading), the closing speed along the ego's heading. It is the constant
  deceleration that brings the closing speed to 0 within the gap, so it is defined only
  where that question has an answer: the other is active, ahead of the ego, the boxes
  are apart (gap > 0), the ego is closing (v_close > 0), the boxes would meet if both kept
  their velocities (finite TTC with relative velocity: a rider passing close *beside* the
  car, not on a collision course, needs no braking -> 0), and the step lies strictly
  before the first contact. Everywhere else in the interaction span it is 0 (nothing to
  avoid) before contact and NaN from the contact step on (the crash was not avoided; a
  deceleration to avoid it no longer exists), NaN where inactive.
  The car cannot brake harder than its full brake: the ceiling is ``MetricsConfig.
  drac_ceiling_mps2`` when set, else the run's ``ego.max_decel_mps2`` (8.0 m/s^2 by
  default). Values above it are reported capped at it (capping instead of NaN keeps
  the run in means and maps). The maximum (``max_drac_mps2``) and the flag
  ``drac_unavoidable`` are taken only over steps whose time to contact gap / v_close is
  at least ``MetricsConfig.reaction_time_s`` (0.5 s): on the step before an impact the
  gap is below v dt, so DRAC > v_close / (2 dt) = 10 v_close at 20 Hz for *every*
  collision. With the reaction time, "unavoidable" means: at a moment when an automatic
  brake still had time to act, braking at the car's full brake from then on could not
  have avoided contact (both keeping their velocities). A conflict that arises less than
  the reaction time before contact has no such step: max 0, flag False (the collision
  columns show it).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.metrics._trace import TraceArrays, arrays, param_of
from vei.metrics.config import MetricsConfig
from vei.types import Trace

FloatArray = npt.NDArray[np.float64]


def gap_series(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B, T] box-to-box gap (m), 0 where the boxes touch or overlap, NaN where inactive."""
    return arrays(trace).gap.copy()


def min_gap(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] smallest box-to-box gap over the interaction span (m); NaN if never active."""
    g = arrays(trace).gap
    out = np.full(g.shape[0], np.nan)
    has = np.isfinite(g).any(axis=1)
    out[has] = np.nanmin(g[has], axis=1)
    return out


def _drac_candidates(
    a: TraceArrays,
) -> tuple[np.ndarray, FloatArray, FloatArray, FloatArray]:
    """([B, T] candidate steps: present, ahead, apart and closing, before contact;
    [B, T] uncapped v_close^2 / (2 gap) there (-inf elsewhere); [B, T, 2] rider velocity;
    [B, T] time to contact gap / v_close there (s; inf elsewhere))."""
    if "drac_candidates" in a.memo:
        return a.memo["drac_candidates"]
    heading = np.stack([np.cos(a.ego_yaw), np.sin(a.ego_yaw)], axis=-1)
    other_vel = np.nan_to_num(a.other_vel)
    v_close = a.ego_speed - np.sum(other_vel * heading, axis=-1)
    gap = np.nan_to_num(a.gap, nan=0.0)
    candidate = a.ahead & (v_close > 0.0) & (gap > 0.0) & ~a.collided
    with np.errstate(divide="ignore", invalid="ignore"):
        safe_gap = np.where(candidate, gap, 1.0)
        raw = np.where(candidate, v_close**2 / (2.0 * safe_gap), -np.inf)
        ttc = np.where(candidate, safe_gap / np.where(candidate, v_close, 1.0), np.inf)
    a.memo["drac_candidates"] = (candidate, raw, other_vel, ttc)
    return candidate, raw, other_vel, ttc


def _on_course(a: TraceArrays, b: np.ndarray, t: np.ndarray, other_vel: FloatArray) -> np.ndarray:
    """[K] the boxes of runs b at steps t would meet if both kept their velocities."""
    from vei.metrics.geometry import box_corners, time_to_contact

    # Corners of the K tested steps only, always computed the same way (whatever else a
    # summary computed before), so the answer depends on the inputs alone.
    tr = a.trace
    ego_c = box_corners(a.ego_xy[b, t], a.ego_yaw[b, t], tr.ego_length_m, tr.ego_width_m)
    yaw = np.nan_to_num(a.other_yaw[b, t])
    oth_c = box_corners(a.other_xy[b, t], yaw, tr.other_length_m, tr.other_width_m)
    ttc = time_to_contact(ego_c, oth_c, other_vel[b, t] - a.ego_vel[b, t])
    return np.isfinite(ttc)


def _drac_raw(a: TraceArrays) -> FloatArray:
    """[B, T] uncapped DRAC (m/s^2): see the module docstring; NaN inactive or from contact."""
    if "drac_raw" in a.memo:
        return a.memo["drac_raw"]
    candidate, raw, other_vel, _ = _drac_candidates(a)
    on_course = np.zeros_like(candidate)
    if candidate.any():
        b, t = np.nonzero(candidate)
        on_course[b, t] = _on_course(a, b, t, other_vel)
    drac = np.where(on_course, raw, 0.0)
    out = np.where(a.active & ~a.collided, drac, np.nan)
    a.memo["drac_raw"] = out
    return out


def _max_drac_raw(a: TraceArrays, reaction_time_s: float) -> FloatArray:
    """[B] max of :func:`_drac_raw` over the steps at least ``reaction_time_s`` before
    contact (time to contact gap / v_close >= reaction_time_s; other steps count as 0),
    without evaluating every step's course test: each run's eligible candidates are tested
    in descending order of DRAC (in blocks of 1, 2, 4, ...) until one is on course. NaN
    where the road user is never present before contact."""
    key = ("max_drac_raw", float(reaction_time_s))
    if key in a.memo:
        return a.memo[key]
    candidate, raw, other_vel, ttc = _drac_candidates(a)
    eligible = candidate & (ttc >= reaction_time_s)  # ttc is finite on candidates
    present = (a.active & ~a.collided).any(axis=1)
    if "drac_raw" in a.memo:  # the full series is there anyway
        d = np.where(eligible, a.memo["drac_raw"], 0.0)
        out = np.where(present, np.max(d, axis=1, initial=0.0), np.nan)
        a.memo[key] = out
        return out
    candidate = candidate & eligible
    raw = np.where(candidate, raw, -np.inf)
    n_b = raw.shape[0]
    n_cand = candidate.sum(axis=1)
    order = np.argsort(-raw, axis=1, kind="stable")  # candidates first, largest DRAC first
    best = np.zeros(n_b)
    todo = np.flatnonzero(n_cand > 0)
    start, width = 0, 1
    while todo.size:
        cols = start + np.arange(width)
        bb = np.repeat(todo, width)
        jj = np.tile(cols, todo.size)
        valid = jj < n_cand[bb]
        bb, jj = bb[valid], jj[valid]
        tt = order[bb, jj]
        ok = _on_course(a, bb, tt, other_vel)
        found = np.zeros(n_b, dtype=bool)
        # the first on-course candidate of each run in this block (the largest DRAC)
        first_j = np.full(n_b, np.iinfo(np.int64).max)
        np.minimum.at(first_j, bb[ok], jj[ok])
        found[todo] = first_j[todo] < np.iinfo(np.int64).max
        hit = np.flatnonzero(found)
        best[hit] = raw[hit, order[hit, first_j[hit]]]
        start += width
        width *= 2
        todo = todo[~found[todo] & (n_cand[todo] > start)]
    out = np.where(present, best, np.nan)
    a.memo[key] = out
    return out


def drac_ceiling(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] the DRAC ceiling of each run (m/s^2): cfg.drac_ceiling_mps2 when set, else the
    run's ``ego.max_decel_mps2`` (trace params; default 8.0 m/s^2)."""
    cfg = MetricsConfig() if cfg is None else cfg
    return param_of(arrays(trace), "ego_max_decel_mps2", cfg.drac_ceiling_mps2)


def drac_series(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B, T] deceleration rate to avoid a crash (m/s^2), in [0, ceiling] (values above
    the run's :func:`drac_ceiling` are capped at it); NaN inactive or from first contact
    on. Every step before contact, also those closer than cfg.reaction_time_s."""
    a = arrays(trace)
    return np.minimum(_drac_raw(a), drac_ceiling(a, cfg)[:, None])


def max_drac(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] largest DRAC over the steps at least cfg.reaction_time_s before contact (time
    to contact gap / v_close; m/s^2), capped at the run's :func:`drac_ceiling`; 0 when no
    such step is on a collision course (e.g. a rider appearing less than the reaction
    time before contact), NaN if the road user is never active before contact."""
    cfg = MetricsConfig() if cfg is None else cfg
    a = arrays(trace)
    return np.minimum(_max_drac_raw(a, cfg.reaction_time_s), drac_ceiling(a, cfg))


def drac_unavoidable(
    trace: Trace | TraceArrays, cfg: MetricsConfig | None = None
) -> npt.NDArray[np.bool_]:
    """[B] at some step at least cfg.reaction_time_s before contact, the DRAC exceeded the
    run's :func:`drac_ceiling` (the car's full brake): had both kept their velocities,
    braking at the full brake from that step on could not have avoided contact."""
    cfg = MetricsConfig() if cfg is None else cfg
    a = arrays(trace)
    with np.errstate(invalid="ignore"):
        return _max_drac_raw(a, cfg.reaction_time_s) > drac_ceiling(a, cfg)


def _first_crossing(p: FloatArray, q: FloatArray) -> tuple[int, float, int, float] | None:
    """First crossing of polylines p [N, 2] and q [M, 2], earliest along q.

    Returns (i, u, j, w): p's segment i at fraction u, q's segment j at fraction w.
    """
    if len(p) < 2 or len(q) < 2:
        return None
    a, da = p[:-1, None, :], (p[1:] - p[:-1])[:, None, :]
    b, db = q[None, :-1, :], (q[1:] - q[:-1])[None, :, :]
    denom = da[..., 0] * db[..., 1] - da[..., 1] * db[..., 0]
    ab = b - a
    with np.errstate(divide="ignore", invalid="ignore"):
        u = (ab[..., 0] * db[..., 1] - ab[..., 1] * db[..., 0]) / denom
        w = (ab[..., 0] * da[..., 1] - ab[..., 1] * da[..., 0]) / denom
    ok = (np.abs(denom) > 1e-12) & (u >= 0) & (u <= 1) & (w >= 0) & (w <= 1)
    if not ok.any():
        return None
    ii, jj = np.nonzero(ok)
    key = jj + w[ii, jj]
    k = int(np.argmin(key))
    i, j = int(ii[k]), int(jj[k])
    return i, float(u[i, j]), j, float(w[i, j])


def _occupancy(t: FloatArray, s: FloatArray, s_c: float, half_len: float) -> tuple[float, float]:
    """Time interval in which the arc length s(t) (non-decreasing) lies within s_c +- half_len."""

    def first_reach(target: float) -> float:
        k = int(np.searchsorted(s, target, side="left"))
        if k == 0:
            return float(t[0])
        if k >= len(s):
            return float("inf")
        ds = s[k] - s[k - 1]
        frac = 0.0 if ds <= 0 else (target - s[k - 1]) / ds
        return float(t[k - 1] + frac * (t[k] - t[k - 1]))

    return first_reach(s_c - half_len), first_reach(s_c + half_len + 1e-9)


def pet(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] post-encroachment time at the paths' conflict point (s); see module docstring."""
    a = arrays(trace)
    tr = a.trace
    t = a.t_s
    out = np.full(a.ego_speed.shape[0], np.nan)
    for bi in range(out.size):
        if a.collided[bi].any():
            out[bi] = 0.0
            continue
        act = a.active[bi] & np.isfinite(a.other_xy[bi]).all(axis=-1)
        if act.sum() < 2:
            continue
        pe, po, to = a.ego_xy[bi], a.other_xy[bi][act], t[act]
        hit = _first_crossing(pe, po)
        if hit is None:
            continue
        i, u, j, w = hit
        se = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(pe, axis=0), axis=1))])
        so = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(po, axis=0), axis=1))])
        sce = se[i] + u * (se[i + 1] - se[i])
        sco = so[j] + w * (so[j + 1] - so[j])
        e_in, e_out = _occupancy(t, se, sce, 0.5 * tr.ego_length_m)
        o_in, o_out = _occupancy(to, so, sco, 0.5 * tr.other_length_m)
        if e_in <= o_in:
            out[bi] = max(0.0, o_in - e_out)
        else:
            out[bi] = max(0.0, e_in - o_out)
    return out
