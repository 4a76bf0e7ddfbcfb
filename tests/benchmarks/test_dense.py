"""benchmarks.recon_research.dense: the 1 s windowed speed of keyframe positions."""

from __future__ import annotations

import numpy as np
import pytest
from benchmarks.recon_research.dense import curve_truth, synthetic_rmse, windowed_speed


def test_windowed_speed_by_hand():
    t = np.arange(0.0, 3.0 + 1e-9, 0.1)
    xy = np.column_stack([3.0 * t, np.zeros_like(t)])  # 3 m/s along x
    v = windowed_speed(t, xy)
    assert v.size == 21 and v == pytest.approx(np.full(21, 3.0))  # t = 0 .. 2 s
    # Accelerating from rest at 2 m/s^2: the mean speed over [t, t + 1] is 2 t + 1.
    xy = np.column_stack([t**2, np.zeros_like(t)])
    assert windowed_speed(t, xy) == pytest.approx(2.0 * t[:21] + 1.0)
    # A 4 s tracking gap splits the track (> 2.5 s); the part after it lasts 0.2 s and
    # gives its mean speed 1 m / 0.2 s; the gap itself gives no speed.
    t2 = np.r_[t, 7.0, 7.1, 7.2]
    xy2 = np.r_[xy, [[50.0, 0.0], [50.5, 0.0], [51.0, 0.0]]]
    v2 = windowed_speed(t2, xy2)
    assert v2.size == 22 and v2[-1] == pytest.approx(5.0) and v2.max() == pytest.approx(5.0)
    assert windowed_speed([1.0], [[0.0, 0.0]]).size == 0


def test_curve_and_synthetic_rmse():
    t = np.linspace(0.0, 5.0, 11)
    xy = curve_truth(t)
    step = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert step == pytest.approx(np.full(10, 2.0), rel=1e-3)  # 4 m/s x 0.5 s, chords
    r = synthetic_rmse(0.2, seed=1)
    assert r["smoothing"] < 0.3 < 3.0 < r["cubic"]
