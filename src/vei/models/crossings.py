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


#: Spacing [m] of the rider's path samples whose distance to the car's path is measured.
CORRIDOR_STEP_M = 0.25
#: Gaps [m] along the rider's path between two stretches inside the car's corridor that
#: are closed (one zone): shorter than a rider, a zone split by sampling is one zone.
ZONE_MERGE_M = 1.0


def corridor_zones(
    rider: PathTable,
    car: PathTable,
    car_length_m: float,
    car_width_m: float,
    rider_length_m: float,
    rider_width_m: float,
    margin_m: float,
    step_m: float = CORRIDOR_STEP_M,
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Where the rider's path comes within the car's swept corridor: [K] zones.

    The corridor is the strip the car's box sweeps along its path (half-width
    ``car_width_m / 2``) widened by the rider's half-extent across the car's path (its box,
    ``0.5 (L_r |sin dpsi| + W_r |cos dpsi|)`` at heading difference dpsi) and ``margin_m``.
    A zone is a stretch of the rider's path whose points lie inside it: a crossing (at
    angle theta its half-length along the rider's path is
    ``(W_e / 2 + L_r sin / 2 + W_r cos / 2 + margin) / sin``, the crossing zone of
    :func:`vei.models.decision_core.zone_half_lengths_core` widened by the margin), a
    stretch shared with the car's lane, or a pass within reach without crossing (a rider
    beside the car's path at a turn).

    Args:
        rider, car: the two paths (their whole tables, extensions included).
        car_length_m, car_width_m, rider_length_m, rider_width_m: footprints [m].
        margin_m: clearance [m] the corridor adds on each side.
        step_m: spacing of the rider's path samples [m].
    Returns:
        (s_in, s_out, e_in, e_out) [K], sorted by s_out: the zone's entry and exit along
        the rider's path [m], and the stretch of the car's path (centre arc length [m]) on
        which the car's box overlaps the zone (the car's half-length and the rider's
        half-extent along the car's path added).
    """
    from scipy.spatial import cKDTree

    sr, rx, ry = _polyline(rider, step_m)
    r_yaw = np.interp(sr, rider.s_start_m + np.arange(rider.x_m.size) * rider.ds_m, rider.yaw_rad)
    sc, cx, cy = _polyline(car, min(step_m, CROSSING_STEP_M))
    c_yaw = np.interp(sc, car.s_start_m + np.arange(car.x_m.size) * car.ds_m, car.yaw_rad)
    empty = np.zeros(0)
    if sr.size < 2 or sc.size < 2:
        return empty, empty, empty, empty
    _, j = cKDTree(np.column_stack([cx, cy])).query(np.column_stack([rx, ry]))
    best_d = np.full(sr.size, np.inf)
    best_s = np.zeros(sr.size)
    best_yaw = np.zeros(sr.size)
    for seg in (np.clip(j - 1, 0, sc.size - 2), np.clip(j, 0, sc.size - 2)):
        ax, ay = cx[seg], cy[seg]
        ux, uy = cx[seg + 1] - ax, cy[seg + 1] - ay
        ll = np.maximum(ux * ux + uy * uy, 1e-12)
        t = np.clip(((rx - ax) * ux + (ry - ay) * uy) / ll, 0.0, 1.0)
        d = np.hypot(rx - (ax + t * ux), ry - (ay + t * uy))
        better = d < best_d
        best_d = np.where(better, d, best_d)
        best_s = np.where(better, sc[seg] + t * (sc[seg + 1] - sc[seg]), best_s)
        best_yaw = np.where(better, c_yaw[seg], best_yaw)
    dpsi = r_yaw - best_yaw
    s_abs, c_abs = np.abs(np.sin(dpsi)), np.abs(np.cos(dpsi))
    across = 0.5 * (rider_length_m * s_abs + rider_width_m * c_abs)
    along = 0.5 * (rider_length_m * c_abs + rider_width_m * s_abs)
    excess = best_d - (0.5 * car_width_m + across + margin_m)  # < 0: inside
    inside = excess < 0.0
    if not inside.any():
        return empty, empty, empty, empty
    edges = np.diff(inside.astype(np.int8))
    starts = list(np.flatnonzero(edges == 1) + 1)
    ends = list(np.flatnonzero(edges == -1))
    if inside[0]:
        starts.insert(0, 0)
    if inside[-1]:
        ends.append(sr.size - 1)
    runs = []
    for a, b in zip(starts, ends, strict=True):
        if runs and sr[a] - sr[runs[-1][1]] < ZONE_MERGE_M:
            runs[-1] = (runs[-1][0], b)
        else:
            runs.append((a, b))

    def cross(i: int, k: int) -> float:
        """The arc where excess crosses 0 between samples i and k (linear)."""
        e0, e1 = excess[i], excess[k]
        f = e0 / (e0 - e1) if e0 != e1 else 0.5
        return float(sr[i] + f * (sr[k] - sr[i]))

    s_in, s_out, e_in, e_out = [], [], [], []
    for a, b in runs:
        s_in.append(float(sr[a]) if a == 0 else cross(a - 1, a))
        s_out.append(float(sr[b]) if b == sr.size - 1 else cross(b, b + 1))
        reach = 0.5 * car_length_m + float(along[a : b + 1].max())
        e_in.append(float(best_s[a : b + 1].min()) - reach)
        e_out.append(float(best_s[a : b + 1].max()) + reach)
    o = np.argsort(s_out, kind="stable")
    return (np.asarray(s_in)[o], np.asarray(s_out)[o], np.asarray(e_in)[o], np.asarray(e_out)[o])
