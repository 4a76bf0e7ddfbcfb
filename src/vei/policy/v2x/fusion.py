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
    age = np.asarray(age_s, dtype=np.float64)
    source = np.where(valid, SOURCE_SENSOR, SOURCE_NONE).astype(np.int8)
    s_std = float(sensor_std_m)
    std = np.where(valid, s_std, np.inf)
    bi, si = np.nonzero(objs.valid)
    if cols.size == 0 or bi.size == 0:
        return world, valid, age, source, std
    out = world.copy()
    val = valid.copy()
    age = age.copy()
    oj = cols[si]
    seen = valid[bi, oj]
    v_std = objs.std_m[bi, si]
    vx, vy = objs.x_m[bi, si], objs.y_m[bi, si]
    if s_std == 0.0:
        w_v = np.zeros(bi.size)
        fused_std = np.zeros(bi.size)
    else:
        with np.errstate(divide="ignore", invalid="ignore"):
            ratio = (s_std / v_std) ** 2  # w_v / w_s
            w_v = np.where(v_std == 0.0, 1.0, ratio / (1.0 + ratio))
            fused_std = np.where(v_std == 0.0, 0.0, 1.0 / np.sqrt(1.0 / s_std**2 + 1.0 / v_std**2))
    # Both: inverse-variance position, the sensor's velocity, heading and box.
    out[0, bi, oj] = np.where(seen, (1.0 - w_v) * world[0, bi, oj] + w_v * vx, vx)
    out[1, bi, oj] = np.where(seen, (1.0 - w_v) * world[1, bi, oj] + w_v * vy, vy)
    # V2X only: the predicted track.
    out[2, bi, oj] = np.where(seen, world[2, bi, oj], objs.yaw_rad[bi, si])
    out[3, bi, oj] = np.where(seen, world[3, bi, oj], objs.vx_mps[bi, si])
    out[4, bi, oj] = np.where(seen, world[4, bi, oj], objs.vy_mps[bi, si])
    out[5, bi, oj] = 1.0
    v_age = objs.age_s[bi, si]
    age[bi, oj] = np.where(seen, np.minimum(age[bi, oj], v_age), v_age)
    std[bi, oj] = np.where(seen, fused_std, v_std)
    val[bi, oj] = True
    source[bi, oj] = np.where(seen, SOURCE_BOTH, SOURCE_V2X)
    return out, val, age, source, std


__all__ = ["fuse"]
