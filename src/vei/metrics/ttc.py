"""Time-to-collision metrics: the paper's TTC, its zones and safety index, and a TTC
with relative velocity.

Paper (Section III-E): TTC := D_v2esc / v_veh, relative velocity neglected. Our D is the
*box gap*: the shortest distance between the ego's and the road user's footprints
(oriented boxes), so TTC reaches 0 exactly at contact; centre distance would leave
~0.5-1 s of "TTC" at the moment of impact. Steps are zoned safe (TTC > 2 s), attention
(1 s < TTC <= 2 s), alert (TTC <= 1 s) and collision (from the collision flag, which is
latched: after a crash every later step is in the collision zone). The safety index is
(T_safe + T_attention) / T_all over the interaction span (the steps where the other road
user is active), forced to 0 when a collision occurs; NaN when the span is empty.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.metrics._trace import TraceArrays, arrays
from vei.metrics.config import MetricsConfig
from vei.metrics.geometry import time_to_contact
from vei.types import Trace

FloatArray = npt.NDArray[np.float64]

#: Zone codes of :func:`ttc_zones` (int8).
ZONE_INACTIVE = -1
ZONE_SAFE = 0
ZONE_ATTENTION = 1
ZONE_ALERT = 2
ZONE_COLLISION = 3
#: Zone code -> name.
ZONE_NAMES: dict[int, str] = {
    ZONE_INACTIVE: "inactive",
    ZONE_SAFE: "safe",
    ZONE_ATTENTION: "attention",
    ZONE_ALERT: "alert",
    ZONE_COLLISION: "collision",
}


def _cfg(cfg: MetricsConfig | None) -> MetricsConfig:
    return MetricsConfig() if cfg is None else cfg


def paper_ttc(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """The paper's TTC = gap / v_ego per step.

    Returns:
        [B, T] seconds: NaN where the other road user is inactive; 0 at collided steps;
        inf where the ego stands (speed <= cfg.min_speed_mps) or, with
        ``cfg.ttc_scope == 'ahead'``, where the other is not ahead of the ego.
    """
    cfg = _cfg(cfg)
    a = arrays(trace)
    key = ("paper_ttc", cfg)
    if key in a.memo:
        return a.memo[key].copy()
    v = a.ego_speed
    moving = v > cfg.min_speed_mps
    with np.errstate(divide="ignore", invalid="ignore"):
        ttc = np.where(moving, a.gap / np.where(moving, v, 1.0), np.inf)
    if cfg.ttc_scope == "ahead":
        ttc = np.where(a.ahead, ttc, np.inf)
    ttc = np.where(a.collided, 0.0, ttc)
    out = np.where(a.active, ttc, np.nan)
    a.memo[key] = out
    return out.copy()


def ttc_zones(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> npt.NDArray[np.int8]:
    """Zone of every step from the paper's TTC.

    Returns:
        [B, T] int8 codes: ZONE_SAFE (TTC > safe_ttc_s), ZONE_ATTENTION (alert_ttc_s < TTC
        <= safe_ttc_s), ZONE_ALERT (TTC <= alert_ttc_s), ZONE_COLLISION (collided at or
        before this step), ZONE_INACTIVE (other road user absent).
    """
    cfg = _cfg(cfg)
    a = arrays(trace)
    key = ("ttc_zones", cfg)
    if key in a.memo:
        return a.memo[key].copy()
    ttc = paper_ttc(a, cfg)
    zones = np.full(ttc.shape, ZONE_ALERT, dtype=np.int8)
    with np.errstate(invalid="ignore"):
        zones[ttc > cfg.alert_ttc_s] = ZONE_ATTENTION
        zones[ttc > cfg.safe_ttc_s] = ZONE_SAFE
    zones[a.collided] = ZONE_COLLISION
    zones[~a.active] = ZONE_INACTIVE
    a.memo[key] = zones
    return zones.copy()


def zone_durations(
    trace: Trace | TraceArrays, cfg: MetricsConfig | None = None
) -> dict[str, FloatArray]:
    """Time spent in each zone over the interaction span.

    Returns:
        {'safe', 'attention', 'alert', 'collision', 'all'} -> [B] seconds (step count x dt).
    """
    a = arrays(trace)
    zones = ttc_zones(a, cfg)
    dt = a.dt_s
    out = {
        ZONE_NAMES[z]: (zones == z).sum(axis=1) * dt
        for z in (ZONE_SAFE, ZONE_ATTENTION, ZONE_ALERT, ZONE_COLLISION)
    }
    out["all"] = (zones != ZONE_INACTIVE).sum(axis=1) * dt
    return out


def safety_index(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """The paper's safety index (T_safe + T_attention) / T_all, 0 on any collision.

    Returns:
        [B] in [0, 1]; NaN where the other road user is never active.
    """
    a = arrays(trace)
    zones = ttc_zones(a, cfg)
    n_all = (zones != ZONE_INACTIVE).sum(axis=1)
    n_ok = ((zones == ZONE_SAFE) | (zones == ZONE_ATTENTION)).sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        index = np.where(n_all > 0, n_ok / np.maximum(n_all, 1), np.nan)
    return np.where(a.collided.any(axis=1), 0.0, index)


def relative_ttc(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """TTC with relative velocity: time until the two boxes touch if both keep their current
    velocity vectors and headings (exact for translating boxes, see geometry.time_to_contact).

    Returns:
        [B, T] seconds: NaN where inactive, 0 at collided or overlapping steps, inf where
        the boxes never meet on their current courses.
    """
    a = arrays(trace)
    if "relative_ttc" in a.memo:  # (one series, whatever the thresholds)
        return a.memo["relative_ttc"].copy()
    ttc = time_to_contact(a.ego_corners, a.other_corners, a.other_vel - a.ego_vel)
    ttc = np.where(a.collided, 0.0, ttc)
    out = np.where(a.active, ttc, np.nan)
    a.memo["relative_ttc"] = out
    return out.copy()
