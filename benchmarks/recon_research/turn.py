"""Turn-aware rider smoother: nearly-coordinated-turn model, extended Kalman filter and
extended Rauch-Tung-Striebel smoother.

State s = (x, vx, y, vy, omega): plane position [m], velocity [m/s] and turn rate
[rad/s]. Between steps the rider moves on a circular arc at constant speed and turn rate
(Bar-Shalom, Li & Kirubarajan 2001, sec. 11.7), driven by white acceleration of spectral
density ``accel_psd`` [m^2/s^3] per axis (as the constant-velocity model of
:mod:`vei.recon.kalman`) and a random walk of the turn rate with spectral density
``turn_psd`` [rad^2/s^3]. Keyframes observe the position with noise ``noise_m`` per axis.
With omega = 0 and turn_psd = 0 the model is the constant-velocity model exactly.

The prior on the first state: position at the first keyframe (variance 1e4 m^2),
velocity 0 with variance PRIOR_SPEED_VAR, turn rate 0 with variance PRIOR_TURN_VAR
(weakly informative: a cyclist's speed and turn rate lie well inside these).

Noise (sigma, q, q_omega) is estimated by maximum likelihood of a recording's own keyframes
(EKF innovations likelihood; :func:`estimate_turn_noise`), never of the ground truth.

Status: measured, not adopted. On the shared TrafficMonitoring recordings it lowers the
mean RMSE of ``--interp kalman`` by 6 mm, almost all on one track, and is slightly worse on
the others (docs/reconstruction.md, "Turn-aware motion models"); the reconstruction
pipeline therefore does not use it. It is kept, with its tests, for the comparison that
``python -m benchmarks recon_accuracy`` prints (:mod:`benchmarks.recon_research.turn_compare`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize

FloatArray = npt.NDArray[np.float64]

#: Prior variances of the first state: position [m^2], velocity [m^2/s^2], turn rate
#: [rad^2/s^2].
PRIOR_POS_VAR, PRIOR_SPEED_VAR, PRIOR_TURN_VAR = 1e4, 1e2, 0.25
#: Search box (log-uniform) of the maximum-likelihood estimate: sigma [m], q [m^2/s^3],
#: q_omega [rad^2/s^3].
TURN_BOUNDS: tuple[tuple[float, float], ...] = ((0.02, 3.0), (1e-3, 1e2), (1e-5, 10.0))
_H = np.array([[1.0, 0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0, 0.0]])
_SMALL_OMEGA = 1e-9
#: Passes of the iterated extended smoother (1: the plain extended RTS smoother).
N_ITER = 3


@dataclass(frozen=True)
class TurnNoise:
    """Noise of the coordinated-turn model.

    Attributes:
        noise_m: keyframe position noise, 1 sigma per axis [m].
        accel_psd_m2ps3: white acceleration spectral density per axis [m^2/s^3].
        turn_psd_rad2ps3: turn-rate random-walk spectral density [rad^2/s^3].
        loglik: log-likelihood of the keyframes at the estimate (NaN if not estimated).
    """

    noise_m: float
    accel_psd_m2ps3: float
    turn_psd_rad2ps3: float
    loglik: float = float("nan")

    def __post_init__(self) -> None:
        for name in ("noise_m", "accel_psd_m2ps3"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ValueError(f"TurnNoise.{name} must be finite and > 0, got {v!r}")
        if not (math.isfinite(self.turn_psd_rad2ps3) and self.turn_psd_rad2ps3 >= 0):
            raise ValueError(
                f"TurnNoise.turn_psd_rad2ps3 must be >= 0, got {self.turn_psd_rad2ps3}"
            )


def _sin_cos_terms(w: float, dt: float) -> tuple[float, float, float, float]:
    """sin(w dt)/w, (1 - cos(w dt))/w (as 2 sin^2(w dt / 2)/w: no cancellation), cos(w dt),
    sin(w dt); the limits w -> 0 below _SMALL_OMEGA."""
    wt = w * dt
    if abs(w) < _SMALL_OMEGA:
        return dt - w**2 * dt**3 / 6.0, w * dt**2 / 2.0, math.cos(wt), math.sin(wt)
    return math.sin(wt) / w, 2.0 * math.sin(0.5 * wt) ** 2 / w, math.cos(wt), math.sin(wt)


def propagate(s: FloatArray, dt_s: float) -> FloatArray:
    """Mean motion over dt_s: the state [5] after an arc at constant speed and turn rate."""
    x, vx, y, vy, w = s
    a, b, c, sn = _sin_cos_terms(w, dt_s)
    return np.array(
        [x + a * vx - b * vy, c * vx - sn * vy, y + b * vx + a * vy, sn * vx + c * vy, w]
    )


def jacobian(s: FloatArray, dt_s: float) -> FloatArray:
    """d propagate / d s [5, 5] (closed form; series in omega near 0)."""
    _, vx, _, vy, w = s
    a, b, c, sn = _sin_cos_terms(w, dt_s)
    t = dt_s
    if abs(w) < 1e-4:
        da = -w * t**3 / 3.0
        db = t**2 / 2.0 - w**2 * t**4 / 8.0
    else:
        da = t * c / w - sn / w**2
        db = t * sn / w - (1.0 - c) / w**2
    dc, dsn = -t * sn, t * c
    return np.array(
        [
            [1.0, a, 0.0, -b, da * vx - db * vy],
            [0.0, c, 0.0, -sn, dc * vx - dsn * vy],
            [0.0, b, 1.0, a, db * vx + da * vy],
            [0.0, sn, 0.0, c, dsn * vx + dc * vy],
            [0.0, 0.0, 0.0, 0.0, 1.0],
        ]
    )


def process_cov(dt_s: float, accel_psd: float, turn_psd: float) -> FloatArray:
    """Process covariance [5, 5]: white acceleration per axis (integrated Wiener blocks on
    (x, vx) and (y, vy)) and a turn-rate random walk."""
    q = np.zeros((5, 5))
    blk = accel_psd * np.array([[dt_s**3 / 3.0, dt_s**2 / 2.0], [dt_s**2 / 2.0, dt_s]])
    q[0:2, 0:2] = blk
    q[2:4, 2:4] = blk
    q[4, 4] = turn_psd * dt_s
    return q


@dataclass(frozen=True)
class TurnSmoothed:
    """Smoothed states of one track at its step times.

    Attributes:
        t_s: [T] times [s]; mean: [T, 5] (x, vx, y, vy, omega); cov: [T, 5, 5].
        loglik: log-likelihood of the keyframes (EKF innovations).
    """

    t_s: FloatArray
    mean: FloatArray
    cov: FloatArray
    loglik: float

    @property
    def xy_m(self) -> FloatArray:
        """[T, 2] smoothed positions [m]."""
        return self.mean[:, [0, 2]]

    @property
    def vel_mps(self) -> FloatArray:
        """[T, 2] smoothed velocities [m/s]."""
        return self.mean[:, [1, 3]]

    @property
    def std_m(self) -> FloatArray:
        """[T] per-axis position standard deviation [m] (root of the mean of the x and y
        variances, as :class:`vei.recon.smoother.Posterior`)."""
        return np.sqrt(0.5 * (self.cov[:, 0, 0] + self.cov[:, 2, 2]))


def _steps(
    t_key_s: FloatArray, xy_key_m: FloatArray, t_query_s: FloatArray | None
) -> tuple[FloatArray, FloatArray, npt.NDArray[np.bool_], npt.NDArray[np.intp]]:
    """Union of keyframe and query times: times [T], observations [T, 2], mask [T] and the
    index of each query time in the union."""
    tq = np.zeros(0) if t_query_s is None else np.asarray(t_query_s, np.float64)
    t_all = np.unique(np.concatenate([t_key_s, tq]))
    obs = np.full((t_all.size, 2), np.nan)
    mask = np.zeros(t_all.size, bool)
    ik = np.searchsorted(t_all, t_key_s)
    obs[ik] = xy_key_m
    mask[ik] = True
    return t_all, obs, mask, np.searchsorted(t_all, tq)


def smooth_turn(
    t_key_s: npt.ArrayLike,
    xy_key_m: npt.ArrayLike,
    noise: TurnNoise,
    t_query_s: npt.ArrayLike | None = None,
    smooth: bool = True,
    n_iter: int = N_ITER,
) -> TurnSmoothed:
    """Iterated extended Kalman filter + RTS smoother of one track.

    The first pass linearises the motion at the filter's own estimates (extended Kalman
    filter); each further pass linearises it at the previous pass's smoothed path (the
    iterated extended smoother, a Gauss-Newton step on the whole path's posterior mode),
    which matters at 1 Hz, where one step turns the rider by up to a radian.

    Args:
        t_key_s: [K] strictly increasing keyframe times [s].
        xy_key_m: [K, 2] keyframe positions [m].
        noise: the model's noise.
        t_query_s: [N] times [s] inside the keyframe span at which to report the state
            (None: the keyframe times).
        smooth: False returns the filtered states of one pass (n_iter ignored).
        n_iter: passes (>= 1).
    Returns:
        TurnSmoothed at the query times (or the keyframe times).
    """
    tk = np.asarray(t_key_s, np.float64)
    yk = np.asarray(xy_key_m, np.float64)
    t, obs, mask, iq = _steps(tk, yk, None if t_query_s is None else np.asarray(t_query_s))
    ref = None
    for _ in range(max(1, n_iter) if smooth else 1):
        ms, ps, loglik = _pass(t, obs, mask, yk[0], noise, ref, smooth)
        ref = ms
    sel = np.flatnonzero(mask) if t_query_s is None else iq
    return TurnSmoothed(t[sel], ms[sel], ps[sel], float(loglik))


def _pass(
    t: FloatArray,
    obs: FloatArray,
    mask: npt.NDArray[np.bool_],
    start_xy: FloatArray,
    noise: TurnNoise,
    ref: FloatArray | None,
    smooth: bool,
) -> tuple[FloatArray, FloatArray, float]:
    """One filter (+ smoother) pass, the motion linearised at ``ref`` [T, 5] (None: at the
    filtered estimates). Returns (means [T, 5], covariances [T, 5, 5], loglik)."""
    n = t.size
    yk0 = start_xy
    r = noise.noise_m**2 * np.eye(2)
    m = np.array([yk0[0], 0.0, yk0[1], 0.0, 0.0])
    p = np.diag([PRIOR_POS_VAR, PRIOR_SPEED_VAR, PRIOR_POS_VAR, PRIOR_SPEED_VAR, PRIOR_TURN_VAR])
    mf = np.zeros((n, 5))
    pf = np.zeros((n, 5, 5))
    mp = np.zeros((n, 5))
    pp = np.zeros((n, 5, 5))
    jac = np.zeros((n, 5, 5))
    loglik = 0.0
    for i in range(n):
        if i > 0:
            dt = t[i] - t[i - 1]
            if ref is None:
                f = jacobian(m, dt)
                m = propagate(m, dt)
            else:
                f = jacobian(ref[i - 1], dt)
                m = propagate(ref[i - 1], dt) + f @ (m - ref[i - 1])
            p = f @ p @ f.T + process_cov(dt, noise.accel_psd_m2ps3, noise.turn_psd_rad2ps3)
            jac[i] = f
        mp[i], pp[i] = m, p
        if mask[i]:
            ph = p[:, [0, 2]]  # P H^T
            s = ph[[0, 2], :] + r
            det = s[0, 0] * s[1, 1] - s[0, 1] * s[1, 0]
            sinv = np.array([[s[1, 1], -s[0, 1]], [-s[1, 0], s[0, 0]]]) / det
            e = obs[i] - m[[0, 2]]
            g = ph @ sinv
            m = m + g @ e
            ikh = np.eye(5) - g @ _H
            p = ikh @ p @ ikh.T + g @ r @ g.T
            loglik += -0.5 * (2.0 * math.log(2.0 * math.pi) + math.log(det) + e @ sinv @ e)
        mf[i], pf[i] = m, p
    if smooth:
        ms, ps = mf.copy(), pf.copy()
        for i in range(n - 2, -1, -1):
            g = np.linalg.solve(pp[i + 1].T, (pf[i] @ jac[i + 1].T).T).T
            ms[i] = mf[i] + g @ (ms[i + 1] - mp[i + 1])
            pi = pf[i] + g @ (ps[i + 1] - pp[i + 1]) @ g.T
            ps[i] = 0.5 * (pi + pi.T)
    else:
        ms, ps = mf, pf
    return ms, ps, loglik


def turn_loglik(tracks: list[tuple[FloatArray, FloatArray]], noise: TurnNoise) -> float:
    """Sum of the keyframe log-likelihoods of ``tracks`` [(t [K], xy [K, 2])] (K >= 3):
    the innovations likelihood of the filter linearised at the first pass's smoothed path
    (two passes; :func:`smooth_turn`)."""
    return sum(smooth_turn(t, xy, noise, n_iter=2).loglik for t, xy in tracks)


def estimate_turn_noise(
    tracks: list[tuple[FloatArray, FloatArray]], min_keyframes: int = 3
) -> TurnNoise:
    """Maximum-likelihood (sigma, q, q_omega) over the tracks' keyframes (tracks with at
    least ``min_keyframes``), Nelder-Mead in log space inside TURN_BOUNDS.

    Args:
        tracks: [(t_s [K], xy_m [K, 2])] of one (or several) recordings.
    Returns:
        TurnNoise at the maximum (loglik set).
    """
    use = [
        (np.asarray(t, float), np.asarray(y, float)) for t, y in tracks if len(t) >= min_keyframes
    ]
    if not use:
        raise ValueError("estimate_turn_noise: no track with enough keyframes")
    lo = np.log([b[0] for b in TURN_BOUNDS])
    hi = np.log([b[1] for b in TURN_BOUNDS])

    def nll(z: FloatArray) -> float:
        zc = np.clip(z, lo, hi)
        e = np.exp(zc)
        val = -turn_loglik(use, TurnNoise(e[0], e[1], e[2]))
        return val + 1e3 * float(np.sum((z - zc) ** 2))

    best = None
    for start in (np.log([0.2, 0.5, 0.01]), np.log([0.5, 2.0, 0.1])):
        res = minimize(
            nll, start, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-4, "maxiter": 600}
        )
        if best is None or res.fun < best.fun:
            best = res
    e = np.exp(np.clip(best.x, lo, hi))
    return TurnNoise(float(e[0]), float(e[1]), float(e[2]), float(-best.fun))
