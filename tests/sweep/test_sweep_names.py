"""One name per parameter: a sweep parameter is its field's path in the run configuration,
old spellings are refused naming the new one, and a sweep refuses the AEB thresholds that
``vei run`` refuses."""

from __future__ import annotations

import dataclasses
import typing

import pytest

from tests.helpers_config import case_field
from vei.config import CaseConfig, load_config
from vei.errors import ConfigError
from vei.policy.aeb import AEBConfig
from vei.policy.idm import IDMConfig
from vei.sweep.evaluator import _PARAM_FIELDS
from vei.sweep.spec import (
    PARAMETERS,
    POLICY_PARAMS,
    POLICY_PARAMS_PREFIX,
    RENAMED,
    REPLACED,
    spec_from_dict,
    variant_config,
    variants_table,
)

#: Design parameters: no field of their own (see vei.sweep.params).
DESIGN_ONLY = {"time_shift_s", "rider_model"}
POLICY_CONFIGS = {"aeb": AEBConfig, "idm": IDMConfig}


def _resolve(path: str) -> tuple[type, typing.Any]:
    """(dataclass, type hint) of the field at ``path`` under CaseConfig, walking the
    dataclasses; ``ego.policy_params.<f>`` resolves in the owning policy's config."""
    if path.startswith(POLICY_PARAMS_PREFIX):
        owner, fname = POLICY_PARAMS[path]
        cls: type = POLICY_CONFIGS[owner]
        return cls, typing.get_type_hints(cls)[fname]
    return case_field(path)


@pytest.mark.parametrize("name", sorted(set(PARAMETERS) - DESIGN_ONLY))
def test_every_sweep_parameter_is_a_run_config_field_path(name):
    cls, hint = _resolve(name)
    kind = PARAMETERS[name].kind
    args = set(typing.get_args(hint)) or {hint}
    if kind == "float":
        assert float in args, f"{name}: {cls.__name__} field is {hint}"
    elif kind == "bool":
        assert hint is bool, f"{name}: {cls.__name__} field is {hint}"
    else:
        assert str in args, f"{name}: {cls.__name__} field is {hint}"


@pytest.mark.parametrize(
    "name", sorted(n for n, p in PARAMETERS.items() if p.kind == "float" and n not in DESIGN_ONLY)
)
def test_the_default_of_every_float_parameter_passes_its_own_bounds(name):
    cls, _ = _resolve(name)
    default = getattr(cls(**({"name": "x"} if cls is CaseConfig else {})), name.split(".")[-1])
    if isinstance(default, int | float):
        PARAMETERS[name].check(default, "default")


def test_a_variant_config_sets_the_field_of_the_parameters_name():
    # The value given under a name lands in the run-config field of that path: the
    # configuration written for `vei run --config` reads it back under the same name.
    spec = spec_from_dict({"design": "grid", "parameters": {"ego.policy": "aeb"}})
    values = {
        "sfm.k_des_nspm": 123.0,
        "sfm.a_veh_n": 77.0,
        "sfm.b_veh_per_m": 2.5,
        "sfm.v0_mps": 4.25,
        "sfm.mass_kg": 88.0,
        "sfm.use_vehicle_force": False,
        "ego.cruise_speed_mps": 6.5,
        "cap.t_safe_s": 1.75,
        "cap.d_buf_m": 2.5,
        "cap.a_min_mps2": -5.5,
        "cap.perception_delay_s": 0.3,
        "ego.policy": "aeb",
        "ego.policy_params.ttc_full_s": 0.7,
        # issue 24
        "decision.enabled": True,
        "decision.critical_gap_s": 1.5,
        "decision.yield_decel_mps2": 2.5,
        "traffic.cars_react": True,
        "traffic.idm_desired_speed_mps": 14.0,
        "traffic.idm_time_headway_s": 1.2,
        "traffic.idm_min_gap_m": 2.5,
        "traffic.idm_max_accel_mps2": 1.2,
        "traffic.idm_comfort_decel_mps2": 1.8,
        "traffic.max_decel_mps2": 7.5,
        "traffic.reaction_time_s": 0.8,
        "traffic.pedestrians": True,
        "v2x.penetration_rate": 0.4,
        "v2x.latency_s": 0.2,
        "v2x.latency_jitter_s": 0.01,
        "v2x.pdr_factor": 0.9,
        "v2x.position_error_std_m": 1.5,
        "v2x.clock_offset_s": -0.05,
        # issue 32
        "sfm.obstacle_braking": False,
        "sfm.obstacle_decel_mps2": 3.0,
    }
    assert set(values) | DESIGN_ONLY >= {n for n in PARAMETERS if not n.startswith("ego.pol")}
    run = variant_config(values, spec, auto_shift_s=0.0)
    raw = dataclasses.asdict(run.case)
    for name, v in values.items():
        node = raw
        for part in name.split("."):
            node = node[part]
        assert node == v, name
    again = load_config(raw, CaseConfig)
    assert again.sfm.k_des_nspm == 123.0 and again.ego.policy_params == {"ttc_full_s": 0.7}


def test_k_des_nspm_is_the_field_before_the_k_des_factor(demo_scenario):
    # sfm.k_des_nspm is SFMConfig.k_des_nspm: the aggressive preset still doubles it.
    from vei.sweep.evaluator import EngineEvaluator, variant_params

    spec = spec_from_dict(
        {
            "design": "grid",
            "parameters": {
                "rider_model": {"choices": ["normal", "aggressive"]},
                "sfm.k_des_nspm": 100.0,
            },
        }
    )
    ev = EngineEvaluator()
    prep = ev.prepare(demo_scenario)
    table = variants_table(spec, prep.scenario_id)
    batch = variant_params(table, prep.arrays, auto_shift_s=prep.auto_shift_s)
    assert list(table["rider_model"]) == ["normal", "aggressive"]
    assert list(batch.k_des_nspm) == [100.0, 200.0]
    cfgs = [variant_config(dict(r), spec, auto_shift_s=0.0).case for _, r in table.iterrows()]
    assert [c.sfm.k_des_effective_nspm for c in cfgs] == [100.0, 200.0]


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory):
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


def test_every_float_parameter_reaches_the_engine():
    floats = {n for n, p in PARAMETERS.items() if p.kind == "float"} - {"time_shift_s"}
    assert floats <= set(_PARAM_FIELDS)


@pytest.mark.parametrize(("old", "new"), sorted(RENAMED.items()))
def test_an_old_spelling_is_refused_naming_the_new_one(old, new):
    assert new in PARAMETERS and old not in PARAMETERS
    value = {"ego.policy": "none", "policy": "none", "sfm.vehicle_force": True}.get(old, 1.0)
    with pytest.raises(ConfigError) as exc:
        spec_from_dict({"design": "grid", "parameters": {old: value}}, source="s.yaml")
    assert str(exc.value) == f"s.yaml: sweep parameter '{old}' was renamed '{new}'"


def test_old_spellings_in_groups_and_replaced_parameters_are_refused(tmp_path):
    from vei.sweep.spec import load_spec

    path = tmp_path / "old.yaml"
    path.write_text("design: grid\nparameters:\n  sfm:\n    k_des: {min: 50, max: 150, num: 3}\n")
    with pytest.raises(ConfigError, match=r"old\.yaml: sweep parameter 'sfm.k_des' was renamed"):
        load_spec(path)
    raw = {"design": "grid", "parameters": {"aeb": {"ttc_full_s": 1.0}}}
    with pytest.raises(
        ConfigError, match="'aeb.ttc_full_s' was renamed 'ego.policy_params.ttc_full_s'"
    ):
        spec_from_dict(raw)
    assert set(REPLACED) == {"cap.enabled"}
    with pytest.raises(ConfigError, match=r"'cap.enabled' was replaced by 'ego.policy' \(cap"):
        spec_from_dict({"design": "grid", "parameters": {"cap.enabled": True}})


def test_nested_groups_are_the_run_configs_nesting():
    flat = spec_from_dict(
        {
            "design": "grid",
            "parameters": {
                "ego.policy": "aeb",
                "ego.policy_params.ttc_full_s": {"min": 0.5, "max": 0.9, "num": 2},
                "cap.t_safe_s": 1.5,
            },
        }
    )
    nested = spec_from_dict(
        {
            "design": "grid",
            "parameters": {
                "ego": {
                    "policy": "aeb",
                    "policy_params": {"ttc_full_s": {"min": 0.5, "max": 0.9, "num": 2}},
                },
                "cap": {"t_safe_s": 1.5},
            },
        }
    )
    assert nested == flat and nested.digest() == flat.digest()
    with pytest.raises(ConfigError, match="unknown parameter 'ego.policy_params.ttc_ful_s'"):
        spec_from_dict(
            {"design": "grid", "parameters": {"ego": {"policy_params": {"ttc_ful_s": 1.0}}}}
        )


def test_a_sweep_refuses_aeb_thresholds_that_vei_run_refuses(demo_scenario):
    raw = {
        "design": "grid",
        "parameters": {
            "ego.policy": {"choices": ["none", "aeb"]},
            "ego.policy_params.ttc_partial_s": {"choices": [1.4, 3.0]},  # default warning 2.6
        },
    }
    spec = spec_from_dict(raw)
    with pytest.raises(ConfigError) as exc:
        variants_table(spec, "demo")
    msg = str(exc.value)
    assert "variant " in msg and "(variant_index 3)" in msg  # aeb x 3.0 is the 4th row
    assert "ego.policy_params.ttc_warning_s >= ego.policy_params.ttc_partial_s" in msg
    assert "got 2.6 < 3" in msg
    # vei run refuses that row's configuration the same way
    bad = {"ego.policy": "aeb", "ego.policy_params.ttc_partial_s": 3.0}
    case = variant_config(bad, spec, auto_shift_s=0.0).case
    from vei.policy.aeb import AEB

    with pytest.raises(ConfigError, match="ttc_warning_s >= ttc_partial_s"):
        AEB(**case.ego.policy_params)
    # with no variant running aeb, its parameters would change nothing: refused
    with pytest.raises(ConfigError, match="belongs to policy 'aeb', which no variant runs"):
        spec_from_dict({**raw, "parameters": {**raw["parameters"], "ego.policy": "none"}})
    # the evaluator checks a table it is given directly (not made by variants_table)
    from vei.sweep.evaluator import EngineEvaluator, variant_params

    good = variants_table(spec_from_dict({**raw, "parameters": {"ego.policy": "aeb"}}), "d")
    good["ego.policy_params.full_decel_mps2"] = 3.0  # below the partial braking's 4.0
    prep = EngineEvaluator().prepare(demo_scenario)
    with pytest.raises(ConfigError, match="full_decel_mps2 >= ego.policy_params.partial_decel"):
        variant_params(good, prep.arrays, auto_shift_s=prep.auto_shift_s)


def test_every_sweep_spec_in_the_docs_and_examples_uses_todays_names():
    # The YAML blocks of docs/*.md and README.md that hold a sweep spec (top level, or
    # under 'sweep:' as in a catalogue settings file) and examples/*.yaml all load.
    import re
    from pathlib import Path

    import yaml

    root = Path(__file__).resolve().parents[2]
    texts = {p: p.read_text() for p in [*sorted((root / "docs").glob("*.md")), root / "README.md"]}
    blocks = [(p, b) for p, t in texts.items() for b in re.findall(r"```yaml\n(.*?)```", t, re.S)]
    blocks += [(p, p.read_text()) for p in sorted((root / "examples").glob("*.yaml"))]
    found = 0
    for path, block in blocks:
        raw = yaml.safe_load(block)
        if isinstance(raw, dict) and isinstance(raw.get("sweep"), dict):
            raw = raw["sweep"]
        if isinstance(raw, dict) and "parameters" in raw and "design" in raw:
            spec_from_dict(raw, source=str(path.relative_to(root)))
            found += 1
    assert found >= 4  # sweeps.md, policy.md, catalogue.md, examples/sweep.yaml


@pytest.mark.parametrize(
    ("policy", "ok"),
    [(None, False), ({"choices": ["none", "idm"]}, False), ({"choices": ["none", "aeb"]}, True),
     ("aeb", True)],
)  # fmt: skip
def test_a_policy_parameter_needs_its_policy_among_the_swept_ones(policy, ok):
    # Swept without any variant running aeb, ttc_full_s would change nothing.
    ego: dict = {"policy_params": {"ttc_full_s": {"choices": [0.6, 0.9]}}}
    if policy is not None:
        ego["policy"] = policy
    raw = {"design": "grid", "base": "normal-cap", "parameters": {"ego": ego}}
    if ok:
        assert spec_from_dict(raw).parameters
    else:
        with pytest.raises(ConfigError, match="belongs to policy 'aeb', which no variant runs"):
            spec_from_dict(raw)
