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
