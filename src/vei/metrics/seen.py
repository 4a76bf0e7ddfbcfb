"""Could the car have known? When the other road user was first seen, and the paper's
safety index on the relative-velocity TTC.

*First seen* is the first step at which the other road user is present (active) and,
for a run with a sensor model (per-run parameters ``sensor_*`` from the case's
perception, :func:`vei.metrics.run_params`), visible to it: at least
``sensor_min_visible_fraction`` of its five sample points (centre and corners) within
``sensor_range_m`` of the sensor and within +-``sensor_fov_deg`` / 2 of the ego's heading
(occlusion and detection misses are left out: the question is whether the sensor could
see it). Without a sensor model: the first present step (the road user entered the
scene).

- ``first_seen_gap_m``: the box gap then [m]; ``first_seen_ttc_s``: the relative-velocity
  TTC then (:func:`vei.metrics.ttc.relative_ttc`: inf = not on a collision course) [s];
  both NaN when it is never seen.
- ``seen_too_late``: no planner could have reacted: a collision within the reaction time
  of first seen (``collision_time_s - t_seen <= reaction_time_s``, or a collision with a
  road user never seen), or first seen on a collision course closer than the car's
  stopping distance ``v t_r + v^2 / (2 a)`` (v: the ego's speed then, t_r =
  ``MetricsConfig.reaction_time_s``, a = the run's full brake, as the DRAC's ceiling).
- ``safety_index_rel``: (T_safe + T_attention) / T_all with the zones of the relative
  TTC instead of the paper's gap / v_ego (same thresholds, 0 on any collision, NaN when
  never present). docs/metrics.md shows where the two disagree.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.metrics._trace import TraceArrays, param_of
from vei.metrics.config import MetricsConfig
from vei.metrics.ttc import relative_ttc

FloatArray = npt.NDArray[np.float64]


def _visible(a: TraceArrays) -> npt.NDArray[np.bool_]:
    """[B, T] the other is present and (runs with a sensor) within its range and view."""
    vis = a.active.copy()
    rng = a.params.get("sensor_range_m")
    if rng is None:
        return vis
    fov = a.params["sensor_fov_deg"]
    sel = np.flatnonzero(np.isfinite(rng) | (fov < 360.0))
    if sel.size == 0:
        return vis
    c, s = np.cos(a.ego_yaw[sel]), np.sin(a.ego_yaw[sel])
    mx, my = a.params["sensor_x_m"][sel, None], a.params["sensor_y_m"][sel, None]
    sx = a.ego_xy[sel, :, 0] + c * mx - s * my
    sy = a.ego_xy[sel, :, 1] + s * mx + c * my
    corners = a.other_corners[sel]  # [b, T, 4, 2]
    xy = np.where(np.isfinite(a.other_xy[sel]), a.other_xy[sel], 1e9)
    pts = np.concatenate([xy[:, :, None, :], corners], axis=2)  # [b, T, 5, 2]
    dx, dy = pts[..., 0] - sx[..., None], pts[..., 1] - sy[..., None]
    dist = np.hypot(dx, dy)
    bearing = np.arctan2(dy, dx) - np.arctan2(s, c)[..., None]
    bearing = np.abs(np.pi - np.mod(np.pi - bearing, 2.0 * np.pi))
    half = np.radians(a.params["sensor_fov_deg"][sel])[:, None, None] / 2.0
    inside = (dist <= rng[sel, None, None]) & ((bearing <= half) | (half >= np.pi))
    frac = inside.sum(axis=-1) / 5.0
    vis[sel] &= frac >= a.params["sensor_min_visible_fraction"][sel, None] - 1e-12
    return vis


def first_seen_index(a: TraceArrays, cfg: MetricsConfig) -> npt.NDArray[np.intp]:
    """[B] step index of first seen (-1: never seen)."""
    key = "first_seen_index"
    if key not in a.memo:
        vis = _visible(a)
        a.memo[key] = np.where(vis.any(axis=1), np.argmax(vis, axis=1), -1)
    return a.memo[key]


def _at_first_seen(a: TraceArrays, cfg: MetricsConfig, series: FloatArray) -> FloatArray:
    k = first_seen_index(a, cfg)
    b = np.arange(k.size)
    return np.where(k >= 0, series[b, np.maximum(k, 0)], np.nan)


def first_seen_gap(a: TraceArrays, cfg: MetricsConfig) -> FloatArray:
    """[B] box gap at first seen [m] (NaN: never seen)."""
    return _at_first_seen(a, cfg, a.gap)


def first_seen_ttc(a: TraceArrays, cfg: MetricsConfig) -> FloatArray:
    """[B] relative-velocity TTC at first seen [s] (inf: not on a collision course then;
    NaN: never seen)."""
    return _at_first_seen(a, cfg, relative_ttc(a, cfg))


def seen_too_late(a: TraceArrays, cfg: MetricsConfig) -> npt.NDArray[np.bool_]:
    """[B] no planner could have reacted (see the module docstring)."""
    k = first_seen_index(a, cfg)
    seen = k >= 0
    b = np.arange(k.size)
    kk = np.maximum(k, 0)
    hit = a.collided.any(axis=1)
    t_hit = a.t_s[np.argmax(a.collided, axis=1)]
    react = float(cfg.reaction_time_s)
    late_hit = hit & (~seen | (t_hit - a.t_s[kk] <= react + 1e-9))
    v = a.ego_speed[b, kk]
    brake = param_of(a, "ego_max_decel_mps2", cfg.drac_ceiling_mps2)
    stop = v * react + v * v / (2.0 * brake)
    gap = a.gap[b, kk]
    ttc = relative_ttc(a, cfg)[b, kk]
    close = seen & np.isfinite(ttc) & (gap < stop)
    return late_hit | close


def safety_index_rel(a: TraceArrays, cfg: MetricsConfig) -> FloatArray:
    """[B] the paper's safety index with the relative-velocity TTC's zones, in [0, 1]; 0
    on any collision; NaN where the other road user is never present."""
    ttc = relative_ttc(a, cfg)
    act = a.active
    coll = a.collided
    with np.errstate(invalid="ignore"):
        ok = act & ~coll & (ttc > cfg.alert_ttc_s)
    n_all = act.sum(axis=1)
    n_ok = ok.sum(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        index = np.where(n_all > 0, n_ok / np.maximum(n_all, 1), np.nan)
    return np.where(coll.any(axis=1), 0.0, index)


#: The flag's column in summaries, sweep results and catalogues.
FLAG_COLUMN = "seen_too_late"


def flagged_mask(table: object) -> npt.NDArray[np.bool_]:
    """[N] the rows of a results table (DataFrame) flagged ``seen_too_late`` (all False
    when the table has no such column, e.g. one written before the flag existed)."""
    import pandas as pd

    assert isinstance(table, pd.DataFrame)
    if FLAG_COLUMN not in table.columns:
        return np.zeros(len(table), dtype=bool)
    return table[FLAG_COLUMN].fillna(False).to_numpy(dtype=bool)


def flag_counts(table: object) -> dict[str, float | int]:
    """How many runs of a results table are flagged ``seen_too_late``, counted apart:
    {'runs', 'flagged', 'flagged_share', 'collisions', 'collisions_flagged',
    'collisions_unflagged', 'collisions_without_approach', 'collisions_without_approach_unflagged'}
    (a collision without approach: impact speed NaN, the rider appeared in contact)."""
    import pandas as pd

    assert isinstance(table, pd.DataFrame)
    flag = flagged_mask(table)
    n = len(table)
    hit = (
        table["collision"].fillna(False).to_numpy(dtype=bool)
        if "collision" in table
        else np.zeros(n, dtype=bool)
    )
    no_app = (
        hit & ~np.isfinite(table["impact_speed_mps"].to_numpy(dtype=np.float64))
        if "impact_speed_mps" in table
        else np.zeros(n, dtype=bool)
    )
    return {
        "runs": int(n),
        "flagged": int(flag.sum()),
        "flagged_share": float(flag.mean()) if n else float("nan"),
        "collisions": int(hit.sum()),
        "collisions_flagged": int((hit & flag).sum()),
        "collisions_unflagged": int((hit & ~flag).sum()),
        "collisions_without_approach": int(no_app.sum()),
        "collisions_without_approach_unflagged": int((no_app & ~flag).sum()),
    }
