"""A drivable ego path: continuous heading, curvature bounded by the vehicle's limits.

The ego follows a path given as recorded positions (GPS/INS at the simulation rate). Raw
positions are not drivable as they stand: while the car waits (e.g. at a red light) the
receiver jitters by millimetres to centimetres in random directions, and a heading taken
from those points is noise. The first heading of the old table came from exactly that
jitter (on stadtmitte_12_audi_geradeaus_03: 0.48 rad, while the INS and the first metres
of motion say 1.95 rad), so the run-up joined the recorded path at 70 degrees.

:func:`build_ego_path` therefore

1. collapses standstill: a recorded point is kept only when it lies at least
   ``min_step_m`` from the last kept one (jitter never adds arc length);
2. fits a cubic smoothing spline ``(x(u), y(u))`` in the arc length u of the kept points
   (:func:`scipy.interpolate.make_smoothing_spline`, one penalty for both coordinates).
   Its second derivative is (for |r'| ~ 1) the curvature, which the penalty bounds: the
   spline is raised in smoothness (lam x 2 per try, then bisected) until the curvature
   just stays within
   ``kappa_max = max_lat_accel_mps2 / path_speed_mps^2`` (lateral acceleration at the
   cruise speed). Natural end conditions give zero curvature at both ends, so the straight
   extensions join with continuous heading *and* curvature;
3. resamples on a uniform grid of the spline's true arc length, heading from the spline's
   analytic tangent (continuous, unwrapped);
4. extends the table straight along the initial tangent backwards (the run-up: the first
   metres of real motion give that heading, never a chord to a far point) and along the
   final tangent forwards.

Why a smoothing spline and not a clothoid fit: it is linear least squares (one solve per
try, milliseconds for a minute of driving), keeps the path within centimetres of the
recording where the recording is already drivable, and its smoothness knob maps directly
onto the curvature bound. The deviation it needs is reported (``max_deviation_m``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from vei.errors import InputError
from vei.models.ego import PathTable

FloatArray = npt.NDArray[np.float64]

#: Default bound on the lateral acceleration of a drivable path at the cruise speed [m/s^2].
DEFAULT_MAX_LAT_ACCEL_MPS2 = 4.0
#: The bound is computed for the cruise speed times this factor, so that the speed
#: controller's overshoot above v_d (a few per cent after braking) stays within it.
PATH_SPEED_MARGIN = 1.05


@dataclass(frozen=True)
class EgoPathInfo:
    """How a drivable ego path was built (see :func:`build_ego_path`).

    Attributes:
        method: 'spline' (smoothing spline), 'line' (too few points: straight chord) or
            'standing' (no motion: straight along the heading hint).
        lam: smoothing parameter of the spline (NaN unless 'spline').
        kappa_max_per_m: the curvature bound [1/m] (max_lat_accel / path_speed^2).
        max_curvature_per_m: largest |curvature| of the built path [1/m].
        path_speed_mps: speed the bound was computed for [m/s].
        max_lat_accel_mps2: the lateral-acceleration bound [m/s^2].
        max_deviation_m: largest distance of a recorded point from the built path [m].
        initial_yaw_rad, final_yaw_rad: headings of the straight extensions [rad].
    """

    method: str
    lam: float
    kappa_max_per_m: float
    max_curvature_per_m: float
    path_speed_mps: float
    max_lat_accel_mps2: float
    max_deviation_m: float
    initial_yaw_rad: float
    final_yaw_rad: float

    def as_dict(self) -> dict:
        """JSON-ready fields."""
        return {k: float(v) if not isinstance(v, str) else v for k, v in self.__dict__.items()}


def decimate_standstill(
    x_m: FloatArray, y_m: FloatArray, min_step_m: float
) -> npt.NDArray[np.intp]:
    """Indices of the points kept: each at least ``min_step_m`` from the previously kept one.

    The first point is always kept; the last one too when it is at least half a step from
    the previously kept one (else it replaces it). Jitter of a standing vehicle (radius <
    min_step_m) thus collapses onto one point.

    Args:
        x_m, y_m: [M] positions in time order [m]. min_step_m: spacing [m] (> 0).
    Returns:
        [K] increasing indices into the input.
    """
    keep = [0]
    lx, ly = x_m[0], y_m[0]
    step2 = min_step_m * min_step_m
    for i in range(1, x_m.shape[0]):
        dx, dy = x_m[i] - lx, y_m[i] - ly
        if dx * dx + dy * dy >= step2:
            keep.append(i)
            lx, ly = x_m[i], y_m[i]
    last = x_m.shape[0] - 1
    if keep[-1] != last:
        d = np.hypot(x_m[last] - x_m[keep[-1]], y_m[last] - y_m[keep[-1]])
        if d >= 0.5 * min_step_m:
            keep.append(last)
        elif len(keep) > 1:
            keep[-1] = last
    return np.asarray(keep, dtype=np.intp)


#: A road user dwells where its track stays within this radius [m] of one point for at
#: least DWELL_MIN_S [s] (the reconstructed tracks of waiting riders jitter by up to a
#: metre: 1.4 m on stadtmitte_12_audi_geradeaus_03, 1.1 m on
#: audi_10_marktkauf_linksabbiegen's cyclist_1, which waits for 20 s).
DWELL_RADIUS_M = 1.5
DWELL_MIN_S = 2.0


def dwell_segments(
    x_m: FloatArray,
    y_m: FloatArray,
    t_s: FloatArray,
    radius_m: float = DWELL_RADIUS_M,
    min_dwell_s: float = DWELL_MIN_S,
) -> list[tuple[int, int]]:
    """The dwells of a track: [(i, j)] sample ranges [i, j) over which it stays within
    ``radius_m`` of sample i for at least ``min_dwell_s`` (a dwell ends at the first
    sample that leaves the radius; the next is looked for from there). A track that moves
    at more than ``radius_m / min_dwell_s`` (0.75 m/s) everywhere has none.

    Args:
        x_m, y_m: [M] positions in time order [m]. t_s: [M] their times [s].
        radius_m, min_dwell_s: the dwell's radius [m] and least duration [s].
    """
    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    t = np.asarray(t_s, dtype=np.float64)
    n = x.shape[0]
    out: list[tuple[int, int]] = []
    r2 = radius_m * radius_m
    i = 0
    while i < n:
        # the samples within min_dwell_s of sample i: all inside the radius?
        m = int(np.searchsorted(t, t[i] + min_dwell_s - 1e-9, side="left"))
        if m >= n or np.any((x[i : m + 1] - x[i]) ** 2 + (y[i : m + 1] - y[i]) ** 2 >= r2):
            i += 1
            continue
        d2 = (x[m:] - x[i]) ** 2 + (y[m:] - y[i]) ** 2
        away = np.flatnonzero(d2 >= r2)
        j = m + int(away[0]) if away.size else n
        out.append((i, j))
        i = j
    return out


def dwell_mask(
    x_m: FloatArray,
    y_m: FloatArray,
    t_s: FloatArray,
    radius_m: float = DWELL_RADIUS_M,
    min_dwell_s: float = DWELL_MIN_S,
) -> npt.NDArray[np.bool_]:
    """[M] True at the samples of the track's dwells (:func:`dwell_segments`)."""
    out = np.zeros(np.shape(x_m)[0], dtype=bool)
    for i, j in dwell_segments(x_m, y_m, t_s, radius_m, min_dwell_s):
        out[i:j] = True
    return out


#: A dwell jitters when the track travels more than twice its reach from the dwell's
#: first sample plus this [m] within it: a reconstructed waiting rider goes back and forth
#: (tens of metres within a metre); a standing run-in travels nothing; slow, steady motion
#: travels about its reach.
JITTER_M = 1.0


def jitter_mask(x_m: FloatArray, y_m: FloatArray, t_s: FloatArray) -> npt.NDArray[np.bool_]:
    """[M] the samples of the dwells (:func:`dwell_segments`) along which the track
    jitters (see :data:`JITTER_M`): a wait whose path through its positions has loops."""
    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    out = np.zeros(x.shape[0], dtype=bool)
    for i, j in dwell_segments(x, y, t_s):
        travel = float(np.hypot(np.diff(x[i:j]), np.diff(y[i:j])).sum())
        reach = float(np.hypot(x[i:j] - x[i], y[i:j] - y[i]).max())
        if travel > 2.0 * reach + JITTER_M:
            out[i:j] = True
    return out


def path_curvature(path: PathTable, recorded_only: bool = True) -> FloatArray:
    """Curvature d(yaw)/ds of a PathTable's grid [1/m] (central differences), [N] or the
    recorded part [0, length_m] only."""
    k = np.gradient(path.yaw_rad, path.ds_m)
    if not recorded_only:
        return k
    i0 = int(round(-path.s_start_m / path.ds_m))
    i1 = i0 + int(round(path.length_m / path.ds_m))
    return k[i0 : i1 + 1]


def _spline_eval(
    u: FloatArray, xy: FloatArray, lam: float, ds_m: float
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, float]:
    """Fit and resample: (grid s [N], x, y, yaw (unwrapped), max |curvature|)."""
    from scipy.interpolate import make_smoothing_spline

    spl = make_smoothing_spline(u, xy, lam=lam, axis=0)
    uf = np.linspace(u[0], u[-1], max(int(np.ceil((u[-1] - u[0]) / (0.25 * ds_m))) + 1, 8))
    p = spl(uf)
    d1 = spl.derivative(1)(uf)
    d2 = spl.derivative(2)(uf)
    sp = np.hypot(d1[:, 0], d1[:, 1])
    kappa = (d1[:, 0] * d2[:, 1] - d1[:, 1] * d2[:, 0]) / np.maximum(sp, 1e-9) ** 3
    arc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(p[:, 0]), np.diff(p[:, 1])))])
    yaw_f = np.unwrap(np.arctan2(d1[:, 1], d1[:, 0]))
    n = int(np.floor(arc[-1] / ds_m + 1e-9)) + 1
    grid = np.arange(n) * ds_m
    gx = np.interp(grid, arc, p[:, 0])
    gy = np.interp(grid, arc, p[:, 1])
    gyaw = np.interp(grid, arc, yaw_f)
    return grid, gx, gy, gyaw, float(np.max(np.abs(kappa)))


def build_ego_path(
    x_m: npt.ArrayLike,
    y_m: npt.ArrayLike,
    *,
    yaw_hint_rad: float,
    path_speed_mps: float,
    max_lat_accel_mps2: float = DEFAULT_MAX_LAT_ACCEL_MPS2,
    min_step_m: float = 0.5,
    smoothing_length_m: float = 4.0,
    ds_m: float = 0.1,
    extend_m: float = 300.0,
    where: str = "ego path",
) -> tuple[PathTable, EgoPathInfo]:
    """A drivable arc-length table of the ego's recorded positions (see the module doc).

    Args:
        x_m, y_m: [M] recorded positions in time order [m].
        yaw_hint_rad: heading used when the vehicle never moves (e.g. the INS yaw) [rad].
        path_speed_mps: cruise speed the curvature bound is computed for [m/s] (> 0).
        max_lat_accel_mps2: lateral acceleration bound at that speed [m/s^2] (> 0).
        min_step_m: standstill collapse radius [m].
        smoothing_length_m: shortest wavelength the first fit keeps [m]; the starting
            lam is ``(smoothing_length_m / (2 pi))^4 / min_step_m`` (a cubic smoothing
            spline's cut-off with points ``min_step_m`` apart), so decimetre noise never
            reaches the curvature. ds_m: grid spacing [m].
        extend_m: straight extension at both ends [m]. where: name for error messages.
    Returns:
        (PathTable, EgoPathInfo). s = 0 is the first recorded position (projected).
    """
    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    if x.ndim != 1 or x.shape != y.shape or x.size == 0:
        raise InputError("expected 1-D x and y of equal, non-zero length", path=where)
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise InputError("path has non-finite positions", path=where)
    for name, val in (
        ("path_speed_mps", path_speed_mps),
        ("max_lat_accel_mps2", max_lat_accel_mps2),
    ):
        if not (np.isfinite(val) and val > 0):
            raise InputError(f"{name} must be finite and > 0, got {val}", path=where, field=name)
    kappa_max = max_lat_accel_mps2 / path_speed_mps**2
    keep = decimate_standstill(x, y, min_step_m)
    kx, ky = x[keep], y[keep]
    u = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(kx), np.diff(ky)))])
    lam = float("nan")
    if kx.size >= 5:
        method = "spline"
        xy = np.column_stack([kx, ky])
        # Smallest lam that removes centimetre noise, raised until the curvature bound holds.
        lam = (smoothing_length_m / (2.0 * np.pi)) ** 4 / min_step_m
        for _tries in range(60):
            fit = _spline_eval(u, xy, lam, ds_m)
            if fit[4] <= kappa_max:
                break
            lam *= 2.0
        else:
            raise InputError(
                f"cannot smooth the path to curvature <= {kappa_max:.4f} 1/m", path=where
            )
        if _tries:  # bisect (log lam) between the last failure and the success: no more
            lo_lam, hi_lam = 0.5 * lam, lam  # smoothing (corner cutting) than the bound needs
            for _ in range(6):
                mid = float(np.sqrt(lo_lam * hi_lam))
                cand = _spline_eval(u, xy, mid, ds_m)
                if cand[4] <= kappa_max:
                    hi_lam, fit = mid, cand
                else:
                    lo_lam = mid
            lam = hi_lam
        grid, gx, gy, gyaw, _ = fit
    elif u[-1] >= ds_m:
        method = "line"
        yaw = float(np.arctan2(ky[-1] - ky[0], kx[-1] - kx[0]))
        n = int(np.floor(u[-1] / ds_m + 1e-9)) + 1
        grid = np.arange(n) * ds_m
        gx = kx[0] + grid * np.cos(yaw)
        gy = ky[0] + grid * np.sin(yaw)
        gyaw = np.full(n, yaw)
    else:
        method = "standing"
        grid = np.array([0.0])
        gx, gy, gyaw = np.array([kx[0]]), np.array([ky[0]]), np.array([float(yaw_hint_rad)])
    yaw0, yaw1 = float(gyaw[0]), float(gyaw[-1])
    m = int(np.ceil(extend_m / ds_m))
    ext = np.arange(1, m + 1) * ds_m
    table = PathTable(
        s_start_m=float(-m * ds_m),
        ds_m=float(ds_m),
        x_m=np.concatenate([gx[0] - ext[::-1] * np.cos(yaw0), gx, gx[-1] + ext * np.cos(yaw1)]),
        y_m=np.concatenate([gy[0] - ext[::-1] * np.sin(yaw0), gy, gy[-1] + ext * np.sin(yaw1)]),
        yaw_rad=np.concatenate([np.full(m, yaw0), gyaw, np.full(m, yaw1)]),
        length_m=float(grid[-1]),
    )
    s_rec = recorded_arc_length(table, x, y)
    px, py, _ = table.lookup(s_rec)
    dev = float(np.max(np.hypot(x - px, y - py)))
    kmax_built = float(np.max(np.abs(path_curvature(table)))) if grid.size > 2 else 0.0
    info = EgoPathInfo(
        method=method,
        lam=lam,
        kappa_max_per_m=float(kappa_max),
        max_curvature_per_m=kmax_built,
        path_speed_mps=float(path_speed_mps),
        max_lat_accel_mps2=float(max_lat_accel_mps2),
        max_deviation_m=dev,
        initial_yaw_rad=yaw0,
        final_yaw_rad=yaw1,
    )
    return table, info


def recorded_arc_length(path: PathTable, x_m: npt.ArrayLike, y_m: npt.ArrayLike) -> FloatArray:
    """Arc length along ``path`` of recorded positions in time order, never decreasing [m].

    Nearest grid entry of the path (the recorded part and its extensions), refined by one
    local projection step, then made monotone (a vehicle never drives backwards along its
    own path; jitter at standstill stays at one s).

    Args:
        path: the PathTable. x_m, y_m: [M] positions in time order [m].
    Returns:
        [M] arc lengths [m].
    """
    from scipy.spatial import cKDTree

    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    _, idx = cKDTree(np.column_stack([path.x_m, path.y_m])).query(np.column_stack([x, y]))
    s = path.s_start_m + idx * path.ds_m
    i, w = path.index(s)
    px, py, c, sn = path.values_at(i, w, "x", "y", "cos", "sin")
    s = s + (x - px) * c + (y - py) * sn
    return np.maximum.accumulate(s)
