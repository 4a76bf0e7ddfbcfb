"""Oriented-box geometry for the metrics: corners, overlap of corner sets, time to contact.

The box-to-box gap is :func:`vei.models.geometry.box_gap` (one implementation for the
engine, the metrics and the sweeps).

Pure NumPy, broadcasting over any leading axes (typically ``[B, T]``). A box is given by
its centre ``xy`` [..., 2] (m), heading ``yaw`` [...] (rad, CCW from +x), length along the
heading and width across it (m). Corners run counter-clockwise: rear-right, front-right,
front-left, rear-left.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.models.geometry import box_corners as _model_box_corners

FloatArray = npt.NDArray[np.float64]

_EPS = 1e-12


def box_corners(
    xy: npt.ArrayLike, yaw: npt.ArrayLike, length_m: float, width_m: float
) -> FloatArray:
    """Corners of oriented boxes (the models' :func:`vei.models.geometry.box_corners`).

    Args:
        xy: centres [..., 2] (m). yaw: headings [...] (rad).
        length_m, width_m: box size (m).
    Returns:
        [..., 4, 2] corners (m), counter-clockwise from rear-right.
    """
    xy = np.asarray(xy, dtype=np.float64)
    return _model_box_corners(xy[..., 0], xy[..., 1], yaw, length_m, width_m)


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def boxes_overlap(corners_a: FloatArray, corners_b: FloatArray) -> npt.NDArray[np.bool_]:
    """Separating-axis test of two convex quadrilaterals (touching counts as overlap).

    Args:
        corners_a, corners_b: [..., 4, 2] corners (m), as from :func:`box_corners`.
    Returns:
        [...] bool, True where the boxes share at least one point.
    """
    result = np.ones(np.broadcast_shapes(corners_a.shape, corners_b.shape)[:-2], dtype=bool)
    for corners in (corners_a, corners_b):
        for k in range(2):  # a rectangle has two distinct edge normals
            edge = corners[..., k + 1, :] - corners[..., k, :]
            axis = np.stack([-edge[..., 1], edge[..., 0]], axis=-1)[..., None, :]
            pa = np.sum(corners_a * axis, axis=-1)
            pb = np.sum(corners_b * axis, axis=-1)
            scale = np.maximum(np.linalg.norm(axis[..., 0, :], axis=-1), _EPS)
            tol = 1e-9 * scale
            separated = (pa.max(axis=-1) < pb.min(axis=-1) - tol) | (
                pb.max(axis=-1) < pa.min(axis=-1) - tol
            )
            result &= ~separated
    return result


def time_to_contact(
    corners_a: FloatArray, corners_b: FloatArray, vel_rel_mps: FloatArray
) -> FloatArray:
    """Time until two boxes first touch if B keeps moving at ``vel_rel_mps`` relative to A.

    Both boxes keep their headings (translation only); the first contact of two
    translating convex polygons is a vertex of one reaching an edge of the other, so the
    answer is the smallest ray-edge hit over B's vertices moving by +v and A's vertices
    moving by -v.

    Args:
        corners_a, corners_b: [..., 4, 2] corners (m).
        vel_rel_mps: [..., 2] velocity of B minus velocity of A (m/s).
    Returns:
        [...] time (s): 0 where they already overlap, inf where they never touch.
    """
    v = np.asarray(vel_rel_mps, dtype=np.float64)
    best = np.full(np.broadcast_shapes(corners_a.shape, corners_b.shape)[:-2], np.inf)
    for verts, edges, sign in ((corners_b, corners_a, 1.0), (corners_a, corners_b, -1.0)):
        p = verts[..., :, None, :]  # [..., 4, 1, 2]
        a = edges[..., None, :, :]  # [..., 1, 4, 2]
        e = np.roll(edges, -1, axis=-2)[..., None, :, :] - a
        vv = sign * v[..., None, None, :]
        denom = _cross(vv, e)
        ap = a - p
        with np.errstate(divide="ignore", invalid="ignore"):
            s = _cross(ap, e) / denom
            u = _cross(ap, vv) / denom
        ok = (np.abs(denom) > _EPS) & (s >= 0.0) & (u >= -1e-12) & (u <= 1.0 + 1e-12)
        hit = np.where(ok, s, np.inf).min(axis=(-1, -2))
        best = np.minimum(best, hit)
    return np.where(boxes_overlap(corners_a, corners_b), 0.0, best)
