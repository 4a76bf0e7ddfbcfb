"""An ego policy sees the road users that react where the engine put them (issue 34's
review): a reacting car (vei.sim.traffic) the engine drives and a walking pedestrian
(vei.sim.pedestrians) are observed at their engine poses of step k - delay
(vei.sim.contacts.others_now), not at their recordings; the others stay recorded."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tests.sim.test_pedestrians import _scene as ped_scene
from tests.sim.test_traffic import _scene
from vei.config import EgoConfig, PerceptionConfig, SimConfig, TrafficConfig, case_preset
from vei.models import traffic_core as core
from vei.policy.base import PolicyAction
from vei.sim.contacts import others_now
from vei.sim.engine import simulate
from vei.sim.state import VariantParams, prepare_scenario

DELAYS_S = np.array([0.0, 0.2])  # 0 and 4 steps


class Recorder:
    """Hold the speed, brake at ``decel_mps2`` from ``t_s`` on; keep every observation."""

    def __init__(self, t_s: float, decel_mps2: float) -> None:
        self.t_s, self.decel_mps2 = t_s, decel_mps2
        self.seen: list = []

    def init_state(self, batch_size: int) -> None:
        return None

    def act(self, obs, state):
        self.seen.append(obs)
        acc = np.where(obs.t_s >= self.t_s - 1e-9, -self.decel_mps2, 0.0)
        return PolicyAction(accel_mps2=acc), None


def _run(arrays, traffic: TrafficConfig, rec: Recorder, cruise_mps: float, **values):
    ego = EgoConfig(cruise_speed_mps=cruise_mps, run_up_m=0.0, actuator_lag_s=0.0,
                    max_decel_mps2=8.0, policy="aeb")  # fmt: skip
    case = dataclasses.replace(case_preset("replay"), ego=ego, traffic=traffic)
    p = VariantParams.from_case(case, arrays, DELAYS_S.size)
    p = p.with_values(policy=rec, perception_delay_s=DELAYS_S, **values)
    return simulate(arrays, p, kernel="numpy")


def _world(r, rec: Recorder, k: int, cols) -> np.ndarray:
    """[5, B, len(cols)] world x, y, yaw, vx, vy of the observed objects ``cols`` at step
    k (back from the ego frame at step k)."""
    o = rec.seen[k]
    ex, ey = r.ego_x_m[:, k, None], r.ego_y_m[:, k, None]
    eyaw, v = r.ego_yaw_rad[:, k, None], r.ego_speed_mps[:, k, None]
    c, s = np.cos(eyaw), np.sin(eyaw)
    rx, ry = o.rel_x_m[:, cols], o.rel_y_m[:, cols]
    rvx, rvy = o.rel_vx_mps[:, cols], o.rel_vy_mps[:, cols]
    return np.stack([ex + rx * c - ry * s, ey + rx * s + ry * c, eyaw + o.rel_yaw_rad[:, cols],
                     v * c + rvx * c - rvy * s, v * s + rvx * s + rvy * c])  # fmt: skip


def _angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to (-pi, pi]."""
    return np.angle(np.exp(1j * a))


def _assert_sees(r, rec: Recorder, arrays, truth_at, moved) -> float:
    """Every step's observation of the replayed others equals the engine's truth_at(kd)
    [5, B, n_o] of the delayed step kd = k - delay (nothing seen while kd < 0); returns
    the largest distance [m] between where it saw the others ``moved`` (their indices)
    and their recording."""
    cols = 1 + arrays.riders.n + np.arange(len(arrays.other_ids))
    delay = np.rint(DELAYS_S / arrays.dt_s).astype(int)
    assert len(rec.seen) == arrays.n_steps - 1
    dev = 0.0
    for k in range(len(rec.seen)):
        got = _world(r, rec, k, cols)
        for b, d in enumerate(delay):
            kd = k - d
            valid = rec.seen[k].valid[b, cols]
            if kd < 0:
                assert not valid.any()
                continue
            want = truth_at(kd)[:, b]
            act = arrays.other_active[kd]
            np.testing.assert_array_equal(valid, act)
            for ch in (0, 1, 3, 4):
                np.testing.assert_allclose(got[ch, b, act], want[ch, act], rtol=0, atol=1e-9,
                                           err_msg=f"step {k} variant {b} channel {ch}")  # fmt: skip
            np.testing.assert_allclose(_angle(got[2, b, act] - want[2, act]), 0.0, atol=1e-9)
            j = np.asarray(moved)[act[moved]]
            if j.size:
                d_rec = np.hypot(got[0, b, j] - arrays.other_x_m[kd, j],
                                 got[1, b, j] - arrays.other_y_m[kd, j])  # fmt: skip
                dev = max(dev, float(d_rec.max()))
    return dev


def test_policy_sees_the_reacting_car_where_the_engine_drives_it() -> None:
    """The ego brakes at 8 m/s^2 from 1 s in front of a car recorded 1 s behind it: the
    car reacts and brakes; the policy sees it at its engine pose and speed (with and
    without a perception delay), metres from its recording, which drives through the ego."""
    arrays = prepare_scenario(_scene(), SimConfig(duration_s=5.0))
    rec = Recorder(1.0, 8.0)
    r = _run(arrays, TrafficConfig(cars_react=True), rec, 10.0)
    assert (r.car_mode[:, -1, 0] > core.REACTING).all()  # the car reacted in both variants
    tr = arrays.traffic
    b = DELAYS_S.size

    def truth(kd: int):
        cars = {"car_x_m": r.car_x_m[:, kd], "car_y_m": r.car_y_m[:, kd],
                "car_yaw_rad": r.car_yaw_rad[:, kd], "car_v_mps": r.car_speed_mps[:, kd],
                "car_mode": r.car_mode[:, kd]}  # fmt: skip
        return np.stack(others_now(arrays, kd, b, cars, None))

    dev = _assert_sees(r, rec, arrays, truth, tr.idx)
    assert dev > 3.0  # the recording drives on: the test could fail


def test_without_reacting_cars_the_policy_sees_the_recording() -> None:
    arrays = prepare_scenario(_scene(), SimConfig(duration_s=3.0))
    rec = Recorder(1.0, 8.0)
    r = _run(arrays, TrafficConfig(cars_react=False), rec, 10.0)
    b = DELAYS_S.size
    dev = _assert_sees(r, rec, arrays, lambda kd: np.stack(others_now(arrays, kd, b)),
                       arrays.traffic.idx)  # fmt: skip
    assert dev == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("walks", [(True, True), (True, False)])
def test_policy_sees_the_walking_pedestrian_where_it_walks(walks) -> None:
    """The pedestrian recorded walking into the side of the passing car steps back for it;
    the policy (holding 5 m/s) sees it where it walks, not at its recording; a variant of
    the same policy block where it does not walk (peds_sfm False) sees its recording."""
    arrays = prepare_scenario(ped_scene(), SimConfig(duration_s=10.0))
    rec = Recorder(1e9, 0.0)
    on = np.array(walks)
    r = _run(arrays, TrafficConfig(pedestrians=True), rec, 5.0, peds_sfm=on)
    b = DELAYS_S.size

    def truth(kd: int):
        peds = {"ped_x_m": r.ped_x_m[:, kd], "ped_y_m": r.ped_y_m[:, kd],
                "ped_vx_mps": r.ped_vx_mps[:, kd], "ped_vy_mps": r.ped_vy_mps[:, kd]}  # fmt: skip
        walking = np.stack(others_now(arrays, kd, b, None, peds))
        return np.where(on[None, :, None], walking, np.stack(others_now(arrays, kd, b)))

    dev = _assert_sees(r, rec, arrays, truth, arrays.peds.idx)
    assert dev > 0.5  # it stepped back: the test could fail


def test_the_sensor_model_sees_the_reacting_car_where_the_engine_drives_it() -> None:
    """An ideal all-round sensor (vei.policy.perception: no noise, every detection, no
    occlusion) reports the reacting car at its engine position, not its recording."""
    arrays = prepare_scenario(_scene(), SimConfig(duration_s=5.0))
    rec = Recorder(1.0, 8.0)
    sensor = PerceptionConfig(enabled=True, range_m=200.0, fov_deg=360.0, occlusion=False)
    r = _run(arrays, TrafficConfig(cars_react=True), rec, 10.0, perception=sensor)
    j = int(arrays.traffic.idx[0])
    col = 1 + arrays.riders.n + j
    delay = np.rint(DELAYS_S / arrays.dt_s).astype(int)
    dev = 0.0
    for k in range(delay.max(), len(rec.seen)):
        got = _world(r, rec, k, [col])[:2, :, 0]
        assert rec.seen[k].valid[:, col].all()
        kd = k - delay
        rows = np.arange(DELAYS_S.size)
        want = np.stack([r.car_x_m[rows, kd, 0], r.car_y_m[rows, kd, 0]])
        np.testing.assert_allclose(got, want, rtol=0, atol=1e-9, err_msg=f"step {k}")
        dev = max(dev, float(np.hypot(*(got - np.stack([arrays.other_x_m[kd, j],
                                                         arrays.other_y_m[kd, j]]))).max()))  # fmt: skip
    assert dev > 3.0
