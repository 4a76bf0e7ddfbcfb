"""Sparse world-frame keyframes per tracked road user (paper Section III-B, step 6).

Each annotated track becomes one agent ``'<category>_<track_id>'`` whose keyframes are its
annotations laid out in the world plane. The keyframe yaw is the annotation's own yaw
(relative yaw + ego yaw) where given, else the direction of motion: the direction from the
previous to the next keyframe (one-sided at the ends); where the rider moved less than
``min_move_m`` over that span the direction is meaningless (jitter) and the yaw of the
nearest keyframe with a valid direction is used; a track that never moves gets yaw 0.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt
import pandas as pd

FloatArray = npt.NDArray[np.float64]

#: Columns of the keyframes table.
KEYFRAME_COLUMNS: tuple[str, ...] = (
    "t_s",
    "agent_id",
    "source_track_id",
    "category",
    "x_m",
    "y_m",
    "yaw_rad",
    "yaw_source",
)


def agent_id_for(category: str, track_id: str) -> str:
    """Scenario agent id of an annotated track: '<category>_<track_id>'."""
    return f"{category}_{track_id}"


def motion_yaw(xy_m: npt.ArrayLike, min_move_m: float = 0.5) -> FloatArray:
    """Direction of motion at each keyframe.

    Args:
        xy_m: [K, 2] keyframe positions [m] in time order.
        min_move_m: displacements shorter than this [m] give no direction.
    Returns:
        [K] yaw [rad] (CCW from +x); nearest valid value where the rider barely moved, 0
        if it never moved.
    """
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    k = xy.shape[0]
    if k < 2:
        return np.zeros(k)
    nxt = np.vstack([xy[1:], xy[-1:]])
    prv = np.vstack([xy[:1], xy[:-1]])
    d = nxt - prv
    ok = np.hypot(d[:, 0], d[:, 1]) >= min_move_m
    if not ok.any():
        return np.zeros(k)
    yaw = np.arctan2(d[:, 1], d[:, 0])
    good = np.flatnonzero(ok)
    idx = np.arange(k)
    pos = np.clip(np.searchsorted(good, idx), 0, good.size - 1)
    left = good[np.clip(pos - 1, 0, good.size - 1)]
    right = good[pos]
    nearest = np.where(np.abs(idx - left) <= np.abs(right - idx), left, right)
    return yaw[nearest]


def build_keyframes(world: pd.DataFrame, min_move_m: float = 0.5) -> pd.DataFrame:
    """Keyframes of every track.

    Args:
        world: output of :func:`vei.recon.world.annotations_to_world` (t_s, track_id,
            category, x_m, y_m, yaw_rad with NaN where the annotation has no yaw).
        min_move_m: see :func:`motion_yaw`.
    Returns:
        DataFrame with KEYFRAME_COLUMNS, sorted by (agent_id, t_s); yaw_source is
        'annotation' or 'motion'. A track whose category changes keeps its majority
        category (ties: the first seen).
    """
    parts = []
    for track_id, grp in world.groupby("track_id", sort=True):
        grp = grp.sort_values("t_s")
        cats = grp["category"].value_counts(sort=False)
        category = str(cats.idxmax())
        xy = grp[["x_m", "y_m"]].to_numpy(dtype=np.float64)
        given = grp["yaw_rad"].to_numpy(dtype=np.float64)
        has = np.isfinite(given)
        yaw = np.where(has, given, motion_yaw(xy, min_move_m) if not has.all() else given)
        parts.append(
            pd.DataFrame(
                {
                    "t_s": grp["t_s"].to_numpy(dtype=np.float64),
                    "agent_id": agent_id_for(category, str(track_id)),
                    "source_track_id": str(track_id),
                    "category": category,
                    "x_m": xy[:, 0],
                    "y_m": xy[:, 1],
                    "yaw_rad": yaw,
                    "yaw_source": np.where(has, "annotation", "motion"),
                }
            )
        )
    if not parts:
        return pd.DataFrame({c: pd.Series(dtype=_dtype(c)) for c in KEYFRAME_COLUMNS})
    out = pd.concat(parts, ignore_index=True)
    return out.sort_values(["agent_id", "t_s"], kind="stable").reset_index(drop=True)[
        list(KEYFRAME_COLUMNS)
    ]


def _dtype(col: str) -> str:
    return "float64" if col in ("t_s", "x_m", "y_m", "yaw_rad") else "object"
