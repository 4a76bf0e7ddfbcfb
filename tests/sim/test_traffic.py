"""Recorded cars that react (vei.sim.traffic, vei.models.traffic_core) and the secondary
collisions (vei.sim.contacts): replay equivalence while nothing deviates, the hand-built
rear-end case against an independent integration of the model, both kernels."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from vei.config import EgoConfig, SimConfig, TrafficConfig, case_preset
from vei.models import traffic_core as core
from vei.policy.base import PolicyAction
from vei.sim.engine import simulate
from vei.sim.state import VariantParams, prepare_scenario
from vei.sim.testing import TrackSpec, make_scenario
from vei.types import EGO_ID

V = 10.0  # both cars' recorded speed [m/s]
DT = 0.05
T_BRAKE = 1.0  # the ego brakes at 8 m/s^2 from here on


class BrakeAt:
    """A test policy: hold the speed, then brake at ``decel_mps2`` from ``t_s`` on."""

    def __init__(self, t_s: float = T_BRAKE, decel_mps2: float = 8.0) -> None:
        self.t_s, self.decel_mps2 = t_s, decel_mps2

    def init_state(self, batch_size: int) -> None:
        return None

    def act(self, obs, state):
        return PolicyAction(
            accel_mps2=np.where(obs.t_s >= self.t_s - 1e-9, -self.decel_mps2, 0.0)
        ), None


def _scene(headway_s: float = 1.0):
    """The ego at 10 m/s along +x from x = 20 m, a car recorded 1 s (10 m) behind it
    bumper to bumper at the same speed, an e-scooter standing far away (the rider)."""
    t = np.arange(0, 301) * DT
    z = np.zeros_like(t)
    ego = TrackSpec("ego", t, 20.0 + V * t, z, z, np.full_like(t, V))
    fol = TrackSpec("vehicle", t, 20.0 + V * t - 4.7 - V * headway_s, z, z, np.full_like(t, V))
    rider = TrackSpec("escooter", t, np.full_like(t, 400.0), np.full_like(t, 40.0),
                      np.full_like(t, math.pi / 2), z)  # fmt: skip
    return make_scenario({EGO_ID: ego, "car1": fol, "r1": rider}, primary_threat="r1")


@pytest.fixture(scope="module")
def arrays():
    return prepare_scenario(_scene(), SimConfig(duration_s=10.0))


def _case(react: bool = True, policy: bool = True):
    ego = EgoConfig(cruise_speed_mps=V, run_up_m=0.0, actuator_lag_s=0.0, max_decel_mps2=8.0)
    if policy:
        ego = dataclasses.replace(ego, policy="tests.sim.test_traffic:BrakeAt")
    return dataclasses.replace(
        case_preset("replay"), ego=ego, traffic=TrafficConfig(cars_react=react)
    )


def test_the_follower_is_a_reacting_car(arrays) -> None:
    tr = arrays.traffic
    assert tr.n == 1 and arrays.other_ids[tr.idx[0]] == "car1"
    assert tr.pair[0, 0]  # the ego comes onto its path
    np.testing.assert_allclose(tr.v_rec_mps[5:-5, 0], V, atol=1e-6)


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_replay_equivalence_without_deviation(arrays, kernel) -> None:
    """The ego replaying its recorded speed: the reacting car reproduces its recording."""
    case = dataclasses.replace(case_preset("replay-speed"), traffic=TrafficConfig(cars_react=True))
    r = simulate(arrays, VariantParams.from_case(case, arrays, 1), kernel=kernel)
    j = arrays.traffic.idx[0]
    dev = np.hypot(
        r.car_x_m[0, :, 0] - arrays.other_x_m[:, j], r.car_y_m[0, :, 0] - arrays.other_y_m[:, j]
    )
    assert dev.max() <= 0.05
    assert (r.car_mode == core.REPLAY).all()
    assert r.final_state.sec_count[0] == 0


def _independent(reaction_s: float = 1.0, trigger: float = 0.5):
    """The rear-end case integrated here, from the model's equations (not vei's code):
    the ego (semi-implicit Euler like the engine) at 10 m/s brakes at 8 m/s^2 from t = 1 s;
    the follower replays 10 m/s until the IDM (city parameters) towards the actual ego asks
    0.5 m/s^2 more braking than towards the recorded one, then after 1 s drives by
    min(intent, IDM) in [-8, 1]. Returns (t of contact or None, the follower's speed at
    the step before it (the impact speed's convention: the ego stands then), gap at rest)."""
    a, b, t_h, s0, v0, delta = 1.0, 1.5, 1.0, 2.0, 15.0, 4.0

    def idm(v, vl, gap):
        s_star = s0 + max(0.0, v * t_h + v * (v - vl) / (2 * math.sqrt(a * b)))
        return a * (1 - (v / v0) ** delta - (s_star / max(gap, 0.01)) ** 2)

    xe, ve = 20.0, V  # ego centre at t = 0
    xf, vf = 20.0 - 4.7 - V, V  # follower centre
    mode, timer, t = 0, 0.0, 0.0
    for k in range(int(10 / DT)):
        t = k * DT
        v_before = vf
        gap = xe - xf - 4.7
        x_rec_e = 20.0 + V * t
        x_rec_f = 20.0 - 4.7 - V + V * t
        if mode == 0:
            a_act = idm(V, ve, gap)
            a_rec = idm(V, V, x_rec_e - x_rec_f - 4.7)
            if a_act < a_rec - trigger:
                mode, timer = 1, reaction_s
        if mode == 1:
            timer -= DT
            if timer <= 1e-9:
                mode = 2
        if mode == 2:
            acc = max(min(min((V - vf) / t_h, idm(vf, ve, gap)), a), -8.0)
            vf = max(vf + acc * DT, 0.0)
            xf = xf + vf * DT
        else:
            vf, xf = V, x_rec_f + V * DT
        # the ego: 8 m/s^2 from t = 1 s (its command applies from the step at t >= 1 s)
        if t >= T_BRAKE - 1e-9:
            ve = max(ve - 8.0 * DT, 0.0)
        xe = xe + ve * DT
        if xe - xf - 4.7 <= 0.0:
            return t + DT, v_before, 0.0
    return None, vf, xe - xf - 4.7


@pytest.mark.parametrize("kernel", ["numpy", "numba"])
def test_rear_end_by_hand(arrays, kernel) -> None:
    """The ego brakes at 8 m/s^2 in front of a follower at a 1 s headway: the follower
    reacts after 1 s and brakes as hard as it can, but touches the ego at the time and
    speed the independent integration predicts; without reacting cars it drives through the ego's
    box at its full 10 m/s (the recorded car knows nothing)."""
    t_hit, v_hit, _ = _independent()
    assert t_hit is not None  # the model's answer: contact
    params = VariantParams.concat(
        [VariantParams.from_case(_case(react), arrays, 1) for react in (True, False)]
    )
    r = simulate(arrays, params, kernel=kernel)
    fs = r.final_state
    assert fs.sec_count.tolist() == [1, 1]
    assert fs.rear_end.tolist() == [True, True]
    assert fs.sec_striker.tolist() == [2, 2] and fs.sec_struck.tolist() == [0, 0]
    assert fs.sec_first_t_s[0] == pytest.approx(t_hit, abs=1e-9)
    assert fs.sec_max_speed_mps[0] == pytest.approx(v_hit, abs=1e-6)  # the ego stands then
    assert fs.sec_first_t_s[1] < fs.sec_first_t_s[0] and fs.sec_max_speed_mps[1] > 9.0
    # the reacting follower stops at the contact
    assert r.car_mode[0, -1, 0] == core.STOPPED and r.car_speed_mps[0, -1, 0] == 0.0


def test_a_longer_headway_stops_short(arrays) -> None:
    """At a 2.5 s headway the same follower stops behind the ego: no contact."""
    a2 = prepare_scenario(_scene(headway_s=2.5), SimConfig(duration_s=10.0))
    t_hit, _, gap = _independent()
    r = simulate(a2, VariantParams.from_case(_case(True), a2, 1), kernel="numpy")
    assert r.final_state.sec_count[0] == 0
    assert r.car_speed_mps[0, -1, 0] == pytest.approx(0.0, abs=1e-9)
    rest = r.ego_x_m[0, -1] - r.car_x_m[0, -1, 0] - 4.7
    assert 0.0 < rest < 2.0 + 0.5  # about s0 behind it
    del t_hit, gap
