"""Oriented-box geometry for the metrics: corners of stacked centres; overlap of corner
sets and time to contact re-exported from the bottom floor.

The box geometry itself lives in :mod:`vei.boxes` (one implementation for the engine, the
models, the metrics and the sweeps; e.g. the box-to-box gap :func:`vei.boxes.box_gap`).

Pure NumPy, broadcasting over any leading axes (typically ``[B, T]``). A box is given by
its centre ``xy`` [..., 2] (m), heading ``yaw`` [...] (rad, CCW from +x), length along the
heading and width across it (m). Corners run counter-clockwise: rear-right, front-right,
front-left, rear-left.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.boxes import box_corners as _box_corners
from vei.boxes import corners_overlap as boxes_overlap
from vei.boxes import time_to_contact

__all__ = ["box_corners", "boxes_overlap", "time_to_contact"]

FloatArray = npt.NDArray[np.float64]


def box_corners(
    xy: npt.ArrayLike, yaw: npt.ArrayLike, length_m: float, width_m: float
) -> FloatArray:
    """Corners of oriented boxes (:func:`vei.boxes.box_corners` of stacked centres).

    Args:
        xy: centres [..., 2] (m). yaw: headings [...] (rad).
        length_m, width_m: box size (m).
    Returns:
        [..., 4, 2] corners (m), counter-clockwise from rear-right.
    """
    xy = np.asarray(xy, dtype=np.float64)
    return _box_corners(xy[..., 0], xy[..., 1], yaw, length_m, width_m)
