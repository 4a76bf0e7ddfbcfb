"""IDM: free-road acceleration and the equilibrium gap behind a constant-speed leader
(hand-computed from Treiber, Hennecke & Helbing 2000), in a pure 1-D loop and in the engine."""

from __future__ import annotations

import math

import numpy as np
import pytest

from tests.policy.helpers import make_obs
from vei.errors import ConfigError
from vei.policy.idm import IDM, IDMConfig, idm_accel


def test_free_road_acceleration_is_a_times_one_minus_speed_ratio_to_the_fourth() -> None:
    pol = IDM()
    v = np.array([0.0, 5.0, 10.0, 12.0])
    action, _ = pol.act(make_obs(v, cruise_mps=10.0), None)
    # a (1 - (v / v0)^4) with a = 1 m/s^2, v0 = 10 m/s
    np.testing.assert_allclose(
        action.accel_mps2, [1.0, 1.0 - 0.5**4, 0.0, 1.0 - 1.2**4], rtol=1e-12
    )


def test_interaction_term_by_hand() -> None:
    # v = 8, leader 2 m/s slower (dv = 2) at s = 20 m: s* = 2 + 8 + 8 * 2 / (2 sqrt(1.5))
    s_star = 2.0 + 8.0 * 1.0 + 8.0 * 2.0 / (2.0 * math.sqrt(1.0 * 1.5))
    want = 1.0 * (1.0 - (8.0 / 10.0) ** 4 - (s_star / 20.0) ** 2)
    got = idm_accel(
        np.array([8.0]), 10.0, np.array([20.0]), np.array([2.0]), 1.0, 1.5, 1.0, 2.0, 4.0
    )
    assert got[0] == pytest.approx(want, rel=1e-12)


def test_equilibrium_gap_behind_a_constant_speed_leader_pure_loop() -> None:
    # Leader at v_l = 5 m/s, v0 = 10 m/s, T = 1 s, s0 = 2 m: s_e = (s0 + v_l T) / sqrt(1 - (v_l/v0)^4)
    pol = IDM()
    v_l, dt = 5.0, 0.05
    s_e = (2.0 + v_l * 1.0) / math.sqrt(1.0 - (v_l / 10.0) ** 4)
    v, gap = np.array([8.0]), np.array([40.0])
    for _ in range(int(120 / dt)):
        action, _ = pol.act(make_obs(v, gap_m=gap, rel_vx_mps=v_l - v, cruise_mps=10.0), None)
        v_new = np.maximum(0.0, v + action.accel_mps2 * dt)
        gap = gap + (v_l - v_new) * dt
        v = v_new
    assert v[0] == pytest.approx(v_l, abs=1e-3)
    assert gap[0] == pytest.approx(s_e, abs=0.01)  # 7.2296 m


def test_engine_follows_a_rider_riding_ahead_at_the_equilibrium_gap() -> None:
    from vei.config import CaseConfig, EgoConfig, SimConfig
    from vei.sim.engine import prepare_scenario, simulate
    from vei.sim.params import VariantParams
    from vei.sim.testing import TrackSpec, ego_straight, make_scenario
    from vei.types import EGO_ID

    t = np.arange(0, 60.0 + 1e-9, 0.05)
    rider = TrackSpec(
        "escooter", t, 30.0 + 4.0 * t, np.zeros_like(t), np.zeros_like(t), np.full_like(t, 4.0)
    )
    scen = make_scenario(
        {EGO_ID: ego_straight(8.0, 60.0), "r": rider}, primary_threat="r", rate_hz=20.0
    )
    arrays = prepare_scenario(scen, SimConfig(kernel="numpy"))
    case = CaseConfig(name="idm", ego=EgoConfig(cruise_speed_mps=8.0, run_up_m=0.0, policy="idm"))
    r = simulate(arrays, VariantParams.from_case(case, arrays, 1))
    assert np.isnan(r.collision_time_s[0])
    gap = r.rider_x_m[0, -1] - 0.6 - r.ego_x_m[0, -1] - 0.5 * arrays.ego_length_m
    s_e = (2.0 + 4.0 * 1.0) / math.sqrt(1.0 - (4.0 / 8.0) ** 4)  # 6.197 m
    assert r.ego_speed_mps[0, -1] == pytest.approx(4.0, abs=0.01)
    assert gap == pytest.approx(s_e, abs=0.05)


def test_config_validation() -> None:
    with pytest.raises(ConfigError, match="idm.max_accel_mps2"):
        IDMConfig(max_accel_mps2=0.0)
    with pytest.raises(ConfigError, match="idm.min_gap_m"):
        IDMConfig(min_gap_m=-1.0)
    with pytest.raises(ConfigError, match="idm"):
        IDM(bogus=1.0)
