"""Rider tracks from the camera trajectories: smoothing, segmenting, the filter rule."""

from __future__ import annotations

import numpy as np
import pytest

from vei.calibrate import tracks as T
from vei.errors import InputError


def test_smoothing_recovers_speed_and_acceleration_of_a_noisy_track() -> None:
    # 3 m/s + 0.5 m/s^2 along x, 0.3 m Gaussian jitter (the camera's order), 30 fps, 8 s.
    rng = np.random.default_rng(1)
    frames = np.arange(240)
    t = frames / 30.0
    x = 3.0 * t + 0.25 * t**2 + rng.normal(0, 0.3, t.size)
    y = 2.0 + rng.normal(0, 0.3, t.size)
    out = T.smooth_segment(frames, x, y, 0.05)
    assert out is not None
    ts, xs, ys, vx, vy, ax, ay = out
    assert ts[0] == 0.0 and ts[-1] == pytest.approx(7.95)  # 20 Hz grid inside the segment
    inner = (ts > 1.0) & (ts < 7.0)
    truth_v = 3.0 + 0.5 * ts
    assert np.sqrt(np.mean((vx[inner] - truth_v[inner]) ** 2)) < 0.35
    assert np.abs(vy[inner]).mean() < 0.3
    assert np.median(ax[inner]) == pytest.approx(0.5, abs=0.4)
    # Raw finite differences of the same track are useless (jitter / dt): the reason to smooth.
    raw = np.diff(x) * 30.0
    assert np.std(raw - 3.0 - 0.5 * t[:-1]) > 5.0


def test_segments_split_at_long_gaps_only() -> None:
    frames = np.r_[np.arange(0, 100), np.arange(110, 200), np.arange(300, 400)]
    segs = T._segments(frames)
    # 10 frames (0.33 s) are bridged; 100 frames (3.3 s) split.
    assert segs == [(0, 190), (190, 290)]


def test_keep_rule() -> None:
    dt = 0.05
    t = np.arange(0, 4.0, dt)
    x = 2.0 * t
    sp = np.full(t.size, 2.0)
    assert T._keep_reason(t, x, 0 * x, sp, dt) is None
    assert "shorter" in T._keep_reason(t[:40], x[:40], 0 * x[:40], sp[:40], dt)
    assert "travels" in T._keep_reason(t, 0.5 * x, 0 * x, sp, dt)
    assert "moves" in T._keep_reason(t, x, 0 * x, np.where(t < 3.5, 0.1, 2.0), dt)


def test_real_scenes(tm_scenes) -> None:
    by = {s.scenario: s for s in tm_scenes}
    assert len(by) == 9
    # The two scenarios without riders and the e-scooters of stadtmitte_12.
    assert not by["marktkauf_04_audi_rechtsabbiegen"].riders
    assert not by["marktkauf_05_klinikum_geradeaus"].riders
    st12 = by["stadtmitte_12_audi_geradeaus_03"]
    scooters = [r for r in st12.riders if r.category == "escooter"]
    assert {r.track_id for r in scooters} >= {"81"}
    r81 = next(r for r in scooters if r.track_id == "81")
    # PROVENANCE: the tracks labelled scooter move at 0.7-1.7 m/s median.
    assert 0.7 <= r81.median_moving_speed_mps() <= 1.7
    # The instrumented car is among the moving vehicles (relevant_track_id 9 there).
    assert st12.vehicles.ids[st12.vehicles.ego_index] == "9"
    for s in tm_scenes:
        for r in s.riders:
            assert r.duration_s >= T.MIN_DURATION_S
            assert np.all(np.diff(r.t_s) > 0)
            assert np.sum(np.hypot(np.diff(r.x_m), np.diff(r.y_m))) >= T.MIN_PATH_M
        # Every dropped rider track names its reason.
        assert all(isinstance(v, str) and v for v in s.dropped.values())
    n_riders = sum(len(s.riders) for s in tm_scenes)
    assert 10 <= n_riders <= 40


def test_missing_file_is_an_input_error(tmp_path) -> None:
    with pytest.raises(InputError, match="data/measurements"):
        T.load_scene(tmp_path, "nothing")
