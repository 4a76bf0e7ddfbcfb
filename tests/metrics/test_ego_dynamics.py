"""Worst yaw step, yaw rate and lateral acceleration of the ego: hand-computed traces."""

from __future__ import annotations

import numpy as np
import pytest

from tests.metrics.helpers import make_trace
from vei.metrics import get_metric, summarize


def _circle(v: float, radius: float, n: int = 50, dt: float = 0.1):
    # Ego on a circle of radius R at speed v: yaw rate v / R, lateral acceleration v^2 / R.
    t = np.arange(n) * dt
    th = v * t / radius
    xy = np.column_stack([radius * np.sin(th), radius * (1 - np.cos(th))])
    return make_trace(ego_xy=xy, other_xy=(100.0, 0.0), ego_speed=v, ego_yaw=th, dt=dt)


def test_circle_gives_v_over_r_and_v2_over_r() -> None:
    tr = _circle(8.0, 20.0)
    assert get_metric("ego_max_yaw_rate_radps").compute(tr)[0] == pytest.approx(0.4)
    assert get_metric("ego_max_lat_accel_mps2").compute(tr)[0] == pytest.approx(3.2)
    assert get_metric("ego_max_yaw_step_rad").compute(tr)[0] == pytest.approx(0.04)


def test_a_kink_shows_as_a_yaw_step_and_wraps_across_pi() -> None:
    # 1.21 rad in one 0.05 s step at 8.3 m/s (the old run-up junction): 24 rad/s, 201 m/s^2.
    yaw = np.concatenate([np.full(10, 0.48), np.full(10, 0.48 + 1.21)])
    tr = make_trace(ego_xy=(0.0, 0.0), other_xy=(9.0, 0.0), ego_speed=8.3, ego_yaw=yaw, dt=0.05)
    assert get_metric("ego_max_yaw_step_rad").compute(tr)[0] == pytest.approx(1.21)
    assert get_metric("ego_max_yaw_rate_radps").compute(tr)[0] == pytest.approx(24.2)
    assert get_metric("ego_max_lat_accel_mps2").compute(tr)[0] == pytest.approx(24.2 * 8.3)
    # Heading crossing +-pi is not a step.
    wrap = np.array([np.pi - 0.01, -np.pi + 0.01])
    tr2 = make_trace(ego_xy=(0.0, 0.0), other_xy=(9.0, 0.0), ego_speed=1.0, ego_yaw=wrap)
    assert get_metric("ego_max_yaw_step_rad").compute(tr2)[0] == pytest.approx(0.02)
    assert "ego_max_lat_accel_mps2" in summarize(tr2).columns
