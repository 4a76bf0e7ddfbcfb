"""AEB: the stages fire at the hand-computed TTCs; it stops short of a standing rider."""

from __future__ import annotations

import numpy as np
import pytest

from tests.policy.helpers import make_obs
from vei.config import CaseConfig, EgoConfig, SimConfig
from vei.errors import ConfigError
from vei.policy.aeb import (
    AEB,
    AEB_FCW,
    AEB_FULL,
    AEB_OFF,
    AEB_PARTIAL,
    HOLD_SPEED_MPS,
    AEBConfig,
    aeb_stage,
    path_ttc,
)
from vei.sim.engine import prepare_scenario, simulate
from vei.sim.params import VariantParams
from vei.sim.testing import (
    EGO_ID,
    TrackSpec,
    ego_straight,
    make_scenario,
    standing_rider_scenario,
)


def test_stage_thresholds_on_ttc() -> None:
    # gap / closing: 30/10 = 3.0 (off), 25/10 = 2.5 (FCW), 15/10 = 1.5 (partial), 8/10 = 0.8 (full)
    v = np.full(4, 10.0)
    obs = make_obs(v, gap_m=np.array([30.0, 25.0, 15.0, 8.0]))
    action, st = AEB().act(obs, AEB().init_state(4))
    np.testing.assert_array_equal(action.fsm_state, [AEB_OFF, AEB_FCW, AEB_PARTIAL, AEB_FULL])
    # FCW / off: the PID (at cruise: no error -> 0); partial -4, full -8 m/s^2
    np.testing.assert_allclose(action.accel_mps2, [0.0, 0.0, -4.0, -8.0])


def test_ttc_ignores_receding_and_out_of_corridor_objects() -> None:
    gap = np.array([[10.0, 5.0, np.inf]])
    rvx = np.array([[-5.0, +1.0, -10.0]])
    assert path_ttc(gap, rvx, np.ones((1, 3), dtype=bool))[0] == pytest.approx(2.0)


def test_braking_holds_while_closing_in_or_stopped_behind_an_object() -> None:
    p, f, w = AEB_PARTIAL, AEB_FULL, AEB_FCW
    prev = np.array([p, p, w, p, f, p], dtype=np.int8)
    # 0-2 stopped (v = 0: nothing closes in); 3 rolling, object receding (TTC inf);
    # 4 rolling, still closing but TTC above every threshold; 5 rolling, path clear
    ttc = np.array([np.inf, np.inf, np.inf, np.inf, 5.0, np.inf])
    in_path = np.array([True, False, True, True, True, False])
    v = np.array([0.0, 0.0, 0.0, 6.0, 6.0, 6.0])
    got = aeb_stage(prev, ttc, in_path, 2.6, 1.6, 0.9, v)
    np.testing.assert_array_equal(got, [p, AEB_OFF, AEB_OFF, AEB_OFF, f, AEB_OFF])
    # just below / at the hold speed
    got = aeb_stage(prev[:1], ttc[:1], in_path[:1], 2.6, 1.6, 0.9, np.array([HOLD_SPEED_MPS]))
    assert got[0] == AEB_OFF
    got = aeb_stage(prev[:1], ttc[:1], in_path[:1], 2.6, 1.6, 0.9, np.array([0.49]))
    assert got[0] == AEB_PARTIAL


def _run(v0: float, **params: float):
    # Rider standing across the path (yaw pi/2: half-extent 0.3 m) with its near edge 30 m
    # ahead of the ego's front bumper (2.35 m ahead of its centre).
    scen = standing_rider_scenario(ego_speed_mps=v0, rider_x_m=30.0 + 2.35 + 0.3, duration_s=10.0)
    arrays = prepare_scenario(scen, SimConfig(kernel="numpy"))
    ego = EgoConfig(cruise_speed_mps=v0, run_up_m=0.0, policy="aeb", policy_params=params or None)
    case = CaseConfig(name="aeb", rider="replay", ego=ego)
    return simulate(arrays, VariantParams.from_case(case, arrays, 1))


def test_stages_fire_at_the_hand_computed_ttcs_in_the_engine() -> None:
    # 10 m/s toward a standing rider 30 m ahead: TTC(t) = 3 - t while cruising. Thresholds
    # 2.62 s / 1.62 s (off the 0.05 s grid) are crossed at the observations of t = 0.40 s
    # and t = 1.40 s; the stage is recorded with the next step (t + dt).
    r = _run(10.0, ttc_warning_s=2.62, ttc_partial_s=1.62, ttc_full_s=0.5)
    st = r.cap_state[0]
    assert r.t_s[np.argmax(st >= AEB_FCW)] == pytest.approx(0.45)
    assert r.t_s[np.argmax(st >= AEB_PARTIAL)] == pytest.approx(1.45)
    # no braking before: the speed is 10 m/s up to the partial stage
    k = int(np.argmax(st >= AEB_PARTIAL))
    np.testing.assert_allclose(r.ego_speed_mps[0, :k], 10.0)
    assert np.isnan(r.collision_time_s[0])


def test_aeb_stops_short_of_a_standing_rider_from_30_kmh() -> None:
    r = _run(30.0 / 3.6)
    assert np.isnan(r.collision_time_s[0])
    assert r.ego_speed_mps[0, -1] == 0.0
    # partial braking at TTC 1.6 s: gap 13.3 m, stopping distance ~ v^2 / (2 * 4) + v tau = 10.3 m
    gap_end = r.rider_x_m[0, -1] - 0.3 - r.ego_x_m[0, -1] - 2.35
    assert 1.0 < gap_end < 5.0
    none = _run_none(30.0 / 3.6)
    assert none == pytest.approx(3.6)  # without AEB: 30 m at 8.33 m/s


def _run_none(v0: float) -> float:
    scen = standing_rider_scenario(ego_speed_mps=v0, rider_x_m=30.0 + 2.35 + 0.3, duration_s=10.0)
    arrays = prepare_scenario(scen, SimConfig(kernel="numpy"))
    case = CaseConfig(
        name="none", rider="replay", ego=EgoConfig(cruise_speed_mps=v0, run_up_m=0.0, policy="none")
    )
    return float(simulate(arrays, VariantParams.from_case(case, arrays, 1)).collision_time_s[0])


def test_config_validation() -> None:
    with pytest.raises(ConfigError, match="ttc_warning_s >= ttc_partial_s"):
        AEBConfig(ttc_warning_s=1.0, ttc_partial_s=1.6)
    with pytest.raises(ConfigError, match="aeb.partial_decel_mps2"):
        AEBConfig(partial_decel_mps2=-1.0)
    with pytest.raises(ConfigError, match="full_decel_mps2"):
        AEBConfig(partial_decel_mps2=6.0, full_decel_mps2=5.0)
    with pytest.raises(ConfigError, match="policy 'aeb'.*'ttc'"):
        case = CaseConfig(name="x", ego=EgoConfig(policy="aeb", policy_params={"ttc": 1.0}))
        VariantParams.from_case(case, prepare_scenario(standing_rider_scenario()), 1)


def test_defaults_match_the_variant_params_defaults() -> None:
    from vei.policy.aeb import AEB_PARAM_FIELDS
    from vei.policy.idm import IDM_PARAM_FIELDS, IDMConfig
    from vei.sim.params import POLICY_PARAM_DEFAULTS

    for cfg, fields in ((AEBConfig(), AEB_PARAM_FIELDS), (IDMConfig(), IDM_PARAM_FIELDS)):
        for f, vp in fields.items():
            assert POLICY_PARAM_DEFAULTS[vp] == getattr(cfg, f)


def test_brake_releases_when_the_rider_pulls_away_and_the_car_returns_to_cruise() -> None:
    """A rider standing 16 m ahead of the bumper (TTC 1.6 s at 10 m/s: partial braking)
    rides off along the ego's path at 12 m/s from t = 1 s, faster than the car: nothing
    closes in any more (TTC = inf) although it stays in the corridor, so the AEB releases
    and the PID brings the car back to its 10 m/s (a latched brake stopped the car)."""
    v0, rate = 10.0, 20.0
    ego = ego_straight(v0, 12.0, rate)
    t = ego.t_s
    x0 = 16.0 + 2.35 + 0.6  # rider along x (yaw 0): half-length 0.6 m
    x = x0 + 12.0 * np.clip(t - 1.0, 0.0, None)
    rider = TrackSpec("escooter", t, x, np.zeros_like(t), np.zeros_like(t),
                      np.where(t >= 1.0, 12.0, 0.0))  # fmt: skip
    scen = make_scenario({EGO_ID: ego, "rider1": rider}, primary_threat="rider1", rate_hz=rate)
    arrays = prepare_scenario(scen, SimConfig(kernel="numpy"))
    ego_cfg = EgoConfig(cruise_speed_mps=v0, run_up_m=0.0, policy="aeb")
    r = simulate(
        arrays,
        VariantParams.from_case(CaseConfig(name="a", rider="replay", ego=ego_cfg), arrays, 1),
    )
    st, v = r.cap_state[0], r.ego_speed_mps[0]
    assert np.isnan(r.collision_time_s[0])
    k_brake = int(np.argmax(st >= AEB_PARTIAL))
    assert 0.0 < r.t_s[k_brake] <= 0.2  # braking at once (TTC 1.6 s at the start)
    k_rel = k_brake + int(np.argmax(st[k_brake:] < AEB_PARTIAL))
    assert k_rel > k_brake and 1.0 < r.t_s[k_rel] < 1.3  # released soon after the rider leaves
    assert (st[k_rel:] < AEB_PARTIAL).all()  # and stays released
    assert 5.0 < v.min() < v0  # slowed (partial braking ~1 s), never stopped
    # back toward cruise: the PID (time constant ~4.5 s) climbs monotonically from ~2.5 s
    k3 = int(np.searchsorted(r.t_s, 2.5))
    assert (np.diff(v[k3:]) >= -1e-9).all() and 9.3 < v[-1] <= v0 + 1e-9
