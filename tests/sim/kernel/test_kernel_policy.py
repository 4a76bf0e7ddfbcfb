"""Ego policies in the compiled kernel (aeb, idm, users' compiled policies) against the
NumPy step loop with the Python policy API, step by step."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from vei.config import case_preset
from vei.errors import ConfigError, PolicyError
from vei.policy.compiled import E_CRUISE, E_SPEED, E_T, O_GAP, O_VALID, CompiledPolicy
from vei.policy.perception import PerceptionConfig
from vei.sim.engine import _RECORDED, simulate
from vei.sim.kernel import ALL_FEATURES, Features, features_of
from vei.sim.kernel.policy_pack import KIND_AEB, KIND_IDM, KIND_USER, kernel_kinds
from vei.sim.params import VariantParams
from vei.sim.state import prepare_scenario
from vei.sim.testing import TrackSpec, crossing_scenario
from vei.sim.warmup import warmup_scene

numba = pytest.importorskip("numba")

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "my_compiled_policy.py"
SHIFTS = np.array([3.5, 4.886, 6.0, 4.2, 5.1])
DELAYS = np.array([0.0, 0.4, 0.0, 0.2, 0.12])


@pytest.fixture(scope="module")
def arrays():
    # a cyclist riding along the ego's path ahead of it (a leader for idm, a target for aeb)
    t = np.arange(0, 501) / 20.0
    x = 25.0 + 3.0 * t
    other = TrackSpec("cyclist", t, x, np.zeros_like(t), np.zeros_like(t), np.full_like(t, 3.0))
    return prepare_scenario(crossing_scenario(others=[("c2", other)]))


def _params(arrays, policy: str) -> VariantParams:
    c = case_preset("normal")
    case = replace(c, name=policy.rpartition(":")[2], ego=replace(c.ego, policy=policy))
    p = VariantParams.from_case(case, arrays, SHIFTS.size, time_shift_s=SHIFTS)
    return p.with_values(perception_delay_s=DELAYS)


def _assert_equal(ref, fast) -> None:
    for name, _, _ in _RECORDED:
        a, b = np.asarray(getattr(ref, name)), np.asarray(getattr(fast, name))
        if a.dtype.kind == "f":
            np.testing.assert_allclose(b, a, rtol=0, atol=1e-9, err_msg=name)
        else:
            np.testing.assert_array_equal(b, a, err_msg=name)
    np.testing.assert_allclose(fast.collision_time_s, ref.collision_time_s, atol=1e-12)
    np.testing.assert_allclose(fast.min_center_distance_m, ref.min_center_distance_m, atol=1e-9)


@pytest.mark.parametrize("policy", ["aeb", "idm", f"{EXAMPLE}:MyCompiledPolicy"])
def test_kernel_policy_equals_numpy_policy_api(arrays, policy) -> None:
    p = _params(arrays, policy)
    kinds, _ = kernel_kinds(p)
    assert set(kinds) == {{"aeb": KIND_AEB, "idm": KIND_IDM}.get(policy, KIND_USER)}
    ref = simulate(arrays, p, kernel="numpy")
    fast = simulate(arrays, p, kernel="numba")
    _assert_equal(ref, fast)
    # the runs are not trivial: the policy brakes for the road users in its path
    assert np.asarray(fast.ego_speed_mps).min() < 3.0
    if policy == "aeb":
        assert np.asarray(fast.cap_state).max() >= 2  # braking stages reached, recorded


def test_kernel_policy_batch_invariant_and_mixed_with_cap(arrays) -> None:
    aeb = _params(arrays, "aeb")
    cap = VariantParams.from_case(case_preset("normal-cap"), arrays, 2, time_shift_s=SHIFTS[:2])
    mixed = simulate(arrays, VariantParams.concat([cap, aeb]), kernel="numba")
    for i in (0, 3):
        one = simulate(arrays, aeb.take([i]), kernel="numba")
        for name, _, _ in _RECORDED:
            np.testing.assert_array_equal(
                np.asarray(getattr(one, name))[0], np.asarray(getattr(mixed, name))[2 + i]
            )


def test_sensor_model_keeps_the_numpy_loop(arrays) -> None:
    p = _params(arrays, "aeb").with_values(perception=PerceptionConfig(enabled=True))
    kinds, _ = kernel_kinds(p)
    assert not kinds.any()


@numba.njit
def _nan_after_two_seconds(ego, objs, state):
    if ego[E_T] > 2.0:
        return np.nan
    return 0.0


def test_nan_demand_names_variant_and_step(arrays) -> None:
    pol = CompiledPolicy(_nan_after_two_seconds, name="nanpol")
    p = _params(arrays, "aeb").with_values(policy=pol)
    with pytest.raises(PolicyError, match=r"nanpol: returned nan .* at step 41 \(t = 2\.050 s\)"):
        simulate(arrays, p, kernel="numba")
    with pytest.raises(PolicyError, match=r"nanpol: returned nan"):
        simulate(arrays, p, kernel="numpy")


def _two_args(ego, objs):
    return 0.0


def _returns_array(ego, objs, state):
    return objs[O_VALID]


def _nan_probe(ego, objs, state):
    return ego[E_CRUISE] - ego[E_SPEED] + np.nan


def _writes_state(ego, objs, state):
    state[0] = objs[O_GAP, 0]
    return 0.0


def _raises(ego, objs, state):
    raise ValueError("no road user")


def test_check_on_load_names_what_is_wrong() -> None:
    with pytest.raises(ConfigError, match="must take 3 arguments"):
        CompiledPolicy(_two_args)
    with pytest.raises(ConfigError, match=r"does not compile as float64\(float64\[::1\] ego"):
        CompiledPolicy(_returns_array)
    with pytest.raises(ConfigError, match="returned nan on a probe observation"):
        CompiledPolicy(_nan_probe)
    with pytest.raises(ConfigError, match="raised ValueError on a probe"):
        CompiledPolicy(_raises)
    with pytest.raises(ConfigError, match="state0 must be 2 numbers"):
        CompiledPolicy(_writes_state, state_size=2, state0=["a", "b"])
    with pytest.raises(ConfigError, match="not a function"):
        CompiledPolicy(3.0)


@pytest.mark.parametrize(
    "feats", [Features(policy=True), Features(policy=True, user=True), ALL_FEATURES]
)
def test_warmup_scene_compiles_the_policy_feature_set(feats) -> None:
    arrays, params, scored = warmup_scene(feats)
    assert features_of(arrays, params, scored) == feats
