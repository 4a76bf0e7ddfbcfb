"""The Kalman / RTS smoother against hand-checkable answers: exact discretisation, the
smoothing spline it must equal, the likelihood, ML recovery of known noise, calibration
of its 95 % region and of its posterior samples on data drawn from the model."""

import math

import numpy as np
import pytest
from scipy.linalg import expm

from vei.recon import kalman, smoother
from vei.recon.interpolate import _smooth


@pytest.mark.parametrize("order", [2, 3])
def test_transition_matches_van_loan(order):
    # Van Loan (1978): expm([[-A, L L^T], [0, A^T]] dt) gives F and Q of dx = A x dt + L dw.
    n = order
    a = np.diag(np.ones(n - 1), 1)
    ll = np.zeros((n, n))
    ll[-1, -1] = 1.0
    dt = 0.37
    m = expm(np.block([[-a, ll], [np.zeros((n, n)), a.T]]) * dt)
    f_ref = m[n:, n:].T
    q_ref = f_ref @ m[:n, n:]
    f, q = kalman.transition(np.array([dt]), order)
    assert f[0] == pytest.approx(f_ref, abs=1e-12)
    assert q[0] == pytest.approx(q_ref, abs=1e-12)


def _cv_tracks(rng, n_tracks, sigma, q, dt=1.0, k=25):
    """Tracks of the model itself: constant velocity + white acceleration, noisy positions."""
    out = []
    for _ in range(n_tracks):
        t = np.cumsum(np.r_[0.0, rng.uniform(0.8 * dt, 1.2 * dt, k - 1)])
        f, q1 = kalman.transition(np.diff(t, prepend=t[0]), 2)
        x = np.zeros((k, 2, 2))
        x[0, 1] = rng.normal(0, 3.0, 2)
        for i in range(1, k):
            x[i] = f[i] @ x[i - 1] + np.linalg.cholesky(q * q1[i] + 1e-15 * np.eye(2)) @ rng.normal(
                size=(2, 2)
            )
        truth = x[:, 0, :]
        out.append((t, truth + rng.normal(0, sigma, (k, 2)), truth))
    return out


def test_rts_mean_is_the_smoothing_spline():
    # Wahba (1978): with a diffuse prior the posterior mean of the constant-velocity model
    # is the natural cubic smoothing spline with lam = sigma^2 / q, at and between keyframes.
    rng = np.random.default_rng(3)
    t, y, _ = _cv_tracks(rng, 1, 0.3, 0.8)[0]
    sigma, q = 0.3, 0.8
    spline = _smooth(t, y, sigma**2 / q)
    query = np.linspace(t[0], t[-1], 301)
    post = smoother.posterior([(t, y)], [query], sigma, q)[0]
    assert post.xy_m == pytest.approx(spline(query), abs=2e-3)
    assert post.vel_mps == pytest.approx(spline(query, 1), abs=1e-2)  # finite prior at t0


def test_restricted_likelihood_equals_the_kalman_filter_up_to_a_constant():
    rng = np.random.default_rng(4)
    tracks = [(t, y) for t, y, _ in _cv_tracks(rng, 3, 0.25, 0.5, k=12)]
    lik = smoother.RestrictedLikelihood(tracks)
    pairs = [(0.1, 0.2), (0.25, 0.5), (0.6, 3.0)]
    diffs_r = [lik(*p) - lik(*pairs[0]) for p in pairs[1:]]
    diffs_k = [
        smoother.track_loglik(tracks, *p) - smoother.track_loglik(tracks, *pairs[0])
        for p in pairs[1:]
    ]
    assert diffs_r == pytest.approx(diffs_k, abs=0.05)


def test_ml_recovers_the_noise_of_simulated_tracks():
    rng = np.random.default_rng(5)
    sim = _cv_tracks(rng, 40, 0.3, 0.5)
    est = smoother.estimate_noise([(t, y) for t, y, _ in sim])
    assert est.method == "ml" and est.n_tracks == 40
    assert est.noise_m == pytest.approx(0.3, rel=0.12)
    assert est.accel_psd_m2ps3 == pytest.approx(0.5, rel=0.35)


def test_95_percent_region_covers_95_percent_of_the_truth():
    # On data drawn from the model with the true noise, the share of true positions (at
    # 10 Hz between keyframes) inside the 2-D 95 % region is 95 % (+- sampling error).
    rng = np.random.default_rng(6)
    sim = _cv_tracks(rng, 30, 0.3, 0.5)
    inside = []
    for t, y, truth in sim:
        post = smoother.posterior([(t, y)], [t], 0.3, 0.5)[0]
        d2 = np.sum((post.xy_m - truth) ** 2, axis=1) / post.std_m**2
        inside.append(d2 <= -2 * math.log(0.05))
    share = np.mean(np.concatenate(inside))
    assert 0.92 <= share <= 0.98


def test_posterior_samples_have_the_smoother_mean_and_spread():
    rng = np.random.default_rng(7)
    t, y, _ = _cv_tracks(rng, 1, 0.3, 0.5, k=10)[0]
    grid = np.linspace(t[0], t[-1], 50)
    xy, vel = smoother.sample_tracks(t, y, grid, 0.3, 0.5, 4000, seed=11)
    post = smoother.posterior([(t, y)], [grid], 0.3, 0.5)[0]
    assert xy.shape == (4000, 50, 2) and vel.shape == (4000, 50, 2)
    assert xy.mean(axis=0) == pytest.approx(post.xy_m, abs=0.02)
    assert xy.std(axis=0).mean(axis=1) == pytest.approx(post.std_m, rel=0.06)
    # Joint, not independent per step: neighbours 1/50 of the span apart move together.
    dev = xy[:, :, 0] - post.xy_m[None, :, 0]
    assert np.corrcoef(dev[:, 20], dev[:, 21])[0, 1] > 0.9
    again, _ = smoother.sample_tracks(t, y, grid, 0.3, 0.5, 4000, seed=11)
    assert np.array_equal(xy, again)


def test_kalman_interpolant_yaw_speed_and_no_extrapolation():
    t = np.arange(6.0)
    xy = np.column_stack([2.0 * t, np.zeros(6)])  # 2 m/s east, exactly
    interp = smoother.KalmanInterpolant(t, xy, smoother.NoiseEstimate(0.2, 1.0))
    q = np.linspace(0, 5, 11)
    # Exact up to the finite "diffuse" prior (velocity variance 1e4 m^2/s^2 around 0).
    assert interp.position(q) == pytest.approx(np.column_stack([2 * q, 0 * q]), abs=2e-3)
    assert interp.velocity(q) == pytest.approx(np.tile([2.0, 0.0], (11, 1)), abs=2e-3)
    assert interp.acceleration(q) == pytest.approx(np.zeros((11, 2)), abs=2e-3)
    std = interp.std(q)
    assert np.all(std < 0.2) and std[5] < std[0]  # data on both sides beats one side
    post = interp.posterior(q)
    # The velocity's posterior spread agrees with that of joint posterior samples (FFBS).
    _, vel = smoother.sample_tracks(t, xy, q, 0.2, 1.0, 4000, seed=2)
    assert vel.std(axis=0).mean(axis=1) == pytest.approx(post.vel_std_mps, rel=0.06)
    with pytest.raises(ValueError, match="never extrapolate"):
        interp.position([5.5])


def test_ego_smoother_on_a_circle_recovers_the_lateral_acceleration():
    # A car on a 20 m circle at 5 m/s: lateral acceleration 1.25 m/s^2. GPS jitter of
    # 2 cm at 10 Hz makes the spline through the fixes swing (finite differences of a
    # path through noise); the smoother recovers 1.25 within 0.15 m/s^2.
    rng = np.random.default_rng(8)
    t = np.arange(0, 20, 0.1)
    ang = 5.0 / 20.0 * t
    xy = 20.0 * np.column_stack([np.cos(ang), np.sin(ang)])
    vel = 5.0 * np.column_stack([-np.sin(ang), np.cos(ang)])
    noisy = xy + rng.normal(0, 0.02, xy.shape)
    vel_noisy = vel + rng.normal(0, 0.05, vel.shape)
    grid = np.arange(0, 19.95, 0.05)
    s_xy, s_vel, s_acc, noise = smoother.smooth_ego(t, noisy, vel_noisy, grid)
    lat = smoother.lateral_accel(grid, s_xy)[20:-20]
    assert np.nanmax(np.abs(lat - 1.25)) < 0.15
    from scipy.interpolate import CubicSpline

    raw = smoother.lateral_accel(grid, CubicSpline(t, noisy)(grid))[20:-20]
    assert np.nanmax(np.abs(raw - 1.25)) > 1.0  # what the smoother removes
    assert 0.005 <= noise.pos_noise_m <= 0.05
    assert np.hypot(*s_acc[200]) == pytest.approx(1.25, abs=0.15)
