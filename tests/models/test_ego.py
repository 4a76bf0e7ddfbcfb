"""Ego models: path table, PID, actuator, d_safe, braking laws, corridor, CAP machine."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.errors import InputError
from vei.models import ego


def test_path_on_a_circle_projection_and_heading() -> None:
    r = 20.0
    th = np.linspace(0.0, math.pi, 400)
    path = ego.build_path(r * np.cos(th), r * np.sin(th))
    assert path.length_m == pytest.approx(math.pi * r, abs=0.1)
    # Point at angle 60 deg, 2 m outside the circle (right of the CCW direction).
    a = math.radians(60)
    s, lat = ego.project_onto_path(path, 22 * math.cos(a), 22 * math.sin(a), s_guess_m=r * a - 1.0)
    assert float(s) == pytest.approx(r * a, abs=0.02)
    assert float(lat) == pytest.approx(-2.0, abs=0.02)
    x, y, yaw = path.lookup(r * a)
    assert (float(x), float(y)) == pytest.approx((r * math.cos(a), r * math.sin(a)), abs=0.01)
    assert float(yaw) == pytest.approx(a + math.pi / 2, abs=0.01)
    # Beyond the end the table continues straight along the final heading (-x; the chord
    # over the last 0.5 m, 0.0125 rad off on this circle: 0.125 m lateral after 10 m).
    x, y, _ = path.lookup(path.length_m + 10.0)
    assert (float(x), float(y)) == pytest.approx((-20.0, -10.0), abs=0.15)


def test_path_rejects_bad_input() -> None:
    with pytest.raises(InputError):
        ego.build_path([0.0, np.nan], [0.0, 1.0])


def test_median_moving_speed() -> None:
    assert ego.median_moving_speed_mps([0.0, 0.1, 5.0, 6.0, 7.0, 0.2]) == 6.0
    with pytest.raises(InputError):
        ego.median_moving_speed_mps([0.0, 0.1])


def test_pid_step_hand_values() -> None:
    st = ego.PIDState.initial(np.array([1.0]))
    u, st = ego.pid_step(st, np.array([1.0]), 0.05, 0.05, 0.05, 0.05)
    assert float(u[0]) == pytest.approx(0.05 * 1.0 + 0.05 * 0.05 + 0.0)
    u, st = ego.pid_step(st, np.array([0.5]), 0.05, 0.05, 0.05, 0.05)
    assert float(u[0]) == pytest.approx(0.05 * 0.5 + 0.05 * (0.05 + 0.025) + 0.05 * (-0.5 / 0.05))
    # Leaky integral: I = I exp(-dt / window) + e dt.
    st = ego.PIDState(np.array([1.0]), np.array([0.0]))
    _, st2 = ego.pid_step(st, np.array([0.0]), 0.05, integral_window_s=0.5)
    assert float(st2.integral_m[0]) == pytest.approx(math.exp(-0.1))
    # Saturation at +-1.
    u, _ = ego.pid_step(ego.PIDState.initial(np.array([100.0])), np.array([100.0]), 0.05)
    assert float(u[0]) == 1.0


def test_command_mapping_and_actuator_lag() -> None:
    a = ego.command_to_accel(np.array([1.0, 0.5, -0.5, -1.0]), 3.0, 8.0)
    assert a == pytest.approx([3.0, 1.5, -4.0, -8.0])
    assert ego.accel_to_command(a, 3.0, 8.0) == pytest.approx([1.0, 0.5, -0.5, -1.0])
    assert float(ego.accel_to_command(-20.0, 3.0, 8.0)) == -1.0
    # First-order lag, exact discretisation: a' = a + (1 - exp(-dt / tau)) (a_cmd - a).
    assert float(ego.actuator_step(0.0, -6.0, 0.2, 0.05)) == pytest.approx(
        -6.0 * (1 - math.exp(-0.25))
    )
    assert float(ego.actuator_step(0.0, -6.0, 0.0, 0.05)) == -6.0
    assert float(ego.speed_step(0.1, -6.0, 0.05)) == 0.0


def _settle(v0: float, vd: float, seconds: float) -> float:
    v, a = np.array([v0]), np.array([0.0])
    pid = ego.PIDState.initial(vd - v)
    for _ in range(int(round(seconds / 0.05))):
        u, pid = ego.pid_step(pid, vd - v, 0.05, 0.05, 0.05, 0.05, 1.0, 0.5)
        a = ego.actuator_step(a, ego.command_to_accel(u, 3.0, 8.0), 0.2, 0.05)
        v = ego.speed_step(v, a, 0.05)
    return float(v[0])


def test_pid_settles_at_cruise_speed() -> None:
    # Paper gains, default actuator: from standstill and from above.
    assert _settle(0.0, 5.6, 60.0) == pytest.approx(5.6, abs=0.005)
    assert _settle(9.0, 5.6, 60.0) == pytest.approx(5.6, abs=0.005)
    # Still on its way after 5 s (time constant ~4.5 s): no bang-bang.
    assert 2.5 < _settle(0.0, 5.6, 5.0) < 4.5


def test_safe_distance_hand_values() -> None:
    d = ego.safe_distance(np.array([0.0, 5.6, 20.0, 30.0]), 2.0, 3.0, -6.0)
    # max(v^2 / 12, 2 v) + 3: 3; max(2.613, 11.2) + 3; max(33.3, 40) + 3; max(75, 60) + 3.
    assert d == pytest.approx([3.0, 14.2, 43.0, 78.0])


def test_braking_laws_hand_values() -> None:
    # Gap law at the trigger (d = d_safe = 14.2 at 5.6 m/s): -5.6^2 / (2 * 11.2) = -1.4.
    assert float(ego.gap_braking_accel(5.6, 14.2, 3.0, -6.0)) == pytest.approx(-1.4)
    # Saturation at a_min; inside the buffer full braking; standing still: 0.
    assert float(ego.gap_braking_accel(5.6, 4.0, 3.0, -6.0)) == -6.0
    assert float(ego.gap_braking_accel(5.6, 2.0, 3.0, -6.0)) == -6.0
    assert float(ego.gap_braking_accel(0.0, 2.0, 3.0, -6.0)) == 0.0
    # Paper per step: -v / (2 T_safe) at urban speed, equal to the gap law at the trigger.
    assert float(ego.paper_braking_accel(5.6, 2.0, 3.0, -6.0)) == pytest.approx(-1.4)
    assert float(ego.paper_braking_accel(2.8, 2.0, 3.0, -6.0)) == pytest.approx(-0.7)


def _straight_path() -> ego.PathTable:
    x = np.linspace(0.0, 200.0, 2001)
    return ego.build_path(x, np.zeros_like(x))


def test_corridor_check() -> None:
    path = _straight_path()
    # Ego centre at s = 10 (front bumper at 12.35); riders: crossing ahead at 30 m, out of
    # the corridor laterally, behind, along-heading ahead, inactive.
    rx = np.array([30.0, 30.0, 5.0, 30.0, 30.0])
    ry = np.array([1.0, 4.0, 0.0, 0.0, 0.0])
    ryaw = np.array([math.pi / 2, math.pi / 2, 0.0, 0.0, 0.0])
    active = np.array([True, True, True, True, False])
    ahead, gap = ego.corridor_check(
        path, np.full(5, 10.0), 4.7, rx, ry, ryaw, 1.2, 0.6, active, 3.5, 60.0
    )
    assert ahead.tolist() == [True, False, False, True, False]
    assert gap[0] == pytest.approx(30.0 - 12.35 - 0.3)  # crossing: half its width along the path
    assert gap[3] == pytest.approx(30.0 - 12.35 - 0.6)  # riding along: half its length
    assert np.isinf(gap[[1, 2, 4]]).all()


def test_cap_state_machine_transitions() -> None:
    C, B, R = ego.CRUISE, ego.BRAKE, ego.RECOVER
    st = np.array([C, C, B, B, R, R], dtype=np.int8)
    v = np.array([5.6, 5.6, 3.0, 3.0, 5.5, 4.0])
    ahead = np.array([True, True, True, False, False, True])
    gap = np.array([14.0, 14.5, 10.0, np.inf, np.inf, 5.0])
    new, a, braking, entered = ego.cap_step(st, v, 5.6, ahead, gap)
    # 0: 14.0 < d_safe 14.2 -> BRAKE; 1: 14.5 > 14.2 -> stays CRUISE; 2: stays BRAKE;
    # 3: rider gone -> RECOVER; 4: |5.5 - 5.6| <= 0.2 -> CRUISE; 5: d < d_safe -> BRAKE.
    assert new.tolist() == [B, C, B, R, C, B]
    assert braking.tolist() == [True, False, True, False, False, True]
    assert entered.tolist() == [False, False, False, True, False, False]
    assert a[0] == pytest.approx(-(5.6**2) / (2 * 11.0))
    assert a[2] == pytest.approx(-9.0 / (2 * 7.0))
    assert a[5] == pytest.approx(-16.0 / (2 * 2.0))
    assert a[[1, 3, 4]].tolist() == [0.0, 0.0, 0.0]
    # Release by distance: BRAKE with d > d_safe + margin.
    new, *_ = ego.cap_step(
        np.array([B], dtype=np.int8), np.array([1.0]), 5.6, np.array([True]), np.array([20.0])
    )
    assert new.tolist() == [R]
    # The paper's per-step law in BRAKE ignores the gap.
    _, a, _, _ = ego.cap_step(
        np.array([B], dtype=np.int8),
        np.array([4.0]),
        5.6,
        np.array([True]),
        np.array([5.0]),
        paper_per_step=True,
    )
    assert float(a[0]) == pytest.approx(-1.0)
