"""The car's fusion of its on-board perception with its V2X tracks, per road user.

Each road user of the observation gets a source (:data:`SOURCE_SENSOR`, :data:`SOURCE_V2X`,
:data:`SOURCE_BOTH`; :data:`SOURCE_NONE` where unknown), an age and a 1-sigma position
uncertainty:

- sensor only: the perceived object as it was (uncertainty: the sensor's position noise);
- V2X only: the V2X track predicted to now (uncertainty: the message's stated accuracy);
- both: the position is the inverse-variance mean of the two (the sensor's alone when its
  noise is 0, the V2X one's alone when the message states 0); velocity, heading and box
  are the sensor's; the age is the younger of the two.

Arrays follow :mod:`vei.sim.observe`: the perceived world ``[6, b, N]`` (x, y, yaw, vx, vy,
present) in the world frame.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.policy.observation import SOURCE_BOTH, SOURCE_NONE, SOURCE_SENSOR, SOURCE_V2X
from vei.policy.v2x.model import V2XObjects

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


def fuse(
    world: FloatArray,
    valid: BoolArray,
    age_s: FloatArray,
    sensor_std_m: float,
    objs: V2XObjects,
    columns: npt.ArrayLike,
) -> tuple[FloatArray, BoolArray, FloatArray, npt.NDArray[np.int8], FloatArray]:
    """Fuse the V2X objects of the sender columns into the perceived world (pure).

    Args:
        world: [6, b, N] perceived road users (x_m, y_m, yaw_rad, vx_mps, vy_mps, present).
        valid: [b, N] perceived. age_s: [b, N] their age [s] (+inf where not perceived).
        sensor_std_m: the sensor's 1-sigma position noise per axis [m] (>= 0).
        objs: [b, S] V2X objects. columns: [S] their road users' indices.
    Returns:
        (world [6, b, N], valid [b, N], age_s [b, N], source [b, N] int8, position_std_m
        [b, N] (+inf where not valid)).
    """
    cols = np.asarray(columns, dtype=np.intp)
    out = world.copy()
    val = valid.copy()
    age = np.array(age_s, dtype=np.float64, copy=True)
    source = np.where(valid, SOURCE_SENSOR, SOURCE_NONE).astype(np.int8)
    std = np.where(valid, float(sensor_std_m), np.inf)
    if cols.size == 0:
        return out, val, age, source, std
    sv = valid[:, cols]
    vv = objs.valid
    only_v = vv & ~sv
    both = vv & sv
    sub = out[:, :, cols]
    v2x = np.stack([objs.x_m, objs.y_m, objs.yaw_rad, objs.vx_mps, objs.vy_mps,
                    vv.astype(np.float64)])  # fmt: skip
    sub = np.where(only_v[None], v2x, sub)
    s_std = float(sensor_std_m)
    v_std = np.where(vv, objs.std_m, np.inf)
    if s_std == 0.0:
        w_v = np.zeros(v_std.shape)
    else:
        with np.errstate(divide="ignore"):
            ratio = (s_std / v_std) ** 2  # w_v / w_s
        w_v = np.where(v_std == 0.0, 1.0, ratio / (1.0 + ratio))
    for axis in (0, 1):
        mixed = (1.0 - w_v) * sub[axis] + w_v * v2x[axis]
        sub[axis] = np.where(both, mixed, sub[axis])
    out[:, :, cols] = sub
    if s_std == 0.0:
        fused_std = np.zeros(v_std.shape)
    else:
        fused_std = np.where(v_std == 0.0, 0.0, 1.0 / np.sqrt(1.0 / s_std**2 + 1.0 / v_std**2))
    std[:, cols] = np.where(both, fused_std, np.where(only_v, v_std, std[:, cols]))
    v_age = np.where(vv, objs.age_s, np.inf)
    age[:, cols] = np.where(both, np.minimum(age[:, cols], v_age),
                            np.where(only_v, v_age, age[:, cols]))  # fmt: skip
    val[:, cols] = sv | vv
    source[:, cols] = np.where(both, SOURCE_BOTH, np.where(only_v, SOURCE_V2X, source[:, cols]))
    return out, val, age, source, std


__all__ = ["fuse"]
