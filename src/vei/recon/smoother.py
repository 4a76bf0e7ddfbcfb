"""Track-level use of the Kalman / RTS smoother (:mod:`vei.recon.kalman`): posteriors of
riders at any times, maximum-likelihood noise estimation over a recording, the ego path.

Riders (``order=2``, constant velocity + white acceleration, position keyframes):

* :func:`estimate_noise` finds the keyframe noise sigma [m] and the acceleration spectral
  density q [m^2/s^3] that maximise the likelihood of a recording's own keyframes (all its
  tracks with >= 3 keyframes together; the exact diffuse-prior Gaussian likelihood of
  :class:`RestrictedLikelihood`, equal to the Kalman filter's). Nothing else enters: no
  ground truth.
* :func:`posterior` gives the smoothed mean position, velocity and the per-axis position
  standard deviation at any times inside a track's keyframe span, and
  :class:`KalmanInterpolant` wraps it in the interface of :mod:`vei.recon.interpolate`.

The ego (``order=3``, white jerk; GPS positions and INS velocity = speed along the
heading): :func:`smooth_ego` with the three noise levels estimated the same way on the
ego's own fixes.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np
import numpy.typing as npt
from scipy.optimize import minimize

from vei.recon import kalman
from vei.recon.calibration import POSTERIOR_STD_INFLATION

FloatArray = npt.NDArray[np.float64]

#: Search box of the maximum-likelihood estimate: sigma [m], q [m^2/s^3].
NOISE_BOUNDS_M: tuple[float, float] = (0.02, 3.0)
PSD_BOUNDS: tuple[float, float] = (1e-3, 1e2)
#: Tracks need this many keyframes to inform the noise estimate.
MIN_KEYFRAMES_FOR_ESTIMATE = 3
_H_POS2 = np.array([[1.0, 0.0]])


@dataclass(frozen=True)
class NoiseEstimate:
    """Noise of the rider motion model for one recording.

    Attributes:
        noise_m: keyframe position noise, 1 sigma per axis [m].
        accel_psd_m2ps3: spectral density q of the white acceleration [m^2/s^3].
        method: 'ml' (maximum likelihood on the keyframes) or 'fixed' (given / too few
            keyframes to estimate).
        loglik: log-likelihood of the keyframes at the estimate (NaN for 'fixed').
        n_tracks, n_keyframes: what the estimate saw.
        std_inflation: factor (>= 1 in practice) on the model's posterior standard
            deviation (and on the spread of posterior samples) that calibrates the 95 %
            region against real ground truth (:mod:`vei.recon.calibration`); 1.0 = the
            pure model. :func:`estimate_noise` sets POSTERIOR_STD_INFLATION.
    """

    noise_m: float
    accel_psd_m2ps3: float
    method: str = "fixed"
    loglik: float = float("nan")
    n_tracks: int = 0
    n_keyframes: int = 0
    std_inflation: float = 1.0

    def __post_init__(self) -> None:
        for name in ("noise_m", "accel_psd_m2ps3", "std_inflation"):
            v = getattr(self, name)
            if not (isinstance(v, int | float) and math.isfinite(v) and v > 0):
                raise ValueError(f"NoiseEstimate.{name} must be a finite number > 0, got {v!r}")

    def as_dict(self) -> dict:
        """Plain dict (JSON; NaN -> None)."""
        d = asdict(self)
        return {
            k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()
        }


def _rider_batch(
    tracks: list[tuple[FloatArray, FloatArray]], queries: list[FloatArray] | None
) -> tuple[kalman.Batch, list[FloatArray]]:
    """Batch of position-only tracks over keyframe times united with query times."""
    times, obs, masks = [], [], []
    for i, (tk, xyk) in enumerate(tracks):
        t = tk if queries is None else np.union1d(tk, queries[i])
        idx = np.searchsorted(t, tk)
        y = np.full((t.size, 1, 2), np.nan)
        y[idx, 0, :] = xyk
        mk = np.zeros(t.size, dtype=bool)
        mk[idx] = True
        times.append(t)
        obs.append(y)
        masks.append(mk)
    return kalman.make_batch(times, obs, masks), times


def track_loglik(
    tracks: list[tuple[FloatArray, FloatArray]], noise_m: float, accel_psd_m2ps3: float
) -> float:
    """Log-likelihood of keyframes under the rider model.

    Args:
        tracks: per track (t_key [K] s, xy_key [K, 2] m).
        noise_m: keyframe noise sigma [m]; accel_psd_m2ps3: q [m^2/s^3].
    Returns:
        The summed Gaussian log-likelihood of every keyframe (both axes).
    """
    batch, _ = _rider_batch(tracks, None)
    return float(_loglik(batch, noise_m, accel_psd_m2ps3).sum())


def _loglik(batch: kalman.Batch, noise_m: float, psd: float) -> FloatArray:
    b = batch.t_s.shape[0]
    r = np.full((b, 1, 1), noise_m**2)
    res = kalman.kalman_filter(batch, _H_POS2, r, np.full(b, psd), order=2)
    return res.loglik


class RestrictedLikelihood:
    """Exact diffuse (restricted) log-likelihood of the rider model, O(K) per evaluation.

    Per axis, keyframes y = a + b t + x(t) + e with an unknown (diffuse) start position a
    and velocity b, x the integrated Wiener process of density q (Cov x(s), x(t) =
    q min^2 (3 max - min) / 6 for s, t from the first keyframe) and e ~ N(0, sigma^2). The
    part of y orthogonal to the trend [1, t] (orthonormal basis N) is N(0, q A + sigma^2 I)
    with A = N^T C N; with A = U diag(lam) U^T once per track, the log-likelihood is
    -1/2 sum_i [log(2 pi (q lam_i + sigma^2)) + z_i^2 / (q lam_i + sigma^2)], z = U^T N^T y,
    summed over both axes and all tracks. This is the likelihood the Kalman filter gives
    with a diffuse prior (de Jong 1991), without its O(K) sequential steps per evaluation.

    Args:
        tracks: per track (t_key [K] s, xy_key [K, 2] m); tracks with < 3 keyframes carry
            no information on the noise and are skipped.
    """

    def __init__(self, tracks: list[tuple[FloatArray, FloatArray]]) -> None:
        lams, zs = [], []
        for t, xy in tracks:
            t = np.asarray(t, float) - float(t[0])
            if t.size < MIN_KEYFRAMES_FOR_ESTIMATE:
                continue
            lo = np.minimum.outer(t, t)
            hi = np.maximum.outer(t, t)
            c = lo**2 * (3.0 * hi - lo) / 6.0
            scale = max(float(t[-1]), 1e-9)
            trend = np.column_stack([np.ones_like(t), t / scale])
            q_full, _ = np.linalg.qr(trend, mode="complete")
            n = q_full[:, 2:]
            lam, u = np.linalg.eigh(n.T @ c @ n)
            lams.append(np.clip(lam, 0.0, None))
            zs.append((n @ u).T @ np.asarray(xy, float))
        self.lam = np.concatenate(lams) if lams else np.zeros(0)
        self.z2 = np.concatenate([np.sum(z**2, axis=1) for z in zs]) if zs else np.zeros(0)
        self.n_tracks = len(lams)

    def __call__(self, noise_m: float, accel_psd_m2ps3: float) -> float:
        """Log-likelihood [-] at sigma = noise_m [m], q = accel_psd_m2ps3 [m^2/s^3]."""
        v = accel_psd_m2ps3 * self.lam + noise_m**2
        return float(-0.5 * np.sum(2.0 * np.log(2.0 * np.pi * v) + self.z2 / v))


def estimate_noise(
    tracks: list[tuple[FloatArray, FloatArray]],
    default: NoiseEstimate | None = None,
    std_inflation: float = POSTERIOR_STD_INFLATION,
) -> NoiseEstimate:
    """Maximum-likelihood (sigma, q) of the rider model from a recording's keyframes.

    The restricted (diffuse-prior) likelihood of all tracks with >=
    MIN_KEYFRAMES_FOR_ESTIMATE keyframes together (:class:`RestrictedLikelihood`) is
    maximised over log sigma and log q inside NOISE_BOUNDS_M x PSD_BOUNDS (L-BFGS-B from
    two starts: the default and a low-noise / high-manoeuvre point).

    Args:
        tracks: per track (t_key [K] s strictly increasing, xy_key [K, 2] m).
        default: what to return without usable tracks (default sigma 0.25 m, q 1.0).
        std_inflation: calibration factor of the posterior std stored in the estimate
            (default: the leave-one-recording-out validated POSTERIOR_STD_INFLATION; 1.0
            for the pure model). The default's own factor is kept when it is returned.
    Returns:
        NoiseEstimate (method 'ml', or the default's 'fixed' without usable tracks).
    """
    default = default or NoiseEstimate(0.25, 1.0)
    lik = RestrictedLikelihood([(np.asarray(t, float), np.asarray(xy, float)) for t, xy in tracks])
    if lik.n_tracks == 0 or lik.lam.size == 0:
        return default

    def objective(theta: FloatArray) -> float:
        return -lik(math.exp(theta[0]), math.exp(theta[1]))

    bounds = [tuple(np.log(NOISE_BOUNDS_M)), tuple(np.log(PSD_BOUNDS))]
    lo, hi = [b[0] for b in bounds], [b[1] for b in bounds]
    x0 = np.clip(np.log([default.noise_m, default.accel_psd_m2ps3]), lo, hi)
    best = None
    for start in (x0, np.clip(np.log([0.05, 5.0]), lo, hi)):
        res = minimize(objective, start, method="L-BFGS-B", bounds=bounds)
        if best is None or res.fun < best.fun:
            best = res
    assert best is not None
    return NoiseEstimate(
        noise_m=float(math.exp(best.x[0])),
        accel_psd_m2ps3=float(math.exp(best.x[1])),
        method="ml",
        loglik=float(-best.fun),
        n_tracks=lik.n_tracks,
        n_keyframes=int(lik.lam.size + 2 * lik.n_tracks),
        std_inflation=float(std_inflation),
    )


@dataclass(frozen=True)
class Posterior:
    """Smoothed state of one track at query times.

    Attributes:
        t_s: [N] query times [s].
        xy_m: [N, 2] posterior mean position [m].
        vel_mps: [N, 2] posterior mean velocity [m/s].
        std_m: [N] posterior standard deviation of the position per axis [m] (the same
            for x and y: isotropic noise and common keyframe times).
        vel_std_mps: [N] posterior standard deviation of the velocity per axis [m/s].
        pos_vel_cov: [N] posterior covariance of position and velocity along one axis
            [m^2/s] (the two axes are independent).
    """

    t_s: FloatArray
    xy_m: FloatArray
    vel_mps: FloatArray
    std_m: FloatArray
    vel_std_mps: FloatArray | None = None
    pos_vel_cov: FloatArray | None = None

    def take(self, idx: npt.ArrayLike, t_s: FloatArray) -> Posterior:
        """The posterior at positions ``idx`` of its arrays, labelled with times t_s."""
        return Posterior(
            t_s,
            self.xy_m[idx],
            self.vel_mps[idx],
            self.std_m[idx],
            None if self.vel_std_mps is None else self.vel_std_mps[idx],
            None if self.pos_vel_cov is None else self.pos_vel_cov[idx],
        )


def posterior(
    tracks: list[tuple[FloatArray, FloatArray]],
    queries: list[FloatArray],
    noise_m: float,
    accel_psd_m2ps3: float,
    std_scale: float = 1.0,
) -> list[Posterior]:
    """RTS-smoothed posteriors of several tracks at their query times (one batch).

    Args:
        tracks: per track (t_key [K] s, xy_key [K, 2] m).
        queries: per track [N] times [s] (any order inside the keyframe span).
        noise_m: keyframe noise sigma [m]; accel_psd_m2ps3: q [m^2/s^3].
        std_scale: factor on the posterior standard deviations (covariances times its
            square; NoiseEstimate.std_inflation); the mean does not depend on it.
    Returns:
        one Posterior per track, at its query times.
    """
    batch, times = _rider_batch(tracks, queries)
    b = batch.t_s.shape[0]
    res = kalman.kalman_filter(
        batch, _H_POS2, np.full((b, 1, 1), noise_m**2), np.full(b, accel_psd_m2ps3), order=2
    )
    m_s, p_s = kalman.rts_smoother(res)
    out = []
    for i, q in enumerate(queries):
        idx = np.searchsorted(times[i], q)
        out.append(
            Posterior(
                t_s=np.asarray(q, float),
                xy_m=m_s[i, idx, 0, :],
                vel_mps=m_s[i, idx, 1, :],
                std_m=std_scale * np.sqrt(np.clip(p_s[i, idx, 0, 0], 0.0, None)),
                vel_std_mps=std_scale * np.sqrt(np.clip(p_s[i, idx, 1, 1], 0.0, None)),
                pos_vel_cov=std_scale**2 * p_s[i, idx, 0, 1],
            )
        )
    return out


def sample_tracks(
    t_key_s: FloatArray,
    xy_key_m: FloatArray,
    t_s: FloatArray,
    noise_m: float,
    accel_psd_m2ps3: float,
    n_samples: int,
    seed: int,
    std_scale: float = 1.0,
) -> tuple[FloatArray, FloatArray]:
    """Joint posterior samples of one track's path at times t_s.

    Args:
        t_key_s: [K] keyframe times [s]; xy_key_m: [K, 2] positions [m].
        t_s: [N] increasing times [s] inside the keyframe span.
        noise_m, accel_psd_m2ps3: the noise model.
        n_samples: S; seed: numpy seed (same seed -> same samples).
        std_scale: factor on each sample's deviation from the posterior mean (the
            calibration of NoiseEstimate.std_inflation; 1.0 = the model's posterior).
    Returns:
        (xy [S, N, 2] positions [m], vel [S, N, 2] velocities [m/s]).
    """
    batch, times = _rider_batch([(t_key_s, xy_key_m)], [t_s])
    res = kalman.kalman_filter(
        batch, _H_POS2, np.full((1, 1, 1), noise_m**2), np.full(1, accel_psd_m2ps3), order=2
    )
    draws = kalman.sample_posterior(res, n_samples, np.random.default_rng(seed))[0]
    if std_scale != 1.0:
        mean = kalman.rts_smoother(res)[0][0]
        draws = mean[None] + std_scale * (draws - mean[None])
    idx = np.searchsorted(times[0], t_s)
    return draws[:, idx, 0, :], draws[:, idx, 1, :]


def prime(interpolants: list, queries: list[FloatArray]) -> None:
    """Compute the posteriors of several KalmanInterpolants at their query times in one
    batch (one filter and smoother pass over all of them) and keep them in their caches,
    so the next ``position`` / ``velocity`` / ``std`` call at exactly those times is free.
    Interpolants of another type, with one keyframe, or with other noise than the first
    are left alone.

    Args:
        interpolants: [M] interpolants; queries: [M] arrays of times [s] inside each span.
    """
    todo = [
        (ip, np.clip(np.asarray(q, float).ravel(), ip.t_start_s, ip.t_end_s))
        for ip, q in zip(interpolants, queries, strict=True)
        if isinstance(ip, KalmanInterpolant) and ip.t_key_s.size > 1 and np.size(q)
    ]
    if not todo:
        return
    noise = todo[0][0].noise
    todo = [(ip, q) for ip, q in todo if ip.noise == noise]
    sorted_q = [np.sort(q) for _, q in todo]
    posts = posterior(
        [(ip.t_key_s, ip.xy_key_m) for ip, _ in todo],
        sorted_q,
        noise.noise_m,
        noise.accel_psd_m2ps3,
        noise.std_inflation,
    )
    for (ip, q), sq, p in zip(todo, sorted_q, posts, strict=True):
        idx = np.searchsorted(sq, q)
        ip._cache = (q.tobytes(), p.take(idx, q))


class KalmanInterpolant:
    """RTS-smoothed track with the interface of :class:`vei.recon.interpolate.TrackInterpolant`.

    Attributes:
        method: 'kalman'. t_start_s, t_end_s: keyframe span [s]. lam: the equivalent
        smoothing-spline lam = sigma^2 / q [s^3]. noise: the NoiseEstimate used.
    """

    method = "kalman"

    def __init__(self, t_key_s: FloatArray, xy_key_m: FloatArray, noise: NoiseEstimate):
        self.t_key_s = np.asarray(t_key_s, float)
        self.xy_key_m = np.asarray(xy_key_m, float).reshape(-1, 2)
        self.noise = noise
        self.t_start_s = float(self.t_key_s[0])
        self.t_end_s = float(self.t_key_s[-1])
        self.lam = noise.noise_m**2 / noise.accel_psd_m2ps3
        self._cache: tuple[bytes, Posterior] | None = None

    def posterior(self, t_s: npt.ArrayLike) -> Posterior:
        """Posterior at t_s [N] (inside the span; ValueError outside: no extrapolation)."""
        t = np.asarray(t_s, dtype=np.float64).ravel()
        if t.size and (t.min() < self.t_start_s - 1e-6 or t.max() > self.t_end_s + 1e-6):
            raise ValueError(
                f"times outside the keyframe span [{self.t_start_s}, {self.t_end_s}] s: "
                "interpolants never extrapolate"
            )
        t = np.clip(t, self.t_start_s, self.t_end_s)
        key = t.tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1]
        if self.t_key_s.size == 1:
            post = Posterior(
                t,
                np.repeat(self.xy_key_m, t.size, axis=0),
                np.zeros((t.size, 2)),
                np.full(t.size, self.noise.noise_m * self.noise.std_inflation),
            )
        else:
            order = np.argsort(t, kind="stable")
            p = posterior(
                [(self.t_key_s, self.xy_key_m)],
                [t[order]],
                self.noise.noise_m,
                self.noise.accel_psd_m2ps3,
                self.noise.std_inflation,
            )[0]
            inv = np.empty_like(order)
            inv[order] = np.arange(order.size)
            post = p.take(inv, t)
        self._cache = (key, post)
        return post

    def position(self, t_s: npt.ArrayLike) -> FloatArray:
        """Posterior mean positions [N, 2] (m) at t_s [N]."""
        return self.posterior(t_s).xy_m

    def velocity(self, t_s: npt.ArrayLike) -> FloatArray:
        """Posterior mean velocities [N, 2] (m/s) at t_s [N]."""
        return self.posterior(t_s).vel_mps

    def std(self, t_s: npt.ArrayLike) -> FloatArray:
        """Posterior position standard deviation per axis [N] (m) at t_s [N]."""
        return self.posterior(t_s).std_m

    def acceleration(self, t_s: npt.ArrayLike) -> FloatArray:
        """Acceleration [N, 2] (m/s^2) of the mean path (derivative of the mean velocity,
        which is piecewise linear between keyframes: a cubic spline's second derivative)."""
        t = np.asarray(t_s, dtype=np.float64).ravel()
        eps = 1e-3
        lo = np.clip(t - eps, self.t_start_s, self.t_end_s)
        hi = np.clip(t + eps, self.t_start_s, self.t_end_s)
        span = np.where(hi > lo, hi - lo, 1.0)[:, None]
        v = self.posterior(np.concatenate([lo, hi])).vel_mps
        return (v[t.size :] - v[: t.size]) / span


# --------------------------------------------------------------------------- the ego

#: Search box of the ego's noise: GPS position sigma [m], INS velocity sigma [m/s],
#: jerk spectral density [m^2/s^5].
EGO_POS_BOUNDS_M: tuple[float, float] = (0.005, 2.0)
EGO_VEL_BOUNDS_MPS: tuple[float, float] = (0.005, 2.0)
EGO_JERK_BOUNDS: tuple[float, float] = (1e-3, 1e3)
#: Fixes per piece in the ego's noise estimate (3 s at 10 Hz).
EGO_PIECE_FIXES = 30
#: Below this speed [m/s] lateral acceleration and course are not evaluated.
MOVING_MIN_SPEED_MPS = 1.0


@dataclass(frozen=True)
class EgoNoise:
    """Noise of the ego model (constant acceleration + white jerk).

    Attributes:
        pos_noise_m: GPS position sigma per axis [m].
        vel_noise_mps: INS velocity sigma per axis [m/s] (None: velocity not observed).
        jerk_psd_m2ps5: spectral density of the white jerk [m^2/s^5].
        method: 'ml' (maximum likelihood on the ego's own fixes) or 'fixed'.
        loglik: log-likelihood at the estimate.
    """

    pos_noise_m: float
    vel_noise_mps: float | None
    jerk_psd_m2ps5: float
    method: str = "ml"
    loglik: float = float("nan")

    def as_dict(self) -> dict:
        """Plain dict (JSON; NaN -> None)."""
        d = asdict(self)
        return {
            k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()
        }


def _ego_batch(
    t_s: FloatArray, xy_m: FloatArray, vel_mps: FloatArray | None, t_query: FloatArray | None
) -> tuple[kalman.Batch, FloatArray, FloatArray]:
    t = t_s if t_query is None else np.union1d(t_s, t_query)
    idx = np.searchsorted(t, t_s)
    k = 1 if vel_mps is None else 2
    y = np.full((t.size, k, 2), np.nan)
    y[idx, 0, :] = xy_m
    if vel_mps is not None:
        y[idx, 1, :] = vel_mps
    mk = np.zeros(t.size, dtype=bool)
    mk[idx] = True
    h = np.eye(k, 3)
    return kalman.make_batch([t], [y], [mk]), t, h


def _ego_filter(batch: kalman.Batch, h: FloatArray, theta: FloatArray) -> kalman.FilterResult:
    r = np.broadcast_to(
        np.diag(np.exp(2.0 * theta[: h.shape[0]])), (batch.t_s.shape[0], h.shape[0], h.shape[0])
    )
    return kalman.kalman_filter(
        batch, h, r, np.full(batch.t_s.shape[0], math.exp(theta[-1])), order=3
    )


def estimate_ego_noise(t_s: FloatArray, xy_m: FloatArray, vel_mps: FloatArray | None) -> EgoNoise:
    """Maximum-likelihood noise of the ego model from its own fixes.

    Args:
        t_s: [M] fix times [s]; xy_m: [M, 2] plane positions [m]; vel_mps: [M, 2] plane
            velocity [m/s] (INS speed along its heading) or None.
    Returns:
        EgoNoise ('ml'); L-BFGS-B over the log noise levels inside the EGO_*_BOUNDS. For
        speed the fixes are cut into pieces of EGO_PIECE_FIXES filtered as one batch (each
        piece restarts from the diffuse prior: a few fixes' worth of information lost).
    """
    pieces = [
        (
            t_s[a : a + EGO_PIECE_FIXES],
            xy_m[a : a + EGO_PIECE_FIXES],
            None if vel_mps is None else vel_mps[a : a + EGO_PIECE_FIXES],
        )
        for a in range(0, t_s.size, EGO_PIECE_FIXES)
    ]
    pieces = [p for p in pieces if p[0].size >= 4] or pieces[:1]
    parts = [_ego_batch(*p, None) for p in pieces]
    h = parts[0][2]
    batch = kalman.make_batch(
        [p[0].t_s[0] for p in parts],
        [p[0].obs[0] for p in parts],
        [p[0].mask[0] for p in parts],
    )
    bounds = [tuple(np.log(EGO_POS_BOUNDS_M))]
    x0 = [math.log(0.05)]
    if vel_mps is not None:
        bounds.append(tuple(np.log(EGO_VEL_BOUNDS_MPS)))
        x0.append(math.log(0.05))
    bounds.append(tuple(np.log(EGO_JERK_BOUNDS)))
    x0.append(math.log(1.0))

    def objective(theta: FloatArray) -> float:
        return -float(_ego_filter(batch, h, theta).loglik.sum())

    res = minimize(objective, np.array(x0), method="L-BFGS-B", bounds=bounds)
    th = res.x
    return EgoNoise(
        pos_noise_m=float(math.exp(th[0])),
        vel_noise_mps=float(math.exp(th[1])) if vel_mps is not None else None,
        jerk_psd_m2ps5=float(math.exp(th[-1])),
        method="ml",
        loglik=float(-res.fun),
    )


def smooth_ego(
    t_s: FloatArray,
    xy_m: FloatArray,
    vel_mps: FloatArray | None,
    t_query: FloatArray,
    noise: EgoNoise | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray, EgoNoise]:
    """RTS-smoothed ego path (constant acceleration + white jerk).

    Args:
        t_s: [M] fix times [s]; xy_m: [M, 2] positions [m]; vel_mps: [M, 2] INS velocity
            [m/s] or None; t_query: [N] times [s] inside [t_s[0], t_s[-1]].
        noise: the noise levels (default: :func:`estimate_ego_noise` on these fixes).
    Returns:
        (xy [N, 2] m, vel [N, 2] m/s, acc [N, 2] m/s^2, noise): posterior means. The mean
        path is C2 (its acceleration is continuous), so heading and curvature are.
    """
    noise = noise or estimate_ego_noise(t_s, xy_m, vel_mps)
    batch, t, h = _ego_batch(t_s, xy_m, vel_mps, t_query)
    theta = [math.log(noise.pos_noise_m)]
    if vel_mps is not None:
        theta.append(math.log(noise.vel_noise_mps or 0.05))
    theta.append(math.log(noise.jerk_psd_m2ps5))
    res = _ego_filter(batch, h, np.array(theta))
    m_s, _ = kalman.rts_smoother(res)
    idx = np.searchsorted(t, t_query)
    st = m_s[0, idx]
    return st[:, 0, :], st[:, 1, :], st[:, 2, :], noise


def lateral_accel(t_s: FloatArray, xy_m: FloatArray) -> FloatArray:
    """Lateral acceleration [N] (m/s^2, positive left) of sampled path positions, by finite
    differences of the samples (what a simulator following them sees); NaN below
    MOVING_MIN_SPEED_MPS.

    Args:
        t_s: [N] times [s]; xy_m: [N, 2] positions [m].
    """
    if t_s.size < 3:
        return np.full(t_s.size, np.nan)
    v = np.gradient(xy_m, t_s, axis=0)
    a = np.gradient(v, t_s, axis=0)
    speed = np.hypot(v[:, 0], v[:, 1])
    lat = (v[:, 0] * a[:, 1] - v[:, 1] * a[:, 0]) / np.maximum(speed, 1e-9)
    return np.where(speed >= MOVING_MIN_SPEED_MPS, lat, np.nan)
