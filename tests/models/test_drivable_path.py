"""Drivable ego path: hand-made paths with known heading and curvature."""

from __future__ import annotations

import numpy as np
import pytest

from vei.errors import InputError
from vei.models.drivable_path import (
    build_ego_path,
    decimate_standstill,
    path_curvature,
    recorded_arc_length,
)


def _standstill_then_straight(heading: float, jitter_m: float = 0.01, seed: int = 3):
    """20 s of standstill jitter (as a GPS receiver at a red light), then 40 m straight."""
    rng = np.random.default_rng(seed)
    jitter = rng.normal(0.0, jitter_m, size=(400, 2))
    s = np.arange(1, 101) * 0.4
    drive = np.column_stack([s * np.cos(heading), s * np.sin(heading)])
    xy = np.vstack([jitter, drive])
    return xy[:, 0], xy[:, 1]


def test_initial_heading_comes_from_the_motion_not_the_standstill_jitter() -> None:
    heading = 1.95
    x, y = _standstill_then_straight(heading)
    path, info = build_ego_path(x, y, yaw_hint_rad=0.3, path_speed_mps=8.3)
    assert info.method == "spline"
    assert info.initial_yaw_rad == pytest.approx(heading, abs=0.01)
    # The run-up (s < 0) continues the path straight along that heading: no kink.
    xs, ys, yaws = path.lookup(np.array([-50.0, -10.0, 0.0, 5.0]))
    assert yaws == pytest.approx(np.full(4, heading), abs=0.01)
    d = np.hypot(xs[1] - xs[0], ys[1] - ys[0])
    assert np.arctan2(ys[1] - ys[0], xs[1] - xs[0]) == pytest.approx(info.initial_yaw_rad, abs=1e-9)
    assert d == pytest.approx(40.0, abs=1e-6)
    # Heading is continuous over the whole table: the largest change per 0.1 m cell is
    # far below a kink (1.21 rad in the old table on the real recording).
    assert np.abs(np.diff(path.yaw_rad)).max() < 0.01
    assert info.max_deviation_m < 0.1  # the jitter itself reaches ~4 cm


def test_standstill_jitter_collapses_to_one_point() -> None:
    x, y = _standstill_then_straight(0.0)
    keep = decimate_standstill(x, y, 0.5)
    assert keep[0] == 0
    assert np.all(keep[1:] >= 400)  # no jitter sample survives (radius 1 cm << 0.5 m)
    s = recorded_arc_length(build_ego_path(x, y, yaw_hint_rad=0.0, path_speed_mps=8.0)[0], x, y)
    assert np.all(np.diff(s) >= 0)
    assert s[:400] == pytest.approx(np.zeros(400), abs=0.05)
    assert s[-1] == pytest.approx(40.0, abs=0.05)


def test_a_drivable_arc_keeps_its_curvature() -> None:
    # Radius 25 m quarter circle (kappa 0.04 1/m) with 2 cm noise; at 8 m/s the bound is
    # 4 / 64 = 0.0625 1/m, so the spline only removes the noise.
    rng = np.random.default_rng(0)
    th = np.linspace(0.0, np.pi / 2, 200)
    x = 25.0 * np.sin(th) + rng.normal(0, 0.02, th.size)
    y = 25.0 * (1.0 - np.cos(th)) + rng.normal(0, 0.02, th.size)
    path, info = build_ego_path(x, y, yaw_hint_rad=0.0, path_speed_mps=8.0)
    k = path_curvature(path)
    mid = k[k.size // 4 : 3 * k.size // 4]
    assert np.median(mid) == pytest.approx(0.04, rel=0.05)
    assert info.max_curvature_per_m <= info.kappa_max_per_m == pytest.approx(0.0625)
    assert info.max_deviation_m < 0.1
    # Natural end conditions (zero curvature at both ends, so the straight extensions join
    # without a curvature step) straighten the first and last ~1.5 m of the arc: the end
    # tangents differ from the circle's by about kappa * 1.5 m = 0.06 rad.
    assert info.initial_yaw_rad == pytest.approx(0.0, abs=0.07)
    assert info.final_yaw_rad == pytest.approx(np.pi / 2, abs=0.07)


def test_a_tight_corner_is_smoothed_to_the_lateral_acceleration_bound() -> None:
    # A right-angle corner with a 5 m radius (kappa 0.2): at 8 m/s that is 12.8 m/s^2.
    # The path is smoothed until kappa <= 4 / 8^2 = 0.0625 (radius 16 m); the corner is
    # cut by decimetres to metres, reported as the deviation.
    a = np.column_stack([np.linspace(-40, -5, 80), np.zeros(80)])
    th = np.linspace(0, np.pi / 2, 30)
    arc = np.column_stack([-5 + 5 * np.sin(th), 5 - 5 * np.cos(th)])
    b = np.column_stack([np.zeros(80), np.linspace(5, 40, 80)])
    xy = np.vstack([a, arc[1:-1], b])
    path, info = build_ego_path(xy[:, 0], xy[:, 1], yaw_hint_rad=0.0, path_speed_mps=8.0)
    k = np.abs(path_curvature(path, recorded_only=False))
    assert k.max() <= 0.0625 + 1e-9
    assert k.max() > 0.05  # not smoothed further than needed
    # Replacing the 5 m corner radius by 16 m cuts the apex by at least
    # (16 - 5)(sqrt 2 - 1) = 4.6 m; one smoothing parameter for the whole path costs ~1 m
    # more and bends the straight legs slightly (their end headings move by ~0.09 rad).
    assert (16.0 - 5.0) * (np.sqrt(2.0) - 1.0) <= info.max_deviation_m < 6.5
    # Lateral acceleration at 8 m/s within 4 m/s^2 everywhere; the heading still turns.
    assert (k * 64.0).max() <= 4.0 + 1e-9
    assert info.final_yaw_rad - info.initial_yaw_rad == pytest.approx(np.pi / 2, abs=0.2)


def test_a_standing_vehicle_uses_the_heading_hint() -> None:
    rng = np.random.default_rng(1)
    x, y = rng.normal(0, 0.01, 100), rng.normal(0, 0.01, 100)
    path, info = build_ego_path(x, y, yaw_hint_rad=1.0, path_speed_mps=5.0)
    assert info.method == "standing" and path.length_m == 0.0
    _, _, yaw = path.lookup(np.array([-20.0, 20.0]))
    assert yaw == pytest.approx([1.0, 1.0])


def test_bad_inputs_are_input_errors() -> None:
    with pytest.raises(InputError):
        build_ego_path([0.0, np.nan], [0.0, 1.0], yaw_hint_rad=0.0, path_speed_mps=5.0)
    with pytest.raises(InputError):
        build_ego_path([0.0, 1.0], [0.0, 1.0], yaw_hint_rad=0.0, path_speed_mps=0.0)
