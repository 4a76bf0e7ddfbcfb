"""Shared helpers of the policy tests: synthetic observations."""

from __future__ import annotations

import numpy as np

from vei.policy.observation import Observation


def make_obs(
    v_mps: np.ndarray,
    *,
    gap_m: np.ndarray | None = None,
    rel_vx_mps: np.ndarray | None = None,
    cruise_mps: float = 10.0,
    dt_s: float = 0.05,
    t_s: float = 0.0,
) -> Observation:
    """An Observation of B variants with one object (index 0) on the ego path.

    gap_m: [B] path gap (+inf = not in the corridor; None = no object at all).
    rel_vx_mps: [B] relative longitudinal velocity (default: a standing object, -v).
    """
    v = np.asarray(v_mps, dtype=np.float64)
    b = v.shape[0]
    valid = np.zeros((b, 1), dtype=bool) if gap_m is None else np.ones((b, 1), dtype=bool)
    gap = np.full((b, 1), np.inf) if gap_m is None else np.asarray(gap_m, dtype=np.float64)[:, None]
    rvx = (-v if rel_vx_mps is None else np.asarray(rel_vx_mps, dtype=np.float64))[:, None]
    z = np.zeros((b, 1))
    return Observation(
        t_s=np.full(b, t_s), dt_s=dt_s, ego_speed_mps=v, ego_accel_mps2=np.zeros(b),
        ego_s_m=np.zeros(b), path_length_m=np.full(b, 500.0),
        cruise_speed_mps=np.full(b, cruise_mps), max_accel_mps2=np.full(b, 3.0),
        max_decel_mps2=np.full(b, 8.0), ego_length_m=4.7, ego_width_m=1.85,
        collided=np.zeros(b, dtype=bool), valid=valid,
        rel_x_m=np.where(valid, gap + 2.35, 0.0), rel_y_m=z, rel_yaw_rad=z,
        rel_vx_mps=np.where(valid, rvx, 0.0), rel_vy_mps=z,
        length_m=np.full((b, 1), 1.2), width_m=np.full((b, 1), 0.6), age_s=np.where(valid, 0.0, np.inf),
        category=np.zeros((b, 1), dtype=np.int8), path_gap_m=np.where(valid, gap, np.inf),
        path_lateral_m=np.where(valid, 0.0, np.inf),
    )  # fmt: skip
