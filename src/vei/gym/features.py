"""The environment's observation vector: its layout, its space, and how it is built from the
policy API's :class:`vei.policy.observation.Observation`.

One float32 vector per environment (``D = N_EGO + 9 K + R`` entries, K = max_objects, R = 1
with road features, else 0), in this order:

ego block (N_EGO = 6):
  0 ``ego_speed_mps`` [m/s], 1 ``ego_accel_mps2`` [m/s^2] (reported), 2 ``cruise_speed_mps``
  [m/s] (the configuration's v_d, a reference), 3 ``path_remaining_m`` [m] (the path's
  recorded end minus the ego's progress), 4 ``time_remaining_s`` [s] (to the end of the
  scenario's span), 5 ``collided`` (0 / 1).
K road-user slots of 9 entries (slot 0 the primary rider, slots 1..K-1 the nearest
perceived other road users by centre distance, ties by index; empty slots all 0 but
``path_gap_m`` = cap):
  ``valid`` (0 / 1), ``rel_x_m``, ``rel_y_m`` [m] (ego frame, x forward, y left; clipped to
  [-cap, cap]), ``rel_vx_mps``, ``rel_vy_mps`` [m/s] (relative velocity in ego axes),
  ``rel_yaw_rad`` [rad] in (-pi, pi], ``path_gap_m`` [m] in [0, cap] (free distance along
  the ego path from its front bumper; cap when not ahead in the path corridor),
  ``path_lateral_m`` [m] in [-cap, cap] (signed offset from the ego path, left +),
  ``category`` (vei.policy.observation.CATEGORY_CODES: 0 e-scooter, 1 cyclist,
  2 pedestrian, 3 vehicle, 5 other).
road block (R = 1, ``EnvConfig.road_features``):
  ``rider_on_road`` (1 when the primary rider's centre lies on a drivable lane of the
  scenario's map, by :class:`vei.gym.world.RoadRaster`; 0 when it is absent).
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

EGO_FEATURES: tuple[str, ...] = (
    "ego_speed_mps", "ego_accel_mps2", "cruise_speed_mps", "path_remaining_m",
    "time_remaining_s", "collided",
)  # fmt: skip
OBJECT_FEATURES: tuple[str, ...] = (
    "valid", "rel_x_m", "rel_y_m", "rel_vx_mps", "rel_vy_mps", "rel_yaw_rad", "path_gap_m",
    "path_lateral_m", "category",
)  # fmt: skip
ROAD_FEATURES: tuple[str, ...] = ("rider_on_road",)
N_EGO = len(EGO_FEATURES)
N_OBJ = len(OBJECT_FEATURES)


def feature_names(max_objects: int, road: bool) -> tuple[str, ...]:
    """The names of the observation's entries, in order (``slot<i>.<feature>`` for objects)."""
    names = list(EGO_FEATURES)
    for i in range(max_objects):
        names += [f"slot{i}.{f}" for f in OBJECT_FEATURES]
    if road:
        names += list(ROAD_FEATURES)
    return tuple(names)


def observation_bounds(
    max_objects: int, road: bool, cap_m: float
) -> tuple[npt.NDArray[np.float32], npt.NDArray[np.float32]]:
    """(low, high) float32 bounds of the observation Box (inf where a value is unbounded)."""
    inf = np.inf
    lo = [0.0, -inf, 0.0, -inf, -inf, 0.0]
    hi = [inf, inf, inf, inf, inf, 1.0]
    slot_lo = [0.0, -cap_m, -cap_m, -inf, -inf, -np.pi, 0.0, -cap_m, 0.0]
    slot_hi = [1.0, cap_m, cap_m, inf, inf, np.pi, cap_m, cap_m, 5.0]
    lo += slot_lo * max_objects
    hi += slot_hi * max_objects
    if road:
        lo += [0.0]
        hi += [1.0]
    return np.array(lo, dtype=np.float32), np.array(hi, dtype=np.float32)


def nearest_slots(
    valid: npt.NDArray[np.bool_],
    rel_x: npt.NDArray[np.float64],
    rel_y: npt.NDArray[np.float64],
    k: int,
) -> npt.NDArray[np.intp]:
    """[B, k] object indices of the slots: 0 (the primary rider), then the k - 1 nearest
    valid objects among 1..N-1 by rel_x^2 + rel_y^2 (ties by index); -1 = empty slot."""
    b, n = valid.shape
    out = np.full((b, k), -1, dtype=np.intp)
    out[:, 0] = 0
    if k == 1 or n == 1:
        return out
    d2 = np.where(valid[:, 1:], rel_x[:, 1:] ** 2 + rel_y[:, 1:] ** 2, np.inf)
    order = np.argsort(d2, axis=1, kind="stable")[:, : k - 1]
    chosen = np.take_along_axis(d2, order, axis=1)
    idx = np.where(np.isfinite(chosen), order + 1, -1)
    out[:, 1 : 1 + idx.shape[1]] = idx
    return out


def vectorize(
    obs: object,
    *,
    max_objects: int,
    cap_m: float,
    time_remaining_s: npt.ArrayLike,
    rider_on_road: npt.ArrayLike | None,
) -> npt.NDArray[np.float32]:
    """The observation vectors [B, D] of a policy-API Observation of B variants.

    Args:
        obs: a vei.policy.observation.Observation. max_objects: K. cap_m: the clip [m].
        time_remaining_s: [B] seconds to the end of the span. rider_on_road: [B] 0 / 1,
            or None without road features.
    """
    o = obs  # Observation (typed loosely: this module imports no engine)
    b = o.batch_size  # type: ignore[attr-defined]
    d = N_EGO + N_OBJ * max_objects + (0 if rider_on_road is None else 1)
    out = np.zeros((b, d), dtype=np.float64)
    out[:, 0] = o.ego_speed_mps  # type: ignore[attr-defined]
    out[:, 1] = o.ego_accel_mps2  # type: ignore[attr-defined]
    out[:, 2] = o.cruise_speed_mps  # type: ignore[attr-defined]
    out[:, 3] = o.path_length_m - o.ego_s_m  # type: ignore[attr-defined]
    out[:, 4] = time_remaining_s
    out[:, 5] = o.collided  # type: ignore[attr-defined]
    slots = nearest_slots(o.valid, o.rel_x_m, o.rel_y_m, max_objects)  # type: ignore[attr-defined]
    rows = np.arange(b)
    n = np.shape(o.valid)[1]  # type: ignore[attr-defined]
    valid = np.asarray(o.valid)  # type: ignore[attr-defined]
    clipped = (o.rel_x_m, o.rel_y_m)  # type: ignore[attr-defined]
    plain = (o.rel_vx_mps, o.rel_vy_mps, o.rel_yaw_rad)  # type: ignore[attr-defined]
    for s in range(max_objects):
        base = N_EGO + N_OBJ * s
        out[:, base + 6] = cap_m  # empty slot: all 0 but path_gap_m = cap
        j = slots[:, s]
        has = j >= 0
        if not has.any():
            continue
        flat = rows * n + np.where(has, j, 0)  # [B] index into the [B, N] arrays, flattened
        vi = np.flatnonzero(has & np.take(valid, flat))
        if vi.size == 0:
            continue
        fi = flat[vi]
        out[vi, base] = 1.0
        for f, a in enumerate(clipped):
            out[vi, base + 1 + f] = np.clip(np.take(a, fi), -cap_m, cap_m)
        for f, a in enumerate(plain):
            out[vi, base + 3 + f] = np.take(a, fi)
        out[vi, base + 6] = np.minimum(np.take(o.path_gap_m, fi), cap_m)  # type: ignore[attr-defined]
        out[vi, base + 7] = np.clip(np.take(o.path_lateral_m, fi), -cap_m, cap_m)  # type: ignore[attr-defined]
        out[vi, base + 8] = np.take(o.category, fi)  # type: ignore[attr-defined]
    if rider_on_road is not None:
        out[:, -1] = rider_on_road
    return out.astype(np.float32)


__all__ = [
    "EGO_FEATURES",
    "N_EGO",
    "N_OBJ",
    "OBJECT_FEATURES",
    "ROAD_FEATURES",
    "feature_names",
    "nearest_slots",
    "observation_bounds",
    "vectorize",
]
