"""Sensor geometry of the perception model: range, field of view and line of sight.

Pure NumPy over a batch of variants ``[B]`` and objects ``[B, N]``. A target is sampled at
``P = 5`` points of its oriented box: its centre and its four corners
(:func:`vei.boxes.box_corners`). A sample point is *seen* when it lies within the
sensor's range (Euclidean distance from the sensor's mounting point), within its field of
view (the bearing from the sensor, measured from the ego's heading, within +-fov/2) and,
with occlusion on, when the straight segment from the sensor to the point crosses the
interior of no occluding box. A target's visible fraction is the share of its P points
seen.

Line of sight: the segment is clipped against each occluder's box in the box's own frame
(slab method of Liang & Barsky, 1984); it is blocked when the clipped part inside the open
box is longer than ``BLOCK_TOL_M`` (so a segment grazing an edge or touching a corner is
not blocked). An occluder never hides itself, and an occluder whose box contains the
sensor point is ignored (that happens only after the ego ran into it; it would otherwise
blind the sensor).
"""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from vei.boxes import box_corners

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

N_SAMPLE_POINTS = 5
BLOCK_TOL_M = 1e-6
_COS_TOL = 1e-12  # so that a point exactly on the FOV edge counts as inside
_PARALLEL_TOL = 1e-12


def sensor_position(
    ego_x_m: FloatArray,
    ego_y_m: FloatArray,
    ego_yaw_rad: FloatArray,
    sensor_x_m: float,
    sensor_y_m: float,
) -> tuple[FloatArray, FloatArray]:
    """World position of the sensor mounted at (sensor_x_m, sensor_y_m) in the ego frame.

    Args:
        ego_x_m, ego_y_m, ego_yaw_rad: ego box centre and heading [B] (m, rad).
        sensor_x_m, sensor_y_m: mounting point, forward of / left of the ego box centre (m).
    Returns:
        (sx_m, sy_m) [B] (m).
    """
    c, s = np.cos(ego_yaw_rad), np.sin(ego_yaw_rad)
    return ego_x_m + c * sensor_x_m - s * sensor_y_m, ego_y_m + s * sensor_x_m + c * sensor_y_m


def sample_points(
    x_m: FloatArray, y_m: FloatArray, yaw_rad: FloatArray, length_m: FloatArray, width_m: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The P = 5 sample points of oriented boxes: centre, then the four corners.

    Args:
        x_m, y_m, yaw_rad, length_m, width_m: boxes [B, N] (m, rad).
    Returns:
        (px_m, py_m) [B, N, 5] (m).
    """
    corners = box_corners(x_m, y_m, yaw_rad, length_m, width_m)  # [B, N, 4, 2]
    px = np.concatenate([np.asarray(x_m, dtype=np.float64)[..., None], corners[..., 0]], axis=-1)
    py = np.concatenate([np.asarray(y_m, dtype=np.float64)[..., None], corners[..., 1]], axis=-1)
    return px, py


def in_range_and_fov(
    px_m: FloatArray,
    py_m: FloatArray,
    sx_m: FloatArray,
    sy_m: FloatArray,
    ego_yaw_rad: FloatArray,
    range_m: float,
    fov_deg: float,
) -> BoolArray:
    """Whether points lie within the sensor's range and field of view.

    In range: distance from the sensor <= range_m. In the field of view: the bearing of the
    point from the sensor, relative to the ego's heading, wrapped to [-180, 180] deg, has
    magnitude <= fov_deg / 2 (always true for fov_deg = 360; a point at the sensor itself
    has bearing 0).

    Args:
        px_m, py_m: points [B, N, P] (m). sx_m, sy_m: sensor [B] (m).
        ego_yaw_rad: ego heading [B] (rad). range_m (m), fov_deg (deg): the sensor's.
    Returns:
        [B, N, P] bool.
    """
    dx = px_m - sx_m[:, None, None]
    dy = py_m - sy_m[:, None, None]
    dist = np.hypot(dx, dy)
    ok = dist <= range_m
    if fov_deg < 360.0:
        # |bearing| <= h  <=>  cos(bearing) >= cos(h)  <=>  forward >= cos(h) * distance.
        c = np.cos(ego_yaw_rad)[:, None, None]
        s = np.sin(ego_yaw_rad)[:, None, None]
        cos_half = math.cos(math.radians(0.5 * fov_deg))
        ok &= c * dx + s * dy >= (cos_half - _COS_TOL) * dist
    return ok


def _slab(start: FloatArray, delta: FloatArray, half: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Parameter interval [lo, hi] of ``start + t * delta`` inside the open slab |.| < half."""
    parallel = np.abs(delta) < _PARALLEL_TOL
    inside = np.abs(start) < half
    safe = np.where(parallel, 1.0, delta)
    t1 = (-half - start) / safe
    t2 = (half - start) / safe
    lo = np.where(parallel, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
    hi = np.where(parallel, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
    return lo, hi


def segments_blocked(
    sx_m: FloatArray,
    sy_m: FloatArray,
    px_m: FloatArray,
    py_m: FloatArray,
    box_x_m: FloatArray,
    box_y_m: FloatArray,
    box_yaw_rad: FloatArray,
    box_length_m: FloatArray,
    box_width_m: FloatArray,
) -> BoolArray:
    """Whether segments from a sensor to points cross the open interior of a box.

    One box per row q; the slab method in the box's frame. Grazing an edge or touching a
    corner (less than ``BLOCK_TOL_M`` inside) does not block.

    Args:
        sx_m, sy_m: sensor [Q] (m).
        px_m, py_m: segment ends [Q, P] (m).
        box_x_m, box_y_m, box_yaw_rad, box_length_m, box_width_m: the boxes [Q] (m, rad).
    Returns:
        [Q, P] bool.
    """
    c = np.cos(box_yaw_rad)[:, None]
    s = np.sin(box_yaw_rad)[:, None]
    hl = 0.5 * box_length_m[:, None]
    hw = 0.5 * box_width_m[:, None]
    rx = (sx_m - box_x_m)[:, None]
    ry = (sy_m - box_y_m)[:, None]
    u0 = rx * c + ry * s  # sensor in the box's frame [Q, 1]
    v0 = -rx * s + ry * c
    dx = px_m - sx_m[:, None]
    dy = py_m - sy_m[:, None]
    lo_u, hi_u = _slab(u0, dx * c + dy * s, hl)
    lo_v, hi_v = _slab(v0, -dx * s + dy * c, hw)
    t_in = np.maximum(np.maximum(lo_u, lo_v), 0.0)
    t_out = np.minimum(np.minimum(hi_u, hi_v), 1.0)
    return (t_out - t_in) * np.hypot(dx, dy) > BLOCK_TOL_M


def _occluder_pairs(
    sx: FloatArray,
    sy: FloatArray,
    x: FloatArray,
    y: FloatArray,
    yaw: FloatArray,
    length: FloatArray,
    width: FloatArray,
    occluders: BoolArray,
    rows_b: npt.NDArray[np.intp],
    rows_n: npt.NDArray[np.intp],
) -> tuple[npt.NDArray[np.intp], npt.NDArray[np.intp]]:
    """(row, occluder) pairs that can block: a cheap necessary test on bounding circles.

    A segment from the sensor S to a point of the target (within r_t, the target's half
    diagonal, of its centre T) stays within r_t of the segment S-T; an occluder can only
    cross it when its centre O lies within r_o + r_t of the segment S-T (r_o its half
    diagonal). Occluders holding the sensor, the target itself and absent / non-occluding
    objects are left out. Rows are targets (rows_b, rows_n); returns (row, occluder) index
    pairs.
    """
    n_obj = x.shape[1]
    dx = x - sx[:, None]  # [B, M], object centres relative to the sensor
    dy = y - sy[:, None]
    radius = 0.5 * np.hypot(length, width)
    c, s = np.cos(yaw), np.sin(yaw)
    u0 = -(dx * c + dy * s)  # the sensor in each box's frame
    v0 = dx * s - dy * c
    usable = occluders & ~((np.abs(u0) < 0.5 * length) & (np.abs(v0) < 0.5 * width))
    tx, ty = dx[rows_b, rows_n][:, None], dy[rows_b, rows_n][:, None]  # [K, 1]
    ox, oy = dx[rows_b], dy[rows_b]  # [K, M]
    t = np.clip((ox * tx + oy * ty) / np.maximum(tx * tx + ty * ty, 1e-300), 0.0, 1.0)
    reach = radius[rows_b] + radius[rows_b, rows_n][:, None] + 1e-9
    ok = usable[rows_b] & (np.hypot(ox - t * tx, oy - t * ty) <= reach)
    ok &= np.arange(n_obj)[None, :] != rows_n[:, None]
    pair_row, pair_occ = np.nonzero(ok)
    return pair_row, pair_occ


def visible_fraction(
    x_m: FloatArray,
    y_m: FloatArray,
    yaw_rad: FloatArray,
    length_m: FloatArray,
    width_m: FloatArray,
    valid: BoolArray,
    can_occlude: BoolArray,
    ego_x_m: FloatArray,
    ego_y_m: FloatArray,
    ego_yaw_rad: FloatArray,
    *,
    range_m: float,
    fov_deg: float,
    sensor_x_m: float,
    sensor_y_m: float,
    occlusion: bool,
) -> FloatArray:
    """Share of each target's P = 5 sample points that the sensor sees.

    Args:
        x_m, y_m, yaw_rad, length_m, width_m: objects' boxes [B, N] (m, rad).
        valid: [B, N] objects present in the scene (absent ones get 0).
        can_occlude: [B, N] objects whose boxes hide others (present ones only count).
        ego_x_m, ego_y_m, ego_yaw_rad: ego box centre and heading [B] (m, rad).
        range_m, fov_deg, sensor_x_m, sensor_y_m, occlusion: the sensor (see
            :class:`vei.policy.perception.PerceptionConfig`).
    Returns:
        [B, N] float in {0, 0.2, 0.4, 0.6, 0.8, 1}.
    """
    sx, sy = sensor_position(ego_x_m, ego_y_m, ego_yaw_rad, sensor_x_m, sensor_y_m)
    px, py = sample_points(x_m, y_m, yaw_rad, length_m, width_m)
    seen = in_range_and_fov(px, py, sx, sy, ego_yaw_rad, range_m, fov_deg)
    seen &= valid[:, :, None]
    n_obj = valid.shape[1]
    if occlusion and n_obj > 1:
        occluders = valid & can_occlude  # [B, M]
        rows_b, rows_n = np.nonzero(seen.any(axis=-1) & occluders.any(axis=1)[:, None])
        rows_q, occ = _occluder_pairs(
            sx, sy, x_m, y_m, yaw_rad, length_m, width_m, occluders, rows_b, rows_n
        )
        if rows_q.size:
            pb, pn = rows_b[rows_q], rows_n[rows_q]
            blocked = segments_blocked(
                sx[pb],
                sy[pb],
                px[pb, pn],
                py[pb, pn],
                x_m[pb, occ],
                y_m[pb, occ],
                yaw_rad[pb, occ],
                length_m[pb, occ],
                width_m[pb, occ],
            )  # [Q, P]
            hidden = np.zeros((rows_b.size, N_SAMPLE_POINTS), dtype=bool)
            np.logical_or.at(hidden, rows_q, blocked)
            seen[rows_b, rows_n] &= ~hidden
    return seen.sum(axis=-1) / float(N_SAMPLE_POINTS)
