"""What 1 FPS keyframes allow: error floors of a reconstruction against denoised ground truth.

Per rider track, against the ground truth denoised over 1 s (:mod:`vei.recon.accuracy`),
at the ground-truth times inside the keyframe span:

* ``clean_interp_rmse_m``: the natural cubic spline (linear for two keyframes) through the
  *denoised ground truth itself* at the keyframe times. No noise at all enters; this is the
  error of sampling the path at 1 FPS and nothing else. No method that sees only the
  keyframes can expect to beat it on average.
* ``oracle_rmse_m``: the constant-velocity smoother's mean (the smoothing spline) with the
  smoothing parameter lam = sigma^2 / q that minimises *this track's* error against the
  ground truth, chosen with hindsight over a grid of 25 values 1e-4..1e2 s^3. A lower bound
  of the Gaussian smoother family (the real method estimates lam from the keyframes).

These are measurements of the data, not methods: both read the ground truth.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.recon.smoother import posterior

FloatArray = npt.NDArray[np.float64]

#: Hindsight grid of the smoothing parameter lam = sigma^2 / q [s^3].
ORACLE_LAMS_S3 = np.logspace(-4.0, 2.0, 25)


def _rmse(a: FloatArray, b: FloatArray) -> float:
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def clean_interp_rmse(t_key_s: FloatArray, t_s: FloatArray, truth_xy_m: FloatArray) -> float:
    """RMSE [m] of a natural cubic spline through the truth sampled at the keyframe times.

    Args:
        t_key_s: [K] keyframe times [s] (K >= 2), inside [t_s[0], t_s[-1]].
        t_s: [N] increasing truth times [s]; truth_xy_m: [N, 2] truth positions [m].
    Returns:
        RMSE over the truth samples inside [t_key_s[0], t_key_s[-1]] (linear for K = 2).
    """
    from scipy.interpolate import CubicSpline

    tk = np.asarray(t_key_s, float)
    at_k = np.column_stack([np.interp(tk, t_s, truth_xy_m[:, j]) for j in (0, 1)])
    inside = (t_s >= tk[0] - 1e-9) & (t_s <= tk[-1] + 1e-9)
    tq = t_s[inside]
    if tk.size >= 3:
        est = CubicSpline(tk, at_k, axis=0, bc_type="natural")(tq)
    else:
        est = np.column_stack([np.interp(tq, tk, at_k[:, j]) for j in (0, 1)])
    return _rmse(est, truth_xy_m[inside])


def oracle_rmse(
    t_key_s: FloatArray, xy_key_m: FloatArray, t_s: FloatArray, truth_xy_m: FloatArray
) -> tuple[float, float]:
    """Smallest RMSE [m] of the smoothing-spline mean over ORACLE_LAMS_S3, and its lam [s^3].

    Args:
        t_key_s: [K] keyframe times [s]; xy_key_m: [K, 2] keyframes [m] (K >= 2).
        t_s: [N] truth times inside the keyframe span [s]; truth_xy_m: [N, 2] [m].
    """
    best = (float("inf"), float("nan"))
    for lam in ORACLE_LAMS_S3:
        p = posterior([(t_key_s, xy_key_m)], [t_s], float(np.sqrt(lam)), 1.0)[0]
        e = _rmse(p.xy_m, truth_xy_m)
        if e < best[0]:
            best = (e, float(lam))
    return best
