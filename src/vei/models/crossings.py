"""Where two paths cross: segment intersections of arc-length parametrised paths.

Used for the conflicts of the rider's yield / go decision (:mod:`vei.sim.decisions`, the
calibration of decisions on recorded tracks :mod:`vei.calibrate.decisions`) and for the
road users that react to the ego (:mod:`vei.sim.traffic`). Pure NumPy on PathTables.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.models.ego import PathTable

FloatArray = npt.NDArray[np.float64]
#: Spacing [m] of the path points whose segments are intersected.
CROSSING_STEP_M = 0.5


def _polyline(path: PathTable, step_m: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """(s, x, y) of every ``step_m``-th grid point of a PathTable (the last one included)."""
    k = max(1, int(round(step_m / path.ds_m)))
    idx = np.arange(0, path.x_m.shape[0], k)
    if idx[-1] != path.x_m.shape[0] - 1:
        idx = np.append(idx, path.x_m.shape[0] - 1)
    s = path.s_start_m + idx * path.ds_m
    return s, path.x_m[idx], path.y_m[idx]


def path_crossings(
    a: PathTable, b: PathTable, step_m: float = CROSSING_STEP_M
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Where two paths cross: [K] arc lengths along a and along b [m] and |sin| of the
    crossing angle (segment intersections of the paths' polylines, ``step_m`` apart)."""
    sa, ax, ay = _polyline(a, step_m)
    sb, bx, by = _polyline(b, step_m)
    px, py = ax[:-1, None], ay[:-1, None]
    rx, ry = np.diff(ax)[:, None], np.diff(ay)[:, None]
    qx, qy = bx[None, :-1], by[None, :-1]
    ux, uy = np.diff(bx)[None, :], np.diff(by)[None, :]
    den = rx * uy - ry * ux
    safe = np.where(np.abs(den) > 1e-12, den, 1.0)
    t = ((qx - px) * uy - (qy - py) * ux) / safe
    u = ((qx - px) * ry - (qy - py) * rx) / safe
    hit = (np.abs(den) > 1e-12) & (t >= 0) & (t < 1) & (u >= 0) & (u < 1)
    i, j = np.nonzero(hit)
    ti, uj = t[i, j], u[i, j]
    s_a = sa[i] + ti * np.diff(sa)[i]
    s_b = sb[j] + uj * np.diff(sb)[j]
    la = np.hypot(rx[i, 0], ry[i, 0])
    lb = np.hypot(ux[0, j], uy[0, j])
    sin_abs = np.abs(den[i, j]) / np.maximum(la * lb, 1e-12)
    return s_a, s_b, sin_abs
