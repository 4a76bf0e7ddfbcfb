"""benchmarks.recon_research.robust (Student-t keyframe noise) on simulated tracks with outliers, and the
error floors of benchmarks.recon_research.floor on hand-computed cases."""

import numpy as np
import pytest
from benchmarks.recon_research.floor import ORACLE_LAMS_S3, clean_interp_rmse, oracle_rmse
from benchmarks.recon_research.robust import fit_student_t, robust_positions

from vei.recon.smoother import estimate_noise, posterior


def _simulated(seed: int, n_tracks: int = 6, k: int = 40):
    """Smooth curved paths sampled at 1 Hz, Gaussian noise 0.1 m plus 10 % jumps of 1.5 m."""
    rng = np.random.default_rng(seed)
    tracks, truths, t_fine = [], [], []
    for _ in range(n_tracks):
        tk = np.arange(float(k))
        tt = np.linspace(0.0, k - 1.0, 20 * (k - 1) + 1)
        omega = rng.uniform(0.05, 0.15)

        def path(t, omega=omega):
            # A circle of radius 1 / omega [m] at 1 m/s.
            return np.column_stack([np.sin(omega * t) / omega, (1 - np.cos(omega * t)) / omega])

        noise = rng.normal(0.0, 0.1, (k, 2))
        jump = rng.random(k) < 0.1
        ang = rng.uniform(0, 2 * np.pi, k)
        noise[jump] += 1.5 * np.column_stack([np.cos(ang), np.sin(ang)])[jump]
        tracks.append((tk, path(tk) + noise))
        truths.append(path(tt))
        t_fine.append(tt)
    return tracks, truths, t_fine


def _rmse(a, b):
    return float(np.sqrt(np.mean(np.sum((a - b) ** 2, axis=1))))


def test_student_t_beats_the_gaussian_smoother_on_outliers():
    tracks, truths, tt = _simulated(0)
    g = estimate_noise(tracks, std_inflation=1.0)
    gauss = posterior(tracks, tt, g.noise_m, g.accel_psd_m2ps3)
    fit = fit_student_t(tracks, dof=4.0)
    robust = robust_positions(tracks, fit, tt)
    e_g = np.mean([_rmse(p.xy_m, tr) for p, tr in zip(gauss, truths, strict=True)])
    e_t = np.mean([_rmse(xy, tr) for (xy, _), tr in zip(robust, truths, strict=True)])
    assert e_t < 0.8 * e_g  # measured: 0.077 m vs 0.200 m
    # The jumps get small weights, ordinary keyframes about 1; the scale is the 0.1 m core.
    assert 0.07 < fit.noise_m < 0.16
    w = np.concatenate(fit.weights)
    assert np.median(w) > 0.8 and w.min() < 0.1


def test_clean_interp_is_exact_for_a_cubic_path_and_linear_for_two_keyframes():
    t = np.linspace(0.0, 4.0, 121)
    line = np.column_stack([2.0 * t + 1.0, -0.5 * t])
    assert clean_interp_rmse(np.array([0.0, 1.0, 2.0, 3.0, 4.0]), t, line) == pytest.approx(
        0.0, abs=1e-9
    )
    # Two keyframes of a parabola x = t^2 on [0, 2]: chord 2 t, error 2 t - t^2.
    par = np.column_stack([t**2, 0 * t])
    inside = t <= 2.0
    expected = np.sqrt(np.mean((2 * t[inside] - t[inside] ** 2) ** 2))
    assert clean_interp_rmse(np.array([0.0, 2.0]), t, par) == pytest.approx(expected, rel=1e-6)


def test_oracle_is_the_best_of_its_grid():
    rng = np.random.default_rng(1)
    tk = np.arange(10.0)
    t = np.linspace(0.0, 9.0, 271)
    truth = np.column_stack([3.0 * t, np.sin(0.5 * t)])
    xyk = np.column_stack([3.0 * tk, np.sin(0.5 * tk)]) + rng.normal(0, 0.2, (10, 2))
    best, lam = oracle_rmse(tk, xyk, t, truth)
    assert lam in ORACLE_LAMS_S3
    for other in ORACLE_LAMS_S3[::6]:
        p = posterior([(tk, xyk)], [t], float(np.sqrt(other)), 1.0)[0]
        assert best <= _rmse(p.xy_m, truth) + 1e-12
