"""Ego policies in the compiled kernel see the reacting cars where the engine drives them
(vei.sim.kernel.policy.put_cars), as the NumPy step loop's observation does
(vei.sim.observe.ground_truth): both kernels agree on every recorded series, with and
without a perception delay, for aeb, idm and a user's compiled policy that steers by
where it sees the car behind it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from tests.sim.kernel.test_kernel_policy import _assert_equal
from tests.sim.test_traffic import _scene
from vei.config import EgoConfig, SimConfig, case_preset
from vei.models import traffic_core as core
from vei.policy.compiled import E_T, O_CATEGORY, O_VALID, O_VX, O_X, CompiledPolicy
from vei.policy.observation import category_code
from vei.sim.engine import simulate
from vei.sim.kernel.policy_pack import KIND_AEB, KIND_IDM, KIND_USER, kernel_kinds
from vei.sim.result import _RECORDED_CARS
from vei.sim.state import VariantParams, prepare_scenario

numba = pytest.importorskip("numba")

pytestmark = pytest.mark.slow  # compiles the kernel's policy + traffic feature sets

#: Per variant: the perception delay [s] (0, 4 and 2 steps) and whether the cars react.
DELAYS_S = np.array([0.0, 0.2, 0.1, 0.2])
REACT = np.array([True, True, True, False])
VEHICLE = float(category_code("vehicle"))


@numba.njit
def _watch_follower(ego, objs, state):
    """Brake at 8 m/s^2 from 1 s to 2.5 s, then accelerate by how far behind (and how
    fast) it sees each vehicle: the ego's motion depends on the car's observed pose."""
    t = ego[E_T]
    if t < 1.0:
        return 0.0
    if t < 2.5:
        return -8.0
    a = 0.0
    for j in range(objs.shape[1]):
        if objs[O_VALID, j] > 0.5 and objs[O_CATEGORY, j] == VEHICLE:
            a += 0.2 * (objs[O_X, j] + 8.0) + 0.1 * objs[O_VX, j]
    return min(max(a, -8.0), 2.0)


@pytest.fixture(scope="module")
def arrays():
    # the ego at 10 m/s with a car recorded 1 s behind it (a reacting car)
    return prepare_scenario(_scene(), SimConfig(duration_s=6.0))


def _params(arrays, policy, cruise_mps: float) -> VariantParams:
    name = policy if isinstance(policy, str) else "aeb"
    ego = EgoConfig(cruise_speed_mps=cruise_mps, run_up_m=0.0, actuator_lag_s=0.0,
                    max_decel_mps2=8.0, policy=name)  # fmt: skip
    case = dataclasses.replace(case_preset("replay"), ego=ego)
    p = VariantParams.from_case(case, arrays, DELAYS_S.size)
    if not isinstance(policy, str):
        p = p.with_values(policy=policy)
    return p.with_values(perception_delay_s=DELAYS_S, cars_react=REACT)


@pytest.mark.parametrize("policy", ["aeb", "idm", "user"])
def test_kernel_policy_sees_the_reacting_car_as_numpy(arrays, policy) -> None:
    pol = CompiledPolicy(_watch_follower, name="watch") if policy == "user" else policy
    # aeb / idm: a cruise speed of 5 m/s makes the ego slow down from its recorded 10 m/s
    # (the car behind reacts); the user's policy brakes by itself
    p = _params(arrays, pol, 10.0 if policy == "user" else 5.0)
    kinds, _ = kernel_kinds(p)
    assert set(kinds) == {{"aeb": KIND_AEB, "idm": KIND_IDM, "user": KIND_USER}[policy]}
    ref = simulate(arrays, p, kernel="numpy")
    fast = simulate(arrays, p, kernel="numba")
    _assert_equal(ref, fast)
    for name, _, _ in _RECORDED_CARS:  # where they react (elsewhere not advanced)
        a, b = np.asarray(getattr(ref, name))[REACT], np.asarray(getattr(fast, name))[REACT]
        np.testing.assert_allclose(b, a, rtol=0, atol=1e-9, err_msg=name)
    # not trivial: the car reacted (the engine drove it off its recording) where it could
    driven = ref.car_mode[:, -1, 0] > core.REACTING
    assert driven.tolist() == REACT.tolist()
    j = arrays.traffic.idx[0]
    off = np.hypot(ref.car_x_m[:, :, 0] - arrays.other_x_m[:, j],
                   ref.car_y_m[:, :, 0] - arrays.other_y_m[:, j])  # fmt: skip
    assert off[REACT].max(axis=1).min() > 1.0
    assert (ref.car_mode[~REACT] == core.REPLAY).all()
