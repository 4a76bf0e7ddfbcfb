import math

import numpy as np
import pytest
from scipy.interpolate import make_smoothing_spline

from vei.recon.interpolate import (
    KinematicLimits,
    SegmentedInterpolant,
    SmoothingParams,
    _smooth,
    fit_track,
    fit_track_segmented,
    slerp_yaw,
    time_grid,
)

# Keyframes at 1 Hz on a circle of radius R at angular speed W (speed R*W = 5 m/s).
R_M, W_RPS = 10.0, 0.5


def _circle(t):
    return np.column_stack([R_M * np.cos(W_RPS * t), R_M * np.sin(W_RPS * t)])


def test_cubic_spline_on_a_circle_within_halls_bound():
    tk = np.arange(0.0, 21.0)  # 21 keyframes, h = 1 s
    interp = fit_track(tk, _circle(tk), "cubic")
    assert interp.method == "cubic"
    t = time_grid(0.0, 20.0, 20.0)
    p = interp.position(t)
    radial = np.abs(np.hypot(p[:, 0], p[:, 1]) - R_M)
    # Hall (1968): |f - s| <= 5/384 h^4 max|f''''| per coordinate for a cubic spline with
    # exact end slopes; f = R cos(W t) has f'''' = R W^4, so with h = 1 s:
    # 5/384 * 10 * 0.0625 = 8.14 mm per axis, <= sqrt(2) * 8.14 mm = 11.5 mm in the plane.
    hall_m = 5.0 / 384.0 * 1.0**4 * R_M * W_RPS**4
    inner = (t >= 1.0) & (t <= 19.0)  # not-a-knot ends are not the complete spline Hall bounds
    assert radial[inner].max() < math.sqrt(2) * hall_m
    err = np.linalg.norm(p - _circle(t), axis=1)
    assert err[inner].max() < math.sqrt(2) * hall_m
    # Everywhere, ends included, far inside the linear chord's sagitta (31 cm, below).
    assert radial.max() < 0.1 * R_M * (1 - math.cos(W_RPS / 2))
    # It passes through the keyframes.
    assert interp.position(tk) == pytest.approx(_circle(tk), abs=1e-9)


def test_linear_on_a_circle_has_the_chord_sagitta():
    tk = np.arange(0.0, 21.0)
    interp = fit_track(tk, _circle(tk), "linear")
    t = time_grid(0.0, 20.0, 20.0)
    radial = R_M - np.hypot(*interp.position(t).T)
    # Chord of angle W*h: midpoint lies R (1 - cos(W h / 2)) = 0.3109 m inside the circle.
    assert radial.max() == pytest.approx(R_M * (1 - math.cos(W_RPS / 2)), rel=1e-9)
    assert radial.min() == pytest.approx(0.0, abs=1e-9)


def test_speed_from_spline_derivative_on_circle():
    tk = np.arange(0.0, 21.0)
    interp = fit_track(tk, _circle(tk), "cubic")
    t = np.linspace(3.0, 17.0, 50)
    speed = np.linalg.norm(interp.velocity(t), axis=1)
    assert speed == pytest.approx(np.full(t.size, R_M * W_RPS), abs=0.02)
    accel = np.linalg.norm(interp.acceleration(t), axis=1)
    # Centripetal R W^2 = 2.5 m/s^2; Hall & Meyer (1976): |f'' - s''| <= 3/8 h^2 max|f''''|.
    assert accel == pytest.approx(np.full(t.size, R_M * W_RPS**2), abs=3 / 8 * R_M * W_RPS**4)


def test_slerp_across_the_wrap_goes_through_180_not_0():
    yaw = slerp_yaw([0.0, 1.0], np.radians([179.0, -179.0]), np.linspace(0.0, 1.0, 21))
    deg = np.degrees(yaw)
    assert abs(deg[10]) == pytest.approx(180.0, abs=1e-9)
    assert np.all(np.abs(deg) >= 179.0 - 1e-9)  # never near 0
    # Heading from 179 deg towards +181 (= -179): the angle grows through 180.
    unwrapped = np.degrees(np.unwrap(yaw))
    assert unwrapped[-1] - unwrapped[0] == pytest.approx(2.0, abs=1e-9)
    assert np.all(np.diff(unwrapped) > 0)


def test_slerp_is_linear_in_angle_and_takes_the_short_way():
    yaw = slerp_yaw([0.0, 2.0], np.radians([10.0, 50.0]), [0.5, 1.0, 1.5])
    assert np.degrees(yaw) == pytest.approx([20.0, 30.0, 40.0], abs=1e-9)
    # 350 deg -> 10 deg: 20 deg counter-clockwise through 0, not 340 deg the other way.
    yaw = slerp_yaw([0.0, 1.0], np.radians([350.0, 10.0]), [0.25, 0.5])
    assert np.degrees(yaw) == pytest.approx([-5.0, 0.0], abs=1e-9)
    assert slerp_yaw([3.0], [4.0], [3.0]) == pytest.approx([4.0 - 2 * math.pi])


def test_smoothing_matches_scipy_and_its_limits():
    rng = np.random.default_rng(1)
    t = np.cumsum(rng.uniform(0.8, 1.2, 12))
    xy = rng.normal(size=(12, 2))
    tt = np.linspace(t[0], t[-1], 300)
    for lam in (0.01, 0.5, 20.0):
        ours = _smooth(t, xy, lam)
        ref = make_smoothing_spline(t, xy, lam=lam, axis=0)
        assert ours(tt) == pytest.approx(ref(tt), abs=1e-9)
    # lam -> 0 interpolates; lam -> inf is the least-squares straight line.
    assert _smooth(t, xy, 1e-12)(t) == pytest.approx(xy, abs=1e-6)
    line = np.polyfit(t, xy, 1)
    assert _smooth(t, xy, 1e9)(t) == pytest.approx(
        np.polyval(line[:, 0], t)[:, None] * [1, 0] + np.polyval(line[:, 1], t)[:, None] * [0, 1],
        abs=1e-4,
    )


def test_smoothing_of_a_long_dense_track_is_banded():
    # 20 000 keyframes (13 min at 25 Hz): a dense (K-2)^2 system would need 3 GB; the
    # band solver matches scipy's own O(K) smoothing spline within float rounding.
    rng = np.random.default_rng(2)
    t = np.arange(20_000) / 25.0
    xy = np.column_stack([4.0 * t, np.sin(t)]) + rng.normal(0.0, 0.2, (t.size, 2))
    ours = _smooth(t, xy, 0.0625)
    ref = make_smoothing_spline(t, xy, lam=0.0625, axis=0)
    tt = np.linspace(t[0], t[-1], 4001)
    assert ours(tt) == pytest.approx(ref(tt), abs=1e-6)


def test_smoothing_keeps_a_noisy_rider_plausible():
    # A rider at 4 m/s along x, keyframes at 1 Hz with 0.3 m noise (camera jitter).
    rng = np.random.default_rng(7)
    tk = np.arange(0.0, 20.0)
    xy = np.column_stack([4.0 * tk, np.zeros(tk.size)]) + rng.normal(0.0, 0.3, (tk.size, 2))
    t = time_grid(0.0, 19.0, 20.0)
    limits = KinematicLimits(max_speed_mps=12.0, max_accel_mps2=1.0)
    smooth = fit_track(tk, xy, "smoothing", SmoothingParams(noise_m=0.3, limits=limits))
    cubic = fit_track(tk, xy, "cubic")
    a_smooth = np.linalg.norm(smooth.acceleration(t), axis=1).max()
    a_cubic = np.linalg.norm(cubic.acceleration(t), axis=1).max()
    assert a_smooth <= 1.0  # the limit is enforced by raising lam
    assert a_cubic > 2 * a_smooth  # the interpolating spline chases the noise
    # and the smoothed path is closer to the truth than the noisy keyframes are.
    truth = np.column_stack([4.0 * t, np.zeros(t.size)])
    err_smooth = np.sqrt(np.mean(np.sum((smooth.position(t) - truth) ** 2, axis=1)))
    err_cubic = np.sqrt(np.mean(np.sum((cubic.position(t) - truth) ** 2, axis=1)))
    assert err_smooth < err_cubic
    assert np.linalg.norm(smooth.velocity(t), axis=1) == pytest.approx(
        np.full(t.size, 4.0), abs=0.6
    )


def test_short_tracks_fall_back_to_linear_and_never_extrapolate():
    tk = np.array([0.0, 1.0, 2.0])
    xy = np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 0.0]])
    assert fit_track(tk, xy, "cubic").method == "linear"
    assert fit_track(tk[:2], xy[:2], "smoothing").method == "linear"
    assert fit_track(tk, xy, "smoothing").method == "smoothing"
    single = fit_track([5.0], [[1.0, 2.0]], "cubic")
    assert single.position([5.0]) == pytest.approx(np.array([[1.0, 2.0]]))
    assert single.velocity([5.0]) == pytest.approx(np.array([[0.0, 0.0]]))
    interp = fit_track(tk, xy, "linear")
    assert interp.position([1.5]) == pytest.approx(np.array([[1.5, 0.5]]))
    assert interp.velocity([1.5]) == pytest.approx(np.array([[1.0, -1.0]]))
    with pytest.raises(ValueError, match="never extrapolate"):
        interp.position([2.5])
    with pytest.raises(ValueError, match="strictly increasing"):
        fit_track([0.0, 0.0], [[0, 0], [1, 1]], "linear")
    with pytest.raises(ValueError, match="unknown interpolation"):
        fit_track(tk, xy, "quintic")


def test_gap_is_bridged_c1_without_extrapolating():
    # Keyframes 0..4 s and 8..12 s (a 4 s gap) on a straight line at 2 m/s: the Hermite
    # bridge between the two segments reproduces the line exactly (hand check).
    tk = np.concatenate([np.arange(0.0, 5.0), np.arange(8.0, 13.0)])
    xy = np.column_stack([2.0 * tk, 1.0 + 0.0 * tk])
    interp = fit_track_segmented(tk, xy, "cubic", max_gap_s=2.5)
    assert isinstance(interp, SegmentedInterpolant)
    assert len(interp.segments) == 2
    t = np.linspace(0.0, 12.0, 241)
    assert interp.position(t) == pytest.approx(
        np.column_stack([2.0 * t, np.ones(t.size)]), abs=1e-9
    )
    assert interp.velocity(t) == pytest.approx(np.tile([2.0, 0.0], (t.size, 1)), abs=1e-9)
    # A curved case: velocity is continuous at both ends of the gap.
    xy2 = np.column_stack([2.0 * tk, 0.05 * tk**2])
    interp2 = fit_track_segmented(tk, xy2, "smoothing", max_gap_s=2.5)
    for edge in (4.0, 8.0):
        left = interp2.velocity([edge - 1e-7])[0]
        right = interp2.velocity([edge + 1e-7])[0]
        assert left == pytest.approx(right, abs=1e-5)
    with pytest.raises(ValueError):
        interp2.position([12.5])
    # Without a long gap it is a plain interpolant.
    assert not isinstance(
        fit_track_segmented(tk[:5], xy[:5], "cubic", max_gap_s=2.5), SegmentedInterpolant
    )


def test_linear_gap_is_a_straight_line():
    tk = np.array([0.0, 1.0, 5.0, 6.0])
    xy = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 4.0], [1.0, 5.0]])
    interp = fit_track_segmented(tk, xy, "linear", max_gap_s=2.5)
    assert interp.position([3.0]) == pytest.approx(np.array([[1.0, 2.0]]))


def test_time_grid_stays_inside_the_span():
    assert time_grid(0.02, 0.31, 10.0) == pytest.approx([0.1, 0.2, 0.3])
    assert time_grid(1.0, 1.0, 20.0) == pytest.approx([1.0])
    assert time_grid(1.01, 1.04, 20.0).size == 0


def test_kalman_is_registered_and_equals_smoothing_for_the_same_noise():
    from vei.recon.interpolate import INTERP_METHODS, SmoothingParams, fit_track_segmented
    from vei.recon.smoother import KalmanInterpolant, NoiseEstimate

    assert "kalman" in INTERP_METHODS
    rng = np.random.default_rng(1)
    t = np.arange(12.0)
    xy = np.column_stack([1.5 * t, 0.1 * t**2]) + rng.normal(0, 0.2, (12, 2))
    params = SmoothingParams(noise_m=0.2, accel_psd_m2ps3=0.5)
    k = fit_track(t, xy, "kalman", params)
    s = fit_track(t, xy, "smoothing", SmoothingParams(0.2, 0.5, max_refits=0))
    assert isinstance(k, KalmanInterpolant) and k.method == "kalman"
    q = np.linspace(0, 11, 45)
    assert k.position(q) == pytest.approx(s.position(q), abs=2e-3)
    assert k.lam == pytest.approx(s.lam)
    # Never split at gaps (its posterior bridges them, with a wider band in the gap).
    tg = np.r_[t[:5], t[5:] + 4.0]
    seg = fit_track_segmented(tg, xy, "kalman", params, max_gap_s=2.5)
    assert isinstance(seg, KalmanInterpolant)
    std = seg.std(np.array([3.0, 6.5]))
    assert std[1] > 2 * std[0]
    # An explicit noise estimate wins over the SmoothingParams.
    est = NoiseEstimate(0.05, 2.0, method="ml")
    assert fit_track(t, xy, "kalman", params, noise=est).noise is est
    # One keyframe: a single point, as for the other methods.
    assert fit_track(t[:1], xy[:1], "kalman").method == "linear"
