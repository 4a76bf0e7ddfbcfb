"""Interpolation of sparse keyframes to the simulation rate: positions and yaw.

Positions (plane x, y [m]) are interpolated per track with one of :data:`INTERP_METHODS`:

* ``'linear'``: piecewise linear between keyframes (speed is piecewise constant).
* ``'cubic'``: the paper's cubic spline through every keyframe (scipy ``CubicSpline``,
  not-a-knot ends). It passes exactly through the (noisy) keyframes.
* ``'kalman'`` (probabilistic): the Rauch-Tung-Striebel smoother of the same constant-velocity
  model (:mod:`vei.recon.smoother`): its mean is the smoothing spline of ``'smoothing'`` for the
  same (sigma, q), and it also gives the position's posterior standard deviation
  (``std(t)``) and samples. The reconstruction estimates (sigma, q) per recording by
  maximum likelihood over its keyframes. It needs no splitting at long gaps: the posterior
  bridges a gap and its uncertainty grows there. With fewer than 2 keyframes: one point.
* ``'smoothing'`` (noise-aware): a cubic smoothing spline (Reinsch's algorithm, the same
  estimate as scipy ``make_smoothing_spline`` but for any K >= 3 keyframes) that minimises ``sum |p_i - f(t_i)|^2 / sigma^2 + (1/q) int |f''(t)|^2 dt``, i.e. ``lam =
  sigma^2 / q``. This is the posterior mean of a constant-velocity motion model driven by
  white acceleration noise of spectral density ``q`` [m^2/s^3] observed with position noise
  of standard deviation ``sigma`` [m] (Wahba 1978; the same estimate a Rauch-Tung-Striebel
  smoother of that model gives). ``sigma`` is the annotation noise (camera tracks jitter by
  decimetres) and ``q`` how hard a rider manoeuvres. If the result still exceeds the
  plausibility limits for a rider (:class:`KinematicLimits`), ``lam`` is raised by a factor
  of 4 at a time (at most ``max_refits`` times), which only ever makes the path smoother.

Short tracks never extrapolate wildly: with fewer keyframes than a method needs (cubic: 4,
smoothing: 3) the track falls back to linear; with one keyframe it is a single point.
Interpolants are only defined on ``[t_first, t_last]`` of their keyframes; evaluating
outside raises ValueError (no extrapolation).

Yaw is interpolated by SLERP (scipy ``Slerp``) of rotations about z: the shortest arc,
correct across the +-pi wrap (179 deg -> -179 deg passes through 180 deg, not 0).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.interpolate import CubicSpline
from scipy.linalg import solveh_banded
from scipy.spatial.transform import Rotation, Slerp

from vei.recon.smoother import KalmanInterpolant, NoiseEstimate

FloatArray = npt.NDArray[np.float64]

#: Position interpolation methods accepted by the reconstruction.
INTERP_METHODS: tuple[str, ...] = ("cubic", "linear", "smoothing", "kalman")
#: Fewest keyframes each method needs; shorter tracks fall back to linear.
MIN_KEYFRAMES: dict[str, int] = {"linear": 2, "cubic": 4, "smoothing": 3, "kalman": 2}
#: Tolerance on the interpolant's time span [s] (float rounding of grid times).
_T_TOL_S = 1e-6


@dataclass(frozen=True)
class KinematicLimits:
    """Plausibility limits for a rider (e-scooter or cyclist) used by ``'smoothing'``.

    Defaults: 12 m/s (43 km/h, a fast cyclist; e-scooters are limited to 20-25 km/h) and
    4 m/s^2 (hard braking of a bicycle is 3-5 m/s^2; everyday accelerations are < 2 m/s^2).

    Attributes:
        max_speed_mps: highest plausible speed [m/s].
        max_accel_mps2: highest plausible magnitude of the acceleration vector [m/s^2].
    """

    max_speed_mps: float = 12.0
    max_accel_mps2: float = 4.0


@dataclass(frozen=True)
class SmoothingParams:
    """Noise model of the ``'smoothing'`` method.

    Attributes:
        noise_m: standard deviation of the keyframe position noise per axis [m].
        accel_psd_m2ps3: spectral density q of the rider's white acceleration [m^2/s^3];
            lam = noise_m^2 / accel_psd_m2ps3.
        limits: plausibility limits; lam grows x4 while they are exceeded.
        max_refits: at most this many lam increases.
    """

    noise_m: float = 0.25
    accel_psd_m2ps3: float = 1.0
    limits: KinematicLimits = KinematicLimits()
    max_refits: int = 6

    @property
    def lam(self) -> float:
        """Regularisation lam = sigma^2 / q [s^3] of make_smoothing_spline (unit weights)."""
        return self.noise_m**2 / self.accel_psd_m2ps3


class TrackInterpolant:
    """Continuous position of one track on ``[t_start_s, t_end_s]``.

    Attributes:
        method: the method actually used (after any fallback to linear).
        t_start_s, t_end_s: span of the keyframes [s].
        lam: regularisation used by 'smoothing' (None otherwise).
    """

    def __init__(self, method: str, t_key_s: FloatArray, xy_key_m: FloatArray, curve, lam=None):
        self.method = method
        self.t_key_s = t_key_s
        self.xy_key_m = xy_key_m
        self.t_start_s = float(t_key_s[0])
        self.t_end_s = float(t_key_s[-1])
        self._curve = curve
        self.lam = lam

    def _check(self, t_s: npt.ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=np.float64)
        if t.size and (t.min() < self.t_start_s - _T_TOL_S or t.max() > self.t_end_s + _T_TOL_S):
            raise ValueError(
                f"times outside the keyframe span [{self.t_start_s}, {self.t_end_s}] s: "
                "interpolants never extrapolate"
            )
        return np.clip(t, self.t_start_s, self.t_end_s)

    def position(self, t_s: npt.ArrayLike) -> FloatArray:
        """Positions [N, 2] (x, y [m]) at times t_s [N] within the span."""
        t = self._check(t_s)
        if self._curve is None:  # single keyframe / linear
            return _linear(self.t_key_s, self.xy_key_m, t)
        return np.asarray(self._curve(t), dtype=np.float64).reshape(-1, 2)

    def velocity(self, t_s: npt.ArrayLike) -> FloatArray:
        """Velocity [N, 2] (m/s) at t_s [N]; linear: the segment's slope (right-continuous)."""
        t = self._check(t_s)
        if self._curve is None:
            return _linear_slope(self.t_key_s, self.xy_key_m, t)
        return np.asarray(self._curve(t, 1), dtype=np.float64).reshape(-1, 2)

    def acceleration(self, t_s: npt.ArrayLike) -> FloatArray:
        """Acceleration [N, 2] (m/s^2); zero inside linear segments (kinks are impulses)."""
        t = self._check(t_s)
        if self._curve is None:
            return np.zeros((t.size, 2))
        return np.asarray(self._curve(t, 2), dtype=np.float64).reshape(-1, 2)


def _linear(t_key: FloatArray, xy_key: FloatArray, t: FloatArray) -> FloatArray:
    if t_key.size == 1:
        return np.repeat(xy_key[:1], t.size, axis=0)
    return np.column_stack([np.interp(t, t_key, xy_key[:, 0]), np.interp(t, t_key, xy_key[:, 1])])


def _linear_slope(t_key: FloatArray, xy_key: FloatArray, t: FloatArray) -> FloatArray:
    if t_key.size == 1:
        return np.zeros((t.size, 2))
    slopes = np.diff(xy_key, axis=0) / np.diff(t_key)[:, None]
    seg = np.clip(np.searchsorted(t_key, t, side="right") - 1, 0, t_key.size - 2)
    return slopes[seg]


def fit_track(
    t_key_s: npt.ArrayLike,
    xy_key_m: npt.ArrayLike,
    method: str = "cubic",
    smoothing: SmoothingParams | None = None,
    noise: NoiseEstimate | None = None,
) -> TrackInterpolant | KalmanInterpolant:
    """Fit a position interpolant through one track's keyframes.

    Args:
        t_key_s: [K] keyframe times [s], strictly increasing.
        xy_key_m: [K, 2] keyframe positions (plane x, y [m]).
        method: one of INTERP_METHODS.
        smoothing: noise model for 'smoothing' and 'kalman' (defaults to SmoothingParams()).
        noise: 'kalman' only: the (estimated) noise, overriding ``smoothing``'s.
    Returns:
        TrackInterpolant on [t_key_s[0], t_key_s[-1]]; ``method`` says what was used
        (tracks with fewer than MIN_KEYFRAMES[method] keyframes fall back to 'linear').
    """
    if method not in INTERP_METHODS:
        raise ValueError(f"unknown interpolation {method!r}; expected one of {INTERP_METHODS}")
    t = np.asarray(t_key_s, dtype=np.float64).ravel()
    xy = np.asarray(xy_key_m, dtype=np.float64).reshape(-1, 2)
    if t.size == 0 or t.size != xy.shape[0]:
        raise ValueError(f"need >= 1 keyframe with matching shapes, got t {t.shape}, xy {xy.shape}")
    if t.size > 1 and np.any(np.diff(t) <= 0):
        raise ValueError("keyframe times must be strictly increasing")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(xy))):
        raise ValueError("keyframes must be finite")
    if t.size < MIN_KEYFRAMES[method]:
        return TrackInterpolant("linear", t, xy, None)
    if method == "linear":
        return TrackInterpolant("linear", t, xy, None)
    if method == "kalman":
        if noise is None:
            p = smoothing or SmoothingParams()
            noise = NoiseEstimate(p.noise_m, p.accel_psd_m2ps3)
        return KalmanInterpolant(t, xy, noise)
    if method == "cubic":
        return TrackInterpolant("cubic", t, xy, CubicSpline(t, xy, axis=0, bc_type="not-a-knot"))
    params = smoothing or SmoothingParams()
    lam = params.lam
    curve = _smooth(t, xy, lam)
    dense = np.linspace(t[0], t[-1], max(int((t[-1] - t[0]) * 20.0) + 1, 2))
    for _ in range(params.max_refits):
        speed = np.linalg.norm(curve(dense, 1), axis=1).max()
        accel = np.linalg.norm(curve(dense, 2), axis=1).max()
        if speed <= params.limits.max_speed_mps and accel <= params.limits.max_accel_mps2:
            break
        lam *= 4.0
        curve = _smooth(t, xy, lam)
    return TrackInterpolant("smoothing", t, xy, curve, lam=lam)


def _smooth(t: FloatArray, xy: FloatArray, lam: float) -> CubicSpline:
    """Cubic smoothing spline (Reinsch algorithm) for any K >= 3 keyframes.

    Minimises ``sum |xy_i - f(t_i)|^2 + lam * int |f''|^2`` (scipy's make_smoothing_spline
    with unit weights, which needs K >= 5). With h_i = t_{i+1} - t_i, Q [K, K-2] and
    R [K-2, K-2] of Green & Silverman (1994, Sec. 2.3): (R + lam Q^T Q) gamma = Q^T y,
    fitted values g = y - lam Q gamma, and f is the natural cubic spline through (t, g).
    Q is tridiagonal by columns and R tridiagonal, so R + lam Q^T Q is a symmetric
    positive definite band of half-width 2: solved in O(K) time and memory
    (scipy solveh_banded), so a track of 10^4 dense keyframes takes milliseconds.

    Args:
        t: [K] strictly increasing times [s]; xy: [K, 2] positions [m]; lam: >= 0 [s^3].
    Returns:
        CubicSpline (natural ends) of the fitted curve.
    """
    h = np.diff(t)
    # Column j of Q holds (a_j, b_j, c_j) in rows j, j+1, j+2.
    a = 1.0 / h[:-1]
    c = 1.0 / h[1:]
    b = -a - c
    m = a.size  # K - 2
    ab = np.zeros((3, m))  # upper band form: ab[2 + i - j, j] = A[i, j]
    ab[2] = (h[:-1] + h[1:]) / 3.0 + lam * (a * a + b * b + c * c)
    ab[1, 1:] = h[1:-1] / 6.0 + lam * (b[:-1] * a[1:] + c[:-1] * b[1:])
    ab[0, 2:] = lam * (c[:-2] * a[2:])
    rhs = a[:, None] * xy[:-2] + b[:, None] * xy[1:-1] + c[:, None] * xy[2:]
    gamma = solveh_banded(ab, rhs)
    q_gamma = np.zeros_like(xy)
    q_gamma[:-2] += a[:, None] * gamma
    q_gamma[1:-1] += b[:, None] * gamma
    q_gamma[2:] += c[:, None] * gamma
    fitted = xy - lam * q_gamma
    return CubicSpline(t, fitted, axis=0, bc_type="natural")


def slerp_yaw(t_key_s: npt.ArrayLike, yaw_key_rad: npt.ArrayLike, t_s: npt.ArrayLike) -> FloatArray:
    """SLERP of yaw angles (rotations about z) between keyframes.

    Args:
        t_key_s: [K] keyframe times [s], strictly increasing.
        yaw_key_rad: [K] yaw [rad], any branch.
        t_s: [N] query times within [t_key_s[0], t_key_s[-1]].
    Returns:
        [N] yaw [rad] in (-pi, pi], along the shorter arc between neighbouring keyframes.
    """
    tk = np.asarray(t_key_s, dtype=np.float64).ravel()
    yk = np.asarray(yaw_key_rad, dtype=np.float64).ravel()
    t = np.asarray(t_s, dtype=np.float64).ravel()
    if tk.size == 1:
        return np.full(t.size, float(np.arctan2(np.sin(yk[0]), np.cos(yk[0]))))
    t = np.clip(t, tk[0], tk[-1])
    slerp = Slerp(tk, Rotation.from_euler("z", yk[:, None]))
    rv = slerp(t).as_rotvec()  # rotations about z: (0, 0, angle), angle in [-pi, pi]
    yaw = rv[:, 2]
    return np.where(yaw <= -np.pi, yaw + 2 * np.pi, yaw)


def time_grid(t_start_s: float, t_end_s: float, rate_hz: float) -> FloatArray:
    """Grid times k / rate_hz [s] inside [t_start_s, t_end_s] (no extrapolation), [N]."""
    k0 = int(np.ceil(t_start_s * rate_hz - 1e-6))
    k1 = int(np.floor(t_end_s * rate_hz + 1e-6))
    if k1 < k0:
        return np.zeros(0)
    return np.arange(k0, k1 + 1, dtype=np.float64) / rate_hz


class SegmentedInterpolant:
    """A track split at long gaps: each segment interpolated on its own, gaps bridged linearly.

    A gap longer than ``max_gap_s`` between two keyframes (a lost track, an occlusion) is
    not trusted to a spline, which would swing through it; the segments on either side are
    fitted separately and the gap is bridged by a cubic Hermite curve that matches their
    end positions and velocities (``hermite=True``, no kink, so no acceleration spike), or
    by a straight line (``hermite=False``, the 'linear' method). Same
    interface as :class:`TrackInterpolant` (position, velocity, acceleration on
    [t_start_s, t_end_s]).

    Attributes:
        segments: the fitted segments in time order.
        method: the requested method, or 'linear' if every segment fell back to it.
    """

    def __init__(self, segments: list[TrackInterpolant], hermite: bool = True):
        self.segments = segments
        self.hermite = hermite
        self.t_start_s = segments[0].t_start_s
        self.t_end_s = segments[-1].t_end_s
        used = {s.method for s in segments}
        self.method = next(iter(used)) if len(used) == 1 else "+".join(sorted(used))
        lams = [s.lam for s in segments if s.lam is not None]
        self.lam = max(lams) if lams else None
        self._starts = np.array([s.t_start_s for s in segments])
        self._ends = np.array([s.t_end_s for s in segments])

    def _eval(self, t_s: npt.ArrayLike, which: int) -> FloatArray:
        t = np.asarray(t_s, dtype=np.float64).ravel()
        if t.size and (t.min() < self.t_start_s - _T_TOL_S or t.max() > self.t_end_s + _T_TOL_S):
            raise ValueError(
                f"times outside the keyframe span [{self.t_start_s}, {self.t_end_s}] s: "
                "interpolants never extrapolate"
            )
        t = np.clip(t, self.t_start_s, self.t_end_s)
        out = np.zeros((t.size, 2))
        seg = np.clip(np.searchsorted(self._starts, t, side="right") - 1, 0, len(self.segments) - 1)
        for i, s in enumerate(self.segments):
            m = (seg == i) & (t <= self._ends[i] + _T_TOL_S)
            if m.any():
                f = (s.position, s.velocity, s.acceleration)[which]
                out[m] = f(np.minimum(t[m], s.t_end_s))
            gap = (seg == i) & (t > self._ends[i] + _T_TOL_S)
            if gap.any():  # bridge to the next segment
                out[gap] = self._bridge(i, t[gap], which)
        return out

    def _chord(self, i: int) -> FloatArray:
        """Mean velocity [2] (m/s) across the gap after segment i."""
        s, nxt = self.segments[i], self.segments[i + 1]
        p0 = s.position([s.t_end_s])[0]
        p1 = nxt.position([nxt.t_start_s])[0]
        return (p1 - p0) / (nxt.t_start_s - s.t_end_s)

    def _end_velocity(self, i: int, at_end: bool) -> FloatArray:
        """Velocity [2] of segment i at its end (or start); a single-keyframe segment has
        none of its own and takes the mean of the chords of the gaps beside it."""
        s = self.segments[i]
        if s.t_key_s.size > 1:
            return s.velocity([s.t_end_s if at_end else s.t_start_s])[0]
        chords = [self._chord(j) for j in (i - 1, i) if 0 <= j < len(self.segments) - 1]
        return np.mean(chords, axis=0)

    def _bridge(self, i: int, t: FloatArray, which: int) -> FloatArray:
        """Gap after segment i: cubic Hermite matching position and velocity at both ends
        (C1, no kink) when ``hermite``, else a straight line."""
        s, nxt = self.segments[i], self.segments[i + 1]
        p0 = s.position([s.t_end_s])[0]
        p1 = nxt.position([nxt.t_start_s])[0]
        dt = nxt.t_start_s - s.t_end_s
        chord = (p1 - p0) / dt
        if not self.hermite:
            v0 = v1 = chord
        else:
            v0 = self._end_velocity(i, at_end=True)
            v1 = self._end_velocity(i + 1, at_end=False)
        u = ((t - s.t_end_s) / dt)[:, None]
        if which == 0:
            h00 = 2 * u**3 - 3 * u**2 + 1
            h10 = u**3 - 2 * u**2 + u
            h01 = -2 * u**3 + 3 * u**2
            h11 = u**3 - u**2
            return h00 * p0 + h10 * dt * v0 + h01 * p1 + h11 * dt * v1
        if which == 1:
            d00 = (6 * u**2 - 6 * u) / dt
            d10 = 3 * u**2 - 4 * u + 1
            d01 = (-6 * u**2 + 6 * u) / dt
            d11 = 3 * u**2 - 2 * u
            return d00 * p0 + d10 * v0 + d01 * p1 + d11 * v1
        a00 = (12 * u - 6) / dt**2
        a10 = (6 * u - 4) / dt
        a01 = (-12 * u + 6) / dt**2
        a11 = (6 * u - 2) / dt
        return a00 * p0 + a10 * v0 + a01 * p1 + a11 * v1

    def position(self, t_s: npt.ArrayLike) -> FloatArray:
        """Positions [N, 2] (m) at t_s [N] within the span."""
        return self._eval(t_s, 0)

    def velocity(self, t_s: npt.ArrayLike) -> FloatArray:
        """Velocity [N, 2] (m/s) at t_s [N]."""
        return self._eval(t_s, 1)

    def acceleration(self, t_s: npt.ArrayLike) -> FloatArray:
        """Acceleration [N, 2] (m/s^2) at t_s [N]."""
        return self._eval(t_s, 2)


def fit_track_segmented(
    t_key_s: npt.ArrayLike,
    xy_key_m: npt.ArrayLike,
    method: str = "cubic",
    smoothing: SmoothingParams | None = None,
    max_gap_s: float = 3.0,
    noise: NoiseEstimate | None = None,
) -> TrackInterpolant | SegmentedInterpolant | KalmanInterpolant:
    """:func:`fit_track` on each run of keyframes separated by gaps <= max_gap_s [s].

    Args:
        t_key_s: [K] strictly increasing times [s]; xy_key_m: [K, 2] positions [m].
        method, smoothing, noise: as :func:`fit_track`.
        max_gap_s: a longer time between consecutive keyframes splits the track
            ('kalman' is never split: its posterior bridges gaps).
    Returns:
        A TrackInterpolant when there is no long gap, else a SegmentedInterpolant
        ('kalman': a KalmanInterpolant).
    """
    t = np.asarray(t_key_s, dtype=np.float64).ravel()
    xy = np.asarray(xy_key_m, dtype=np.float64).reshape(-1, 2)
    if method == "kalman":
        return fit_track(t, xy, method, smoothing, noise)
    cuts = np.flatnonzero(np.diff(t) > max_gap_s) + 1 if t.size > 1 else np.zeros(0, dtype=int)
    if cuts.size == 0:
        return fit_track(t, xy, method, smoothing)
    bounds = np.concatenate([[0], cuts, [t.size]])
    segs = [
        fit_track(t[a:b], xy[a:b], method, smoothing)
        for a, b in zip(bounds[:-1], bounds[1:], strict=True)
    ]
    return SegmentedInterpolant(segs, hermite=method != "linear")
