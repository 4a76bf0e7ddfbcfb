"""vei.recon.accuracy on hand-computed cases: the Savitzky-Golay reference, error figures
and the 95 % coverage rule."""

import numpy as np
import pandas as pd
import pytest

from vei.geo.frame import LocalFrame
from vei.recon.accuracy import CHI2_2DOF_95, denoise_ground_truth, evaluate, track_errors
from vei.recon.smoother import KalmanInterpolant, NoiseEstimate


def test_savitzky_golay_keeps_a_parabola_and_removes_jitter():
    t = np.arange(0, 4, 1 / 30)
    xy = np.column_stack([0.5 * t**2, 3.0 * t])  # order 2: reproduced exactly
    assert denoise_ground_truth(t, xy) == pytest.approx(xy, abs=1e-9)
    rng = np.random.default_rng(0)
    noisy = xy + rng.normal(0, 0.3, xy.shape)
    den = denoise_ground_truth(t, noisy)
    inner = slice(15, -15)
    assert np.sqrt(np.mean((den - xy)[inner] ** 2)) < 0.12  # 31-frame window: ~0.3 / sqrt(12)


def test_savitzky_golay_fills_short_gaps_and_splits_long_ones():
    t = np.arange(0, 3, 1 / 30)
    keep = (t < 1.0) | (t > 1.3)  # a 0.3 s gap: filled, one run
    xy = np.column_stack([3.0 * t + 1.0, -t])  # linear: the linear fill is exact too
    out = denoise_ground_truth(t[keep], xy[keep])
    assert out == pytest.approx(xy[keep], abs=1e-9)
    # A 1 s gap splits; a run of 4 samples (< polyorder + 3) stays raw.
    t2 = np.r_[np.arange(0, 2, 1 / 30), 3.0 + np.arange(4) / 30]
    xy2 = np.column_stack([np.sin(t2), np.cos(t2)]) + 0.01 * np.arange(t2.size)[:, None] % 0.02
    out2 = denoise_ground_truth(t2, xy2)
    assert out2[-4:] == pytest.approx(xy2[-4:])


def test_track_errors_and_coverage_by_hand():
    est = np.zeros((4, 2))
    gt = np.array([[0.3, 0.4], [0.0, 1.0], [0.0, 0.0], [2.0, 0.0]])  # distances 0.5, 1, 0, 2
    e = track_errors(est, gt, gt, std_m=np.full(4, 0.5), noise_m=0.0)
    assert e["rmse_m"] == pytest.approx(np.sqrt((0.25 + 1 + 0 + 4) / 4))
    assert e["max_m"] == pytest.approx(2.0)
    # d^2 / 0.25 = 1, 4, 0, 16 against 5.991: three of four inside.
    assert e["coverage_sg"] == pytest.approx(0.75)
    assert CHI2_2DOF_95 == pytest.approx(5.991, abs=1e-3)
    # The raw region adds the keyframe noise: sigma 1 m takes the 2 m point in too.
    assert track_errors(est, gt, gt, np.full(4, 0.5), noise_m=1.0)["coverage_raw"] == 1.0


def test_evaluate_reports_coverage_for_kalman_tracks():
    frame = LocalFrame(48.0, 11.0)
    t = np.arange(0, 10, 1 / 30)
    x, y = 2.0 * t, 0.2 * np.sin(t)
    lat, lon = frame.to_latlon(x, y)
    gt = pd.DataFrame(
        {"t_s": t, "track_id": "1", "category": "cyclist", "lat_deg": lat, "lon_deg": lon}
    )
    tk = np.arange(0.0, 10.0)
    kf = pd.DataFrame(
        {
            "t_s": tk,
            "agent_id": "cyclist_1",
            "source_track_id": "1",
            "category": "cyclist",
            "x_m": 2.0 * tk,
            "y_m": 0.2 * np.sin(tk),
        }
    )
    interp = KalmanInterpolant(tk, kf[["x_m", "y_m"]].to_numpy(), NoiseEstimate(0.1, 1.0))
    res = evaluate(gt, frame, kf, {"cyclist_1": interp})
    tr = res["tracks"][0]
    assert tr["n_samples"] == 271  # ground truth inside [0, 9] s
    assert tr["rmse_m"] < 0.1 and tr["keyframe_rmse_sg_m"] < 0.01
    assert 0.9 <= tr["coverage_sg"] <= 1.0
    assert res["riders"]["coverage_sg"] == pytest.approx(tr["coverage_sg"])
