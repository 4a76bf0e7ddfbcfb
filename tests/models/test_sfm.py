"""Social forces against hand-computed values; point mass against the analytic solution."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.models import sfm


def test_desired_velocity_normalised_and_paper_forms() -> None:
    # Goal 5 m away along (3, 4); v0 = 5, sigma = 1.
    vx, vy = sfm.desired_velocity(0.0, 0.0, 3.0, 4.0, 5.0, 1.0)
    assert (float(vx), float(vy)) == pytest.approx((5 * 3 / math.sqrt(26), 5 * 4 / math.sqrt(26)))
    # The paper's literal form: v0 (g - p) / (|g - p|^2 + sigma^2).
    vx, vy = sfm.desired_velocity(0.0, 0.0, 3.0, 4.0, 5.0, 1.0, paper_form=True)
    assert (float(vx), float(vy)) == pytest.approx((15 / 26, 20 / 26))
    # Far from the goal the normalised speed tends to v0; at the goal it is 0.
    vx, vy = sfm.desired_velocity(0.0, 0.0, 1000.0, 0.0, 5.0, 1.0)
    assert float(vx) == pytest.approx(5.0, rel=1e-6)
    vx, vy = sfm.desired_velocity(2.0, 3.0, 2.0, 3.0, 5.0, 1.0)
    assert (float(vx), float(vy)) == (0.0, 0.0)
    # Batched with a per-variant form switch.
    vx, _ = sfm.desired_velocity(
        0.0, 0.0, np.array([3.0, 3.0]), 4.0, 5.0, 1.0, np.array([False, True])
    )
    assert vx == pytest.approx([15 / math.sqrt(26), 15 / 26])


def test_destination_force() -> None:
    fx, fy = sfm.destination_force(4.0, 1.0, 3.0, -1.0, 100.0)
    assert (float(fx), float(fy)) == pytest.approx((100.0, 200.0))


def test_vehicle_force_hand_value() -> None:
    # A = 100 N, b = 3.5 1/m, rider 2 m from the influential point along +x.
    fx, fy = sfm.vehicle_force(2.0, 0.0, 0.0, 0.0, 100.0, 3.5)
    assert float(fx) == pytest.approx(100.0 * math.exp(-7.0))
    assert float(fy) == 0.0
    # Direction from q to p at 45 degrees, d = sqrt(2).
    fx, fy = sfm.vehicle_force(1.0, 1.0, 0.0, 0.0, 100.0, 3.5)
    mag = 100.0 * math.exp(-3.5 * math.sqrt(2))
    assert (float(fx), float(fy)) == pytest.approx((mag / math.sqrt(2), mag / math.sqrt(2)))


def test_influential_point_options() -> None:
    # Ego at the origin heading +x, 4.7 x 1.85; rider at (5, 0.3).
    qx, qy = sfm.influential_point(5.0, 0.3, 0.0, 0.0, 0.0, 4.7, 1.85)
    assert (float(qx), float(qy)) == pytest.approx((2.35, 0.3))
    qx, qy = sfm.influential_point(5.0, 0.3, 0.0, 0.0, 0.0, 4.7, 1.85, front_bumper=True)
    assert (float(qx), float(qy)) == pytest.approx((2.35, 0.0))
    # Rider beside the car: the closest box point is on the side.
    qx, qy = sfm.influential_point(0.5, 3.0, 0.0, 0.0, 0.0, 4.7, 1.85)
    assert (float(qx), float(qy)) == pytest.approx((0.5, 0.925))


def test_social_force_total_and_switches() -> None:
    kw = dict(k_des_nspm=100.0, v0_mps=5.0, sigma_m=1.0, a_veh_n=100.0, b_veh_per_m=3.5)
    # Rider at (5, 0) at rest, goal (10, 0): v_des = 5 * 5 / sqrt(26); car box ends at x = 2.35.
    fx, fy = sfm.social_force(5.0, 0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 0.0, 4.7, 1.85, **kw)
    f_des = 100.0 * 25.0 / math.sqrt(26)
    f_veh = 100.0 * math.exp(-3.5 * 2.65)
    assert float(fx) == pytest.approx(f_des + f_veh)
    assert float(fy) == pytest.approx(0.0)
    fx, _ = sfm.social_force(
        5.0, 0.0, 0.0, 0.0, 10.0, 0.0, 0.0, 0.0, 0.0, 4.7, 1.85, use_vehicle_force=False, **kw
    )
    assert float(fx) == pytest.approx(f_des)


def test_point_mass_constant_force_matches_analytic_solution() -> None:
    # Semi-implicit Euler: v_n = v0 + a t exactly; x_n = x0 + v0 t + a t^2 / 2 + a t dt / 2.
    m, dt, n = 95.0, 0.05, 200
    f = np.array([2.0, -1.0])
    a = f / m
    p = np.array([1.0, -2.0])
    v = np.array([1.0, 0.5])
    p0, v0 = p.copy(), v.copy()
    for _ in range(n):
        px, py, vx, vy = sfm.point_mass_step(p[0], p[1], v[0], v[1], f[0], f[1], m, dt)
        p, v = np.array([px, py]), np.array([vx, vy])
    t = n * dt
    analytic = p0 + v0 * t + 0.5 * a * t * t
    assert v == pytest.approx(v0 + a * t, abs=1e-12)
    assert p - analytic == pytest.approx(a * t * dt / 2, abs=1e-12)
    # The error bound |a| t dt / 2 vanishes with dt: halving dt halves the error.
    assert np.abs(p - analytic).max() <= np.abs(a).max() * t * dt / 2 + 1e-12


def _ride_past_standing_car(use_vehicle_force: bool, k_des: float) -> np.ndarray:
    """Rider from (-10, 1.5) towards (20, 1.5) past a car standing at the origin (heading +x)."""
    x, y, vx, vy = -10.0, 1.5, 5.0, 0.0
    ys = []
    for _ in range(120):
        fx, fy = sfm.social_force(
            x, y, vx, vy, 20.0, 1.5, 0.0, 0.0, 0.0, 4.7, 1.85,
            k_des_nspm=k_des, v0_mps=5.0, sigma_m=1.0, a_veh_n=100.0, b_veh_per_m=3.5,
            use_vehicle_force=use_vehicle_force,
        )  # fmt: skip
        x, y, vx, vy = (float(q) for q in sfm.point_mass_step(x, y, vx, vy, fx, fy, 95.0, 0.05))
        ys.append(y)
    return np.array(ys)


def test_aggressive_rider_ignores_the_car_normal_rider_deviates() -> None:
    aggressive = _ride_past_standing_car(False, 200.0)
    normal = _ride_past_standing_car(True, 100.0)
    assert np.all(aggressive == 1.5)  # no lateral force at all
    assert normal.max() > 1.5 + 0.01  # pushed away from the car (to +y)
    assert normal.min() >= 1.5 - 1e-9


def test_speed_from_recording_by_hand() -> None:
    # 10 standing samples, 50 at 2 m/s, one at 3 m/s: median moving speed 2 m/s.
    speeds = np.r_[np.zeros(10), np.full(50, 2.0), 3.0, np.nan]
    v0, vmax = sfm.speed_from_recording(speeds, 1.0, 1.0, 5.0, None)
    # Cruise speed of the normalised form at L = sigma = 1: v0 / sqrt(2) = 2.
    assert v0 == pytest.approx(2.0 * math.sqrt(2.0))
    # 99th percentile of the 61 finite samples: 2 + 0.4 * (3 - 2) (linear interpolation).
    assert vmax == pytest.approx(2.4)
    # A rider that never moves keeps the fallbacks.
    assert sfm.speed_from_recording(np.zeros(5), 1.0, 1.0, 4.2, 4.7) == (4.2, 4.7)


def test_calibrated_preset_takes_the_riders_own_speed() -> None:
    from dataclasses import replace

    from vei.config import SFM_PRESETS, case_preset
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.state import VariantParams, prepare_scenario

    arrays = prepare_scenario(reconstruct(demo_interaction()))
    cal = SFM_PRESETS["calibrated"]
    case = replace(case_preset("normal"), sfm=cal)
    p = VariantParams.from_case(case, arrays, 1)
    from vei.sim.tables import recorded_column

    # the recorded samples (not the run-in / run-out the track also holds: issue 22)
    sp = recorded_column(arrays.rider_track, "speed_mps", arrays.rider_recorded_span_s)
    med = float(np.median(sp[sp > 0.5]))
    # The demo's e-scooter rides at 4.0-4.8 m/s (the reconstruction's spline adds a few
    # percent): the calibrated rider cruises at its median.
    assert 4.0 <= med <= 5.0
    la = cal.lookahead_m
    assert p.v0_mps[0] * la / math.hypot(la, cal.sigma_m) == pytest.approx(med)
    assert p.max_speed_mps[0] == pytest.approx(max(np.quantile(sp, 0.99), med))
    assert p.k_des_nspm[0] == cal.k_des_nspm and p.lookahead_m[0] == la
    assert p.max_accel_mps2[0] == cal.max_accel_mps2
    # The paper's preset keeps v0 = 5 m/s and no limits.
    q = VariantParams.from_case(case_preset("normal", sfm=SFM_PRESETS["paper"]), arrays, 1)
    assert q.v0_mps[0] == 5.0 and math.isinf(q.max_speed_mps[0])
