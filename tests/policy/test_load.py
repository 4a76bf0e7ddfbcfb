"""The policy loader: built-in names, module:Class, file.py:Class, and clear errors."""

from __future__ import annotations

import numpy as np
import pytest

from vei.config import CaseConfig, EgoConfig, load_config
from vei.errors import ConfigError
from vei.policy.aeb import AEB
from vei.policy.base import PerVariantPolicy, PolicyAction
from vei.policy.load import load_policy


def test_builtin_names_and_module_class() -> None:
    assert isinstance(load_policy("aeb", {"ttc_full_s": 1.0}), AEB)
    assert load_policy("aeb", {"ttc_full_s": 1.0}).config.ttc_full_s == 1.0
    assert isinstance(load_policy("vei.policy.aeb:AEB"), AEB)


@pytest.mark.parametrize(
    ("spec", "message"),
    [
        ("nosuch", "expected a built-in name"),
        ("nosuch.module:Planner", "cannot import 'nosuch.module'"),
        ("vei.policy.aeb:Nope", "has no 'Nope'"),
        ("vei.policy.aeb:AEB_FULL", "is not a class"),
        ("vei.policy.observation:Observation", "bad parameters|does not implement"),
        ("vei.config:SimConfig", "does not implement the policy interface"),
        ("missing/file.py:X", "file missing/file.py not found"),
    ],
)
def test_errors_name_the_spec(spec: str, message: str) -> None:
    with pytest.raises(ConfigError, match=message) as exc:
        load_policy(spec)
    assert repr(spec) in str(exc.value) or "expected a built-in" in str(exc.value)


def test_file_with_an_error_and_bad_parameters(tmp_path) -> None:
    bad = tmp_path / "bad.py"
    bad.write_text("raise RuntimeError('boom')\n")
    with pytest.raises(ConfigError, match="importing .*bad.py failed: RuntimeError: boom"):
        load_policy(f"{bad}:X")
    with pytest.raises(ConfigError, match="policy 'aeb'.*unexpected keyword"):
        load_policy("aeb", {"nope": 1})


def test_run_config_spelling_and_removed_spelling() -> None:
    c = load_config(
        {"preset": "normal-cap", "ego": {"policy": "aeb", "policy_params": {"ttc_full_s": 1.2}}},
        CaseConfig,
    )
    assert (
        c.ego_mode == "policy"
        and c.policy_name == "aeb"
        and c.ego.policy_params == {"ttc_full_s": 1.2}
    )
    assert (
        load_config({"preset": "normal", "ego": {"policy": "paper-cap"}}, CaseConfig).ego_mode
        == "cap"
    )
    assert (
        load_config({"preset": "normal-cap", "ego": {"policy": "none"}}, CaseConfig).ego_mode
        == "pid"
    )
    with pytest.raises(
        ConfigError, match=r"ego_mode 'aeb' is a policy: write ego: \{policy: aeb\}"
    ):
        load_config({"name": "x", "ego_mode": "aeb"}, CaseConfig)
    with pytest.raises(ConfigError, match="replay-speed"):
        CaseConfig(name="x", ego_mode="replay-speed", ego=EgoConfig(policy="aeb"))
    with pytest.raises(ConfigError, match="policy_params given without a policy"):
        EgoConfig(policy_params={"a": 1})


def test_per_variant_adapter_and_action_checks() -> None:
    from tests.policy.helpers import make_obs

    class Half(PerVariantPolicy):
        def act_one(self, obs):
            return -0.5 * obs.ego_speed_mps

    action, _ = Half().act(make_obs(np.array([2.0, 4.0])), Half().init_state(2))
    np.testing.assert_array_equal(action.accel_mps2, [-1.0, -2.0])
    with pytest.raises(ConfigError, match="exactly one of"):
        PolicyAction()
    with pytest.raises(ConfigError, match=r"shape \(3,\), expected \(2,\)"):
        PolicyAction(accel_mps2=np.zeros(3)).checked(2, "policy X")
    with pytest.raises(ConfigError, match="NaN"):
        PolicyAction(accel_mps2=np.array([np.nan, 0.0])).checked(2, "policy X")


def test_builtin_policies_compare_by_parameters() -> None:
    assert load_policy("aeb") == load_policy("aeb")
    assert load_policy("aeb") != load_policy("aeb", {"ttc_full_s": 1.0})
    assert load_policy("paper-cap") == load_policy("paper-cap")
    assert load_policy("idm") != load_policy("aeb")


@pytest.mark.parametrize(
    ("policy", "params", "field"),
    [
        ("none", {"bogus": 1}, "'bogus': no parameter of 'none'"),
        ("none", {"kp": 0.1}, "'kp': set ego.kp"),
        ("paper-cap", {"t_safe_s": 3.0}, "'t_safe_s': set cap.t_safe_s"),
        ("paper-cap", {"ki": 0.2}, "'ki': set ego.ki"),
        ("vei.policy.builtin:PIDCruise", {"kd": 0.3}, "'kd': set ego.kd"),
        ("vei.policy.builtin:PaperCAP", {"paper_per_step": True}, "cap.braking_law"),
    ],
)
def test_policy_params_of_none_and_paper_cap_are_refused(
    policy: str, params: dict, field: str
) -> None:
    """'none' / 'paper-cap' take their gains from ego.* / cap.* (their bind replaces any
    constructor values with the run's): policy_params given to them would be ignored."""
    raw = {"preset": "normal", "ego": {"policy": policy, "policy_params": params}}
    with pytest.raises(ConfigError, match="policy_params given to policy") as exc:
        load_config(raw, CaseConfig)
    assert field in str(exc.value)
    with pytest.raises(ConfigError, match="policy_params given to policy"):
        EgoConfig(policy=policy, policy_params=params)
    # empty params, and params of the policies that take them, still load
    assert EgoConfig(policy=policy, policy_params={}).policy == policy
    assert load_config(
        {"preset": "normal", "ego": {"policy": "idm", "policy_params": {"time_headway_s": 1.0}}},
        CaseConfig,
    ).ego.policy_params == {"time_headway_s": 1.0}


def test_unknown_policy_params_of_aeb_and_idm_are_refused() -> None:
    with pytest.raises(ConfigError, match="policy 'idm'.*unexpected keyword"):
        load_policy("idm", {"bogus": 1})
    case = load_config(
        {"preset": "normal", "ego": {"policy": "aeb", "policy_params": {"bogus": 1}}}, CaseConfig
    )
    from vei.sim.params import _policy_param_values

    with pytest.raises(ConfigError, match="policy_params of 'aeb'.*bogus"):
        _policy_param_values(case)


@pytest.mark.parametrize(
    ("ego_mode", "policy", "implied"),
    [("cap", "none", "pid"), ("pid", "paper-cap", "cap"), ("pid", "aeb", "policy"),
     ("policy", "none", "pid")],
)  # fmt: skip
def test_explicit_ego_mode_that_disagrees_with_the_policy_is_refused(
    ego_mode: str, policy: str, implied: str
) -> None:
    raw = {"preset": "normal", "ego_mode": ego_mode, "ego": {"policy": policy}}
    with pytest.raises(
        ConfigError,
        match=rf"ego_mode '{ego_mode}' disagrees with ego.policy '{policy}' .*'{implied}'",
    ):
        load_config(raw, CaseConfig)
    with pytest.raises(ConfigError, match="disagrees"):  # nested in a run config too
        from vei.config import RunConfig

        load_config({"case": raw}, RunConfig)


def test_agreeing_ego_mode_and_written_configs_load() -> None:
    from vei.config import config_to_dict

    for ego_mode, policy in (("pid", "none"), ("cap", "paper-cap"), ("policy", "aeb")):
        raw = {"preset": "normal", "ego_mode": ego_mode, "ego": {"policy": policy}}
        case = load_config(raw, CaseConfig)
        assert case.ego_mode == ego_mode and case.policy_name == policy
        assert load_config(config_to_dict(case), CaseConfig) == case
