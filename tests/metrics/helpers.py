"""Build small constructed traces for the metric tests."""

from __future__ import annotations

import numpy as np

from vei.types import Trace


def make_trace(
    *,
    ego_xy,
    other_xy,
    ego_speed,
    dt: float = 0.1,
    ego_yaw=0.0,
    ego_accel=0.0,
    other_yaw=0.0,
    other_vel=(0.0, 0.0),
    active=True,
    collided=False,
    ego_dims=(4.0, 2.0),
    other_dims=(1.0, 1.0),
) -> Trace:
    """One run (B = 1) of T steps; scalars broadcast over time."""
    ego_xy = np.asarray(ego_xy, dtype=float).reshape(-1, 2)
    other_xy = np.asarray(other_xy, dtype=float).reshape(-1, 2)
    n = max(
        len(ego_xy),
        len(other_xy),
        *(np.size(v) for v in (ego_speed, ego_yaw, ego_accel, other_yaw, active, collided)),
    )

    def series(v):
        return np.broadcast_to(np.asarray(v, dtype=float), (n,)).copy()[None]

    other_vel = np.broadcast_to(np.asarray(other_vel, dtype=float), (n, 2)).copy()[None]
    return Trace(
        t_s=np.arange(n) * dt,
        ego_xy_m=np.broadcast_to(ego_xy, (n, 2)).copy()[None],
        ego_yaw_rad=series(ego_yaw),
        ego_speed_mps=series(ego_speed),
        ego_accel_mps2=series(ego_accel),
        other_xy_m=np.broadcast_to(other_xy, (n, 2)).copy()[None],
        other_yaw_rad=series(other_yaw),
        other_speed_mps=np.linalg.norm(other_vel, axis=-1),
        other_vel_mps=other_vel,
        other_active=np.broadcast_to(np.asarray(active, dtype=bool), (n,)).copy()[None],
        collided=np.broadcast_to(np.asarray(collided, dtype=bool), (n,)).copy()[None],
        ego_length_m=ego_dims[0],
        ego_width_m=ego_dims[1],
        other_length_m=other_dims[0],
        other_width_m=other_dims[1],
    )
