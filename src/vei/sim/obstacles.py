"""Riders brake for a standing or slow car in their way (issue 32), in the NumPy step.

The paper's forces let a rider ride into a car that stands in its path: the car's
repulsion is ~3 N at 1 m (A 100 N, b 3.5 1/m) against the ~400 N of the destination force
that keeps the rider at its desired speed. A rider with ``sfm.obstacle_braking`` (the
calibrated Normal rider) looks along its desired velocity: where that ray meets the car's
box (widened by the rider's half-diagonal) and the car is slower than
``sfm.obstacle_speed_mps``, it caps its desired speed so that it can stop
``sfm.obstacle_margin_m`` short of it at ``sfm.obstacle_decel_mps2``
(:func:`vei.models.sfm_core.obstacle_speed_core`; the compiled kernel runs the same core
on scalars, :mod:`vei.sim.kernel.sfm`). The car of the state at step k counts (the
forces' own time).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from vei.models import decision_core as dcore
from vei.models import sfm_core as core

FloatArray = npt.NDArray[np.float64]


def _at(a: Any, idx: npt.NDArray[np.intp] | None) -> Any:
    """a[idx] for arrays, a for scalars; idx None = everything."""
    if idx is None or np.ndim(a) == 0:
        return a
    return np.asarray(a)[idx]


def obstacle_block(
    st: Any,
    arrays: Any,
    blk: Any,
    sel: npt.NDArray[np.intp] | None,
    x0: FloatArray,
    y0: FloatArray,
    vdx: FloatArray,
    vdy: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """The desired velocity (vdx, vdy) [b] [m/s] of the moving social-force riders ``sel``
    (None = all) of one engine block at step k (state ``st``; positions x0, y0 [m]),
    capped where the ego stands or creeps in their way (see the module)."""
    p = blk.params
    eyaw = _at(st.ego_yaw_rad, sel)
    cap = core.obstacle_speed_core(
        x0, y0, vdx, vdy, _at(st.rider_speed_mps, sel),
        _at(st.ego_x_m, sel), _at(st.ego_y_m, sel), np.cos(eyaw), np.sin(eyaw),
        0.5 * arrays.ego_length_m, 0.5 * arrays.ego_width_m,
        0.5 * np.hypot(arrays.rider_length_m, arrays.rider_width_m),
        _at(p.obstacle_margin_m, sel), _at(p.obstacle_decel_mps2, sel),
        _at(p.mass_kg, sel) / _at(p.k_des_nspm, sel),
    )  # fmt: skip
    on = _at(st.ego_v_mps, sel) < _at(p.obstacle_speed_mps, sel)
    if blk.obstacle is not True:  # a mixed block: only the braking variants
        on = on & np.asarray(_at(blk.obstacle, sel), dtype=bool)
    cap = np.where(on, cap, np.inf)
    vx, vy = dcore.capped_velocity_core(vdx, vdy, cap)
    return np.asarray(vx), np.asarray(vy)
