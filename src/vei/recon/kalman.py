"""Probabilistic smoother of road-user tracks: linear motion model, Kalman filter, RTS smoother.

Motion models (per plane axis, both axes independent with the same noise, so they share one
covariance recursion and only the means are computed per axis):

* ``order=2``, constant velocity driven by white acceleration: state (p, v), spectral
  density ``psd`` [m^2/s^3]. Its smoothed mean through position observations with noise
  ``noise_m`` is the cubic smoothing spline with lam = noise_m^2 / psd (Wahba 1978), so
  :mod:`vei.recon.interpolate`'s ``'smoothing'`` is its posterior mean; this module adds
  the posterior covariance and samples. Used for riders.
* ``order=3``, constant acceleration driven by white jerk: state (p, v, a), ``psd``
  [m^2/s^5]; the mean is C2 (continuous curvature of the path). Used for the ego, which
  observes position (GPS) and velocity (INS speed along its heading).

Discretisation over a step dt (exact for these models): F = exp(A dt) and
Q = psd * int_0^dt exp(A s) L L^T exp(A s)^T ds (closed forms in :func:`transition`).

The prior on the first state is diffuse (PRIOR_VAR: for riders position and velocity
variances 1e6 m^2 and 1e4 m^2/s^2), so the first keyframes decide where the track starts; the smoothed mean then
matches the natural smoothing spline to well below a millimetre (tested).

Everything runs vectorised over a batch of B tracks padded to a common length T (padding
steps have dt = 0 and no observation, which leaves the state unchanged).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Diffuse prior variances per model order: position [m^2], velocity [m^2/s^2],
#: acceleration [m^2/s^4] (order 3, the ego, observes its velocity: a tighter prior keeps
#: the covariance well conditioned against millimetre GPS noise).
PRIOR_VAR: dict[int, tuple[float, ...]] = {2: (1e6, 1e4), 3: (1e4, 1e2, 1e2)}
#: log(2 pi)
_LOG2PI = float(np.log(2.0 * np.pi))


def transition(dt_s: npt.ArrayLike, order: int) -> tuple[FloatArray, FloatArray]:
    """Exact discretisation of the integrated white-noise models over steps ``dt_s``.

    Args:
        dt_s: [...] step lengths [s] (>= 0).
        order: 2 (constant velocity, white acceleration) or 3 (constant acceleration,
            white jerk).
    Returns:
        (F [..., n, n], Q1 [..., n, n]) with n = order: transition matrix and process
        covariance for a unit spectral density (multiply Q1 by psd).
    """
    dt = np.asarray(dt_s, dtype=np.float64)
    n = order
    f = np.zeros((*dt.shape, n, n))
    q = np.zeros((*dt.shape, n, n))
    if order == 2:
        f[..., 0, 0] = f[..., 1, 1] = 1.0
        f[..., 0, 1] = dt
        q[..., 0, 0] = dt**3 / 3.0
        q[..., 0, 1] = q[..., 1, 0] = dt**2 / 2.0
        q[..., 1, 1] = dt
    elif order == 3:
        for i in range(3):
            f[..., i, i] = 1.0
        f[..., 0, 1] = f[..., 1, 2] = dt
        f[..., 0, 2] = dt**2 / 2.0
        q[..., 0, 0] = dt**5 / 20.0
        q[..., 0, 1] = q[..., 1, 0] = dt**4 / 8.0
        q[..., 0, 2] = q[..., 2, 0] = dt**3 / 6.0
        q[..., 1, 1] = dt**3 / 3.0
        q[..., 1, 2] = q[..., 2, 1] = dt**2 / 2.0
        q[..., 2, 2] = dt
    else:
        raise ValueError(f"order must be 2 or 3, got {order}")
    return f, q


@dataclass(frozen=True)
class Batch:
    """Tracks padded to a common length, ready for the filter.

    Attributes:
        t_s: [B, T] times [s] (padding repeats the last time).
        obs: [B, T, k, D] observations (k observed quantities, D independent axes).
        mask: [B, T] True where an observation is present.
        length: [B] number of real (unpadded) steps per track.
    """

    t_s: FloatArray
    obs: FloatArray
    mask: npt.NDArray[np.bool_]
    length: npt.NDArray[np.intp]


def make_batch(
    times: list[FloatArray], obs: list[FloatArray], masks: list[npt.NDArray[np.bool_]]
) -> Batch:
    """Pad per-track arrays into a :class:`Batch`.

    Args:
        times: B arrays [T_b] of strictly increasing times [s].
        obs: B arrays [T_b, k, D] of observations (NaN allowed where the mask is False).
        masks: B arrays [T_b] (True: observed).
    """
    b = len(times)
    t_max = max(t.size for t in times)
    k, d = obs[0].shape[1:]
    t_s = np.zeros((b, t_max))
    o = np.zeros((b, t_max, k, d))
    m = np.zeros((b, t_max), dtype=bool)
    length = np.array([t.size for t in times], dtype=np.intp)
    for i, (t, y, mk) in enumerate(zip(times, obs, masks, strict=True)):
        n = t.size
        t_s[i, :n] = t
        t_s[i, n:] = t[-1]
        o[i, :n] = np.where(mk[:, None, None], y, 0.0)
        m[i, :n] = mk
    return Batch(t_s, o, m, length)


@dataclass(frozen=True)
class FilterResult:
    """Output of :func:`kalman_filter` (B tracks, T steps, n states, D axes).

    Attributes:
        m_pred, m_filt: [B, T, n, D] predicted / filtered means.
        p_pred, p_filt: [B, T, n, n] predicted / filtered covariances (shared by the axes).
        f: [B, T, n, n] transition from step t-1 to t (identity at t = 0).
        loglik: [B] log-likelihood of each track's observations (summed over axes).
        n_obs: [B] number of scalar observations that entered loglik.
    """

    m_pred: FloatArray
    m_filt: FloatArray
    p_pred: FloatArray
    p_filt: FloatArray
    f: FloatArray
    loglik: FloatArray
    n_obs: FloatArray


def kalman_filter(
    batch: Batch,
    h: FloatArray,
    r: FloatArray,
    psd: FloatArray,
    order: int,
) -> FilterResult:
    """Kalman filter over a batch of tracks.

    Args:
        batch: the tracks (observations [B, T, k, D]).
        h: [k, n] observation matrix (e.g. [[1, 0]] for position only).
        r: [B, k, k] observation noise covariance per track, or [B, T, k, k] per step
            (heteroscedastic: e.g. the reweighted keyframes of :mod:`benchmarks.recon_research.robust`).
        psd: [B] spectral density of the driving noise per track.
        order: state dimension n (2 or 3), see :func:`transition`.
    Returns:
        FilterResult. The first state's prior is centred on the first observed position
        with the diffuse variances of PRIOR_VAR.
    """
    bsz, tlen, k, d = batch.obs.shape
    n = order
    dt = np.diff(batch.t_s, axis=1, prepend=batch.t_s[:, :1])
    f, q1 = transition(dt, order)
    q = q1 * psd[:, None, None, None]
    ft = np.swapaxes(f, 2, 3)
    ht = h.T
    m_pred = np.zeros((bsz, tlen, n, d))
    m_filt = np.zeros((bsz, tlen, n, d))
    p_pred = np.zeros((bsz, tlen, n, n))
    p_filt = np.zeros((bsz, tlen, n, n))
    loglik = np.zeros(bsz)
    n_obs = batch.mask.sum(axis=1) * float(k * d)
    first = np.argmax(batch.mask, axis=1)
    m = np.zeros((bsz, n, d))
    m[:, 0, :] = batch.obs[np.arange(bsz), first, 0, :]
    p = np.broadcast_to(np.diag(PRIOR_VAR[n]), (bsz, n, n)).copy()
    eye = np.eye(n)
    per_step = r.ndim == 4
    for t in range(tlen):
        if t > 0:
            m = f[:, t] @ m
            p = f[:, t] @ p @ ft[:, t] + q[:, t]
        m_pred[:, t], p_pred[:, t] = m, p
        obs = batch.mask[:, t]
        if obs.any():
            r_t = r[:, t] if per_step else r
            hp = h @ p  # [B, k, n]
            s = hp @ ht + r_t  # [B, k, k]
            sinv, logdet = _inv_small(s)
            e = batch.obs[:, t] - h @ m  # [B, k, d]
            gain = np.swapaxes(hp, 1, 2) @ sinv  # [B, n, k]
            w = obs[:, None, None]
            m = np.where(w, m + gain @ e, m)
            ikh = eye - gain @ h  # Joseph form: stays symmetric positive definite
            p_new = ikh @ p @ np.swapaxes(ikh, 1, 2) + gain @ r_t @ np.swapaxes(gain, 1, 2)
            p = np.where(w, p_new, p)
            quad = np.einsum("bkd,bkl,bld->b", e, sinv, e)
            loglik += np.where(obs, -0.5 * (d * (k * _LOG2PI + logdet) + quad), 0.0)
        m_filt[:, t], p_filt[:, t] = m, p
    f[:, 0] = np.eye(n)
    return FilterResult(m_pred, m_filt, p_pred, p_filt, f, loglik, n_obs)


def _inv_small(s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Inverse and log-determinant of a batch of 1x1 or 2x2 SPD matrices (closed form),
    else by numpy."""
    k = s.shape[-1]
    if k == 1:
        return 1.0 / s, np.log(s[:, 0, 0])
    if k == 2:
        a, b, c, dd = s[:, 0, 0], s[:, 0, 1], s[:, 1, 0], s[:, 1, 1]
        det = a * dd - b * c
        inv = np.stack([np.stack([dd, -b], -1), np.stack([-c, a], -1)], -2) / det[:, None, None]
        return inv, np.log(det)
    return np.linalg.inv(s), np.linalg.slogdet(s)[1]


def rts_smoother(res: FilterResult) -> tuple[FloatArray, FloatArray]:
    """Rauch-Tung-Striebel smoother.

    Args:
        res: the filter's output.
    Returns:
        (m_smooth [B, T, n, D], p_smooth [B, T, n, n]).
    """
    m_s = res.m_filt.copy()
    p_s = res.p_filt.copy()
    tlen = m_s.shape[1]
    gains = smoother_gains(res)
    gains_t = np.swapaxes(gains, 2, 3)
    for t in range(tlen - 2, -1, -1):
        gain = gains[:, t]
        m_s[:, t] = res.m_filt[:, t] + gain @ (m_s[:, t + 1] - res.m_pred[:, t + 1])
        p = res.p_filt[:, t] + gain @ (p_s[:, t + 1] - res.p_pred[:, t + 1]) @ gains_t[:, t]
        p_s[:, t] = 0.5 * (p + np.swapaxes(p, 1, 2))
    return m_s, p_s


def smoother_gains(res: FilterResult) -> FloatArray:
    """All smoother gains J_t = P_filt[t] F[t+1]^T P_pred[t+1]^-1 at once, [B, T-1, n, n]."""
    bsz, tlen, n, _ = res.p_filt.shape
    if tlen < 2:
        return np.zeros((bsz, 0, n, n))
    fp = res.f[:, 1:] @ res.p_filt[:, :-1]  # F P, [B, T-1, n, n]
    sol = _solve_psd(res.p_pred[:, 1:].reshape(-1, n, n), fp.reshape(-1, n, n))
    return np.swapaxes(sol.reshape(bsz, tlen - 1, n, n), 2, 3)


def _solve_psd(a: FloatArray, b: FloatArray) -> FloatArray:
    """Solve a x = b for a batch of symmetric positive (semi-)definite a (tiny ridge;
    closed-form inverse for 2 x 2)."""
    n = a.shape[-1]
    scale = np.maximum(np.trace(a, axis1=-2, axis2=-1) / n, 1e-300)[..., None, None]
    reg = a + 1e-12 * scale * np.eye(n)
    if n == 2:
        return _inv_small(reg)[0] @ b
    return np.linalg.solve(reg, b)


def sample_posterior(res: FilterResult, n_samples: int, rng: np.random.Generator) -> FloatArray:
    """Joint samples of the whole state path (forward filtering, backward sampling).

    Args:
        res: the filter's output over the times to sample (B tracks, T steps).
        n_samples: S samples per track.
        rng: the random generator (seeded by the caller).
    Returns:
        [B, S, T, n, D] sampled states; their mean and covariance per step converge to the
        RTS smoother's, and consecutive steps are correlated as the motion model says.
    """
    bsz, tlen, n, d = res.m_filt.shape
    out = np.zeros((bsz, n_samples, tlen, n, d))
    z = rng.standard_normal((tlen, bsz, n_samples, n, d))
    gains = smoother_gains(res)
    # Conditional covariances of every step at once: P_filt[t] - J P_pred[t+1] J^T.
    cov = res.p_filt[:, :-1] - gains @ res.p_pred[:, 1:] @ np.swapaxes(gains, 2, 3)
    roots = _chol(cov)  # [B, T-1, n, n]
    chol = _chol(res.p_filt[:, -1])  # [B, n, n]
    out[:, :, -1] = res.m_filt[:, None, -1] + np.einsum("bij,bsjd->bsid", chol, z[-1])
    for t in range(tlen - 2, -1, -1):
        gain = gains[:, t]  # [B, n, n]
        mean = res.m_filt[:, None, t] + np.einsum(
            "bij,bsjd->bsid", gain, out[:, :, t + 1] - res.m_pred[:, None, t + 1]
        )
        out[:, :, t] = mean + np.einsum("bij,bsjd->bsid", roots[:, t], z[t])
    return out


def _chol(cov: FloatArray) -> FloatArray:
    """Square roots R (R R^T = cov) of a batch [..., n, n] of PSD matrices, by
    eigen-decomposition (robust where the covariance is singular)."""
    sym = 0.5 * (cov + np.swapaxes(cov, -1, -2))
    w, v = np.linalg.eigh(sym)
    return v * np.sqrt(np.clip(w, 0.0, None))[..., None, :]
