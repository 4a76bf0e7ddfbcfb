"""Calibration of the rider posterior's 95 % region against real ground truth.

The constant-velocity model of :mod:`vei.recon.smoother` treats the keyframe error as
white Gaussian noise and the rider's motion as a smooth random walk of its velocity. On
the shared trafficmonitoring recordings neither holds exactly: the camera's track jumps
by up to 1-1.5 m for single frames (heavy tails), and the ground truth denoised over 1 s
still wobbles between 1 FPS keyframes (model error the keyframes cannot reveal). Its 95 %
region therefore covers only 87.9 % of the denoised ground truth (pooled over the 20
rider tracks of the seven recordings).

The fix is one factor ``c`` on the posterior standard deviation (covariance times c^2),
chosen so that the pooled squared Mahalanobis distances d^2 = |mean - truth|^2 / std^2 of
the ground-truth samples fall inside the chi-square(2) 95 % bound in 95 % of cases:
``c^2 = quantile_0.95(d^2) / 5.991`` (:func:`fit_inflation`). It is validated by leaving
one recording out (:func:`leave_one_out`): each recording is scored with the factor fitted
on the other six only, so no recording's coverage is fitted on its own data
(``python -m benchmarks recon_accuracy`` prints the table; docs/reconstruction.md).

POSTERIOR_STD_INFLATION is the factor fitted on all seven recordings (1.461 measured; the
six-recording factors of the leave-one-out folds lie in 1.41-1.69). A multiplicative
factor was chosen over an additive model-error variance (c std vs sqrt(std^2 + tau^2)):
both give 95 % pooled held-out coverage, but the multiplicative one varies less between
folds (per-recording held-out coverage 84-100 % vs 86-100 %, factor range 1.41-1.69 vs
tau 0.15-0.27 m).

This module is numpy only (the smoother imports the constant from here).
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Factor on the rider posterior's standard deviation that makes its 95 % region cover
#: 95 % of the denoised ground truth of the seven shared recordings (fitted on all of
#: them with :func:`fit_inflation`; leave-one-recording-out held-out coverage 95.5 %).
POSTERIOR_STD_INFLATION = 1.461
#: chi-square quantile, 2 degrees of freedom, 0.95: -2 ln(0.05).
CHI2_2DOF_95 = float(-2.0 * np.log(0.05))


def fit_inflation(d2: npt.ArrayLike, level: float = 0.95) -> float:
    """Factor c on the posterior std that puts ``level`` of the samples inside the 95 % region.

    Args:
        d2: [N] squared Mahalanobis distances |mean - truth|^2 / std^2 of the model
            (std per axis, isotropic 2-D posterior) [-], N >= 1.
        level: the coverage to reach, in (0, 1).
    Returns:
        c = sqrt(quantile_level(d2) / chi2_2(0.95)) (> 0; below 1 if the model is too wide).
    Raises:
        ValueError: no samples or level outside (0, 1).
    """
    d = np.asarray(d2, dtype=np.float64).ravel()
    if d.size == 0 or not 0.0 < level < 1.0:
        raise ValueError(f"need samples and a level in (0, 1), got {d.size} samples, {level}")
    return float(np.sqrt(max(float(np.quantile(d, level)), 1e-12) / CHI2_2DOF_95))


def coverage(d2: npt.ArrayLike, factor: float = 1.0) -> float:
    """Share of samples inside the 95 % region of a posterior whose std is scaled by ``factor``.

    Args:
        d2: [N] squared Mahalanobis distances of the unscaled model [-].
        factor: c > 0.
    Returns:
        mean(d2 <= c^2 chi2_2(0.95)) in [0, 1] (NaN for no samples).
    """
    d = np.asarray(d2, dtype=np.float64).ravel()
    return float(np.mean(d <= factor**2 * CHI2_2DOF_95)) if d.size else float("nan")


def leave_one_out(d2_by_group: Mapping[str, FloatArray], level: float = 0.95) -> dict:
    """Leave-one-group-out validation of the inflation factor.

    Args:
        d2_by_group: group (recording) -> [N_g] squared Mahalanobis distances of the
            unscaled model; at least two groups with samples.
        level: the coverage the factor is fitted to.
    Returns:
        {'folds': [{group, n_samples, factor (fitted on the other groups), coverage_model
        (unscaled), coverage_held_out (with that factor)}], 'coverage_model',
        'coverage_held_out' (pooled over all samples), 'factor_all' (fitted on all groups)}.
    Raises:
        ValueError: fewer than two groups with samples.
    """
    groups = {k: np.asarray(v, float).ravel() for k, v in d2_by_group.items() if np.size(v)}
    if len(groups) < 2:
        raise ValueError("leave-one-out needs at least two groups with samples")
    folds, hits, hits_model, total = [], 0.0, 0.0, 0
    for name, d in groups.items():
        others = np.concatenate([v for k, v in groups.items() if k != name])
        c = fit_inflation(others, level)
        cov, cov0 = coverage(d, c), coverage(d)
        folds.append(
            {
                "group": name,
                "n_samples": int(d.size),
                "factor": c,
                "coverage_model": cov0,
                "coverage_held_out": cov,
            }
        )
        hits += cov * d.size
        hits_model += cov0 * d.size
        total += d.size
    return {
        "folds": folds,
        "coverage_model": hits_model / total,
        "coverage_held_out": hits / total,
        "factor_all": fit_inflation(np.concatenate(list(groups.values())), level),
    }
