"""paper-cap and none through the policy API equal the engine's own branches bit for bit
(NumPy path) on the demo and on a crossing scenario, with and without perception delay."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from vei.config import case_preset
from vei.policy.builtin import PaperCAP, PIDCruise
from vei.sim.engine import prepare_scenario, simulate
from vei.sim.params import EGO_POLICY, VariantParams
from vei.sim.result import _RECORDED
from vei.sim.testing import crossing_scenario


@pytest.fixture(scope="module")
def demo_arrays():
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct

    return prepare_scenario(reconstruct(demo_interaction()))


@pytest.fixture(scope="module")
def crossing_arrays():
    return prepare_scenario(crossing_scenario())


def _assert_same(ref, got) -> None:
    for name, _, _ in _RECORDED:
        np.testing.assert_array_equal(getattr(ref, name), getattr(got, name), err_msg=name)
    np.testing.assert_array_equal(ref.collision_time_s, got.collision_time_s)
    np.testing.assert_array_equal(ref.min_center_distance_m, got.min_center_distance_m)


@pytest.mark.parametrize("which", ["demo", "crossing"])
@pytest.mark.parametrize("delay_s", [0.0, 0.3])
def test_paper_cap_through_the_api_equals_the_engine_cap(
    which, delay_s, demo_arrays, crossing_arrays
) -> None:
    arrays = demo_arrays if which == "demo" else crossing_arrays
    shifts = (
        np.array([0.0, 2.0, 4.886, 5.5]) if which == "crossing" else np.array([-1.0, 0.0, 1.0, 2.0])
    )
    parts = []
    for name in ("normal-cap", "aggressive-cap"):
        case = case_preset(name)
        case = replace(case, cap=replace(case.cap, perception_delay_s=delay_s))
        parts.append(VariantParams.from_case(case, arrays, shifts.size, time_shift_s=shifts))
    ref_p = VariantParams.concat(parts)
    api_p = ref_p.with_values(ego_mode=EGO_POLICY, policy=PaperCAP())
    ref = simulate(arrays, ref_p, kernel="numpy")
    got = simulate(arrays, api_p, kernel="numpy")
    assert (ref.cap_state == 1).any()  # the CAP brakes in some variant: the test has teeth
    _assert_same(ref, got)


def test_pid_cruise_through_the_api_equals_the_engine_pid(crossing_arrays) -> None:
    shifts = np.array([0.0, 4.886])
    ref_p = VariantParams.from_case(case_preset("normal"), crossing_arrays, 2, time_shift_s=shifts)
    ref = simulate(crossing_arrays, ref_p, kernel="numpy")
    got = simulate(
        crossing_arrays, ref_p.with_values(ego_mode=EGO_POLICY, policy=PIDCruise()), kernel="numpy"
    )
    assert not np.isnan(ref.collision_time_s).all()  # one collides
    _assert_same(ref, got)


def test_mixed_batch_groups_policies_and_equals_single_runs(crossing_arrays) -> None:
    """Kernel variants, two policy instances, interleaved: each equals its own run."""

    cases = []
    for pol in ("paper-cap", "aeb", "idm", "none", "aeb"):
        c = case_preset("normal-cap")
        cases.append(replace(c, name=pol, ego=replace(c.ego, policy=pol)))
    parts = [VariantParams.from_case(c, crossing_arrays, 1, time_shift_s=4.886) for c in cases]
    batch = VariantParams.concat(parts)
    res = simulate(crossing_arrays, batch, kernel="numpy")
    for i, p in enumerate(parts):
        one = simulate(crossing_arrays, p, kernel="numpy")
        np.testing.assert_array_equal(one.ego_speed_mps[0], res.ego_speed_mps[i])
        np.testing.assert_array_equal(one.cap_state[0], res.cap_state[i])
    assert list(res.labels) == ["paper-cap", "aeb", "idm", "none", "aeb"]
