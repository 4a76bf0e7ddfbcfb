"""Sweep spec: YAML loading, validation errors, designs and the variants table."""

from __future__ import annotations

import numpy as np
import pytest

from vei.errors import ConfigError, InputError
from vei.sweep.spec import (
    PARAMETERS,
    load_spec,
    spec_from_dict,
    variant_id,
    variant_seed,
    variants_table,
)

GRID_YAML = """\
design: grid
parameters:
  time_shift_s: {min: -1.0, max: 1.0, num: 5}
  rider_model: {choices: [normal, aggressive]}
  ego:
    cruise_speed_mps: {min: 4.0, max: 6.0, num: 3}
  ego.policy: paper-cap
"""


def test_grid_yaml_is_the_cartesian_product(tmp_path):
    path = tmp_path / "sweep.yaml"
    path.write_text(GRID_YAML)
    spec = load_spec(path)
    assert spec.design == "grid"
    assert spec.names == ("time_shift_s", "rider_model", "ego.cruise_speed_mps", "ego.policy")
    table = variants_table(spec, "demo")
    assert len(table) == 5 * 2 * 3 == spec.n_variants()
    assert list(table.columns[:4]) == ["variant_id", "scenario_id", "variant_index", "seed"]
    assert sorted(set(table["time_shift_s"])) == pytest.approx([-1.0, -0.5, 0.0, 0.5, 1.0])
    assert sorted(set(table["ego.cruise_speed_mps"])) == pytest.approx([4.0, 5.0, 6.0])
    assert set(table["rider_model"]) == {"normal", "aggressive"}
    assert (table["ego.policy"] == "paper-cap").all()
    # last parameter varies fastest: rows 0..2 differ only in the cruise speed
    assert list(table["ego.cruise_speed_mps"][:3]) == pytest.approx([4.0, 5.0, 6.0])
    assert table["variant_id"].is_unique
    assert list(table["variant_index"]) == list(range(30))


def test_variant_id_and_seed_are_stable_and_depend_on_scenario_and_values():
    a = variant_id("demo", {"time_shift_s": 0.5, "rider_model": "normal"})
    assert a == variant_id("demo", {"rider_model": "normal", "time_shift_s": 0.5})  # order-free
    assert a != variant_id("other", {"time_shift_s": 0.5, "rider_model": "normal"})
    assert a != variant_id("demo", {"time_shift_s": 0.5000001, "rider_model": "normal"})
    assert len(a) == 16 and int(a, 16) >= 0
    s = variant_seed(a, 7)
    assert s == variant_seed(a, 7) and 0 <= s < 2**31
    assert s != variant_seed(a, 8)


def test_lhs_is_seeded_and_stratified():
    raw = {
        "design": "lhs",
        "n_samples": 40,
        "seed": 11,
        "parameters": {
            "time_shift_s": {"min": -2.0, "max": 2.0},
            "sfm.k_des_nspm": {"min": 50.0, "max": 150.0},
            "rider_model": {"choices": ["replay", "normal", "aggressive", "normal"][:3]},
        },
    }
    t1 = variants_table(spec_from_dict(raw), "s")
    t2 = variants_table(spec_from_dict(raw), "s")
    assert t1.equals(t2)
    assert len(t1) == 40
    # Latin hypercube: exactly one sample in each of the 40 equal strata of every range
    strata = np.floor((t1["time_shift_s"].to_numpy() + 2.0) / 4.0 * 40).astype(int)
    assert sorted(strata) == list(range(40))
    strata_k = np.floor((t1["sfm.k_des_nspm"].to_numpy() - 50.0) / 100.0 * 40).astype(int)
    assert sorted(strata_k) == list(range(40))
    # 3 choices over 40 rows: strata of width 40/3 -> 13 or 14 each
    counts = t1["rider_model"].value_counts()
    assert set(counts.index) == {"replay", "normal", "aggressive"}
    assert counts.min() >= 13 and counts.max() <= 14
    other = variants_table(spec_from_dict({**raw, "seed": 12}), "s")
    assert not np.allclose(other["time_shift_s"], t1["time_shift_s"])


def test_random_design_within_bounds_and_duplicates_kept_once():
    spec = spec_from_dict(
        {
            "design": "random",
            "n_samples": 50,
            "seed": 1,
            "parameters": {
                "rider_model": {"choices": ["normal", "aggressive"]},
                "ego.policy": "none",
            },
        }
    )
    table = variants_table(spec, "s")
    # only two distinct parameter sets exist: identical simulations are run once
    assert len(table) == 2
    assert set(table["rider_model"]) == {"normal", "aggressive"}
    spec2 = spec_from_dict(
        {
            "design": "random",
            "n_samples": 200,
            "seed": 3,
            "parameters": {"cap.a_min_mps2": {"min": -8.0, "max": -2.0}},
        }
    )
    t = variants_table(spec2, "s")
    assert len(t) == 200
    assert t["cap.a_min_mps2"].between(-8.0, -2.0).all()


@pytest.mark.parametrize(
    ("raw", "needle"),
    [
        ({"design": "grid", "parameters": {"time_shift_s": 1.0}, "sede": 1}, "sede"),
        ({"design": "grid", "parameters": {"time_shft_s": 1.0}}, "time_shft_s"),
        ({"design": "grid", "parameters": {"sfm": {"kdes": 1.0}}}, "sfm.kdes"),
        (
            {"design": "grid", "parameters": {"time_shift_s": {"min": 0, "max": 1, "step": 2}}},
            "step",
        ),
        (
            {"design": "grid", "parameters": {"time_shift_s": {"min": 0.0, "max": 1.0}}},
            "needs 'num'",
        ),
        ({"design": "lhs", "parameters": {"time_shift_s": 0.0}}, "n_samples"),
        ({"design": "lhs", "n_samples": 0, "parameters": {"time_shift_s": 0.0}}, "n_samples"),
        ({"design": "grid", "n_samples": 4, "parameters": {"time_shift_s": 0.0}}, "n_samples"),
        ({"design": "sobol", "parameters": {"time_shift_s": 0.0}}, "design"),
        ({"design": "grid", "parameters": {"sfm.k_des_nspm": 0.0}}, "sfm.k_des_nspm must be > 0"),
        ({"design": "grid", "parameters": {"cap.a_min_mps2": 3.0}}, "cap.a_min_mps2 must be < 0"),
        ({"design": "grid", "parameters": {"rider_model": "wild"}}, "rider_model"),
        ({"design": "grid", "parameters": {"sfm.use_vehicle_force": 1}}, "true or false"),
        (
            {"design": "grid", "parameters": {"ego.policy": "cap"}},
            "ego.policy: policy 'cap': expected a built-in name",
        ),
        (
            {"design": "grid", "parameters": {"time_shift_s": {"min": 2.0, "max": 1.0, "num": 2}}},
            "min",
        ),
        ({"design": "grid", "parameters": {}}, "parameters"),
        ({"design": "grid", "parameters": {"rider_model": {"choices": []}}}, "non-empty"),
        (
            {"design": "grid", "parameters": {"rider_model": {"min": 0, "max": 1, "num": 2}}},
            "range",
        ),
    ],
)
def test_invalid_specs_name_the_problem(raw, needle):
    with pytest.raises(ConfigError, match="sweep.yaml") as exc:
        spec_from_dict(raw, source="sweep.yaml")
    assert needle in str(exc.value)


def test_load_spec_errors_name_the_file(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("design: grid\nparameters: {time_shift_s: [\n")
    with pytest.raises(InputError, match="bad.yaml"):
        load_spec(bad)
    with pytest.raises(InputError, match="missing.yaml"):
        load_spec(tmp_path / "missing.yaml")
    typo = tmp_path / "typo.yaml"
    typo.write_text("design: grid\nparamters: {}\n")
    with pytest.raises(ConfigError, match=r"typo\.yaml.*paramters"):
        load_spec(typo)


def test_digest_changes_with_content_and_round_trips():
    spec = spec_from_dict(
        {"design": "grid", "parameters": {"time_shift_s": {"min": 0.0, "max": 1.0, "num": 3}}}
    )
    again = spec_from_dict(spec.to_dict())
    assert again == spec and again.digest() == spec.digest()
    other = spec_from_dict(
        {"design": "grid", "parameters": {"time_shift_s": {"min": 0.0, "max": 1.0, "num": 4}}}
    )
    assert other.digest() != spec.digest()


def test_every_documented_parameter_is_known():
    assert set(PARAMETERS) == {
        "time_shift_s",
        "rider_model",
        "sfm.k_des_nspm",
        "sfm.a_veh_n",
        "sfm.b_veh_per_m",
        "sfm.v0_mps",
        "sfm.mass_kg",
        "sfm.use_vehicle_force",
        "ego.cruise_speed_mps",
        "cap.t_safe_s",
        "cap.d_buf_m",
        "cap.a_min_mps2",
        "cap.perception_delay_s",
        "ego.policy",
        "ego.policy_params.ttc_warning_s",
        "ego.policy_params.ttc_partial_s",
        "ego.policy_params.ttc_full_s",
        "ego.policy_params.partial_decel_mps2",
        "ego.policy_params.full_decel_mps2",
        "ego.policy_params.max_accel_mps2",
        "ego.policy_params.comfort_decel_mps2",
        "ego.policy_params.time_headway_s",
        "ego.policy_params.min_gap_m",
        # issue 24: the rider's decisions, the road users that react
        "decision.enabled",
        "decision.critical_gap_s",
        "decision.yield_decel_mps2",
        "traffic.cars_react",
        "traffic.idm_desired_speed_mps",
        "traffic.idm_time_headway_s",
        "traffic.idm_min_gap_m",
        "traffic.idm_max_accel_mps2",
        "traffic.idm_comfort_decel_mps2",
        "traffic.max_decel_mps2",
        "traffic.reaction_time_s",
        "traffic.pedestrians",
        "v2x.penetration_rate",
        "v2x.latency_s",
        "v2x.latency_jitter_s",
        "v2x.pdr_factor",
        "v2x.position_error_std_m",
        "v2x.clock_offset_s",
        # issue 32: the rider brakes for a car in its way
        "sfm.obstacle_braking",
        "sfm.obstacle_decel_mps2",
    }


def test_shipped_example_spec_is_valid():
    from pathlib import Path

    path = Path(__file__).resolve().parents[2] / "examples" / "sweep.yaml"
    spec = load_spec(path)
    assert spec.design == "lhs" and spec.n_samples == 2000 and spec.base == "normal-cap"
    table = variants_table(spec, "example")
    assert len(table) == 2000
    assert table["cap.a_min_mps2"].between(-8.0, -4.0).all()
    assert (table["sfm.b_veh_per_m"] == 3.5).all()


def test_swept_v0_is_the_riders_own_speed_over_the_calibrated_default():
    # The default rider takes its speeds from its recording; a swept v0 must not be ignored.
    from vei.config import CASE_PRESETS
    from vei.sweep.spec import variant_config

    spec = spec_from_dict({"design": "grid", "parameters": {"sfm.v0_mps": 4.0}})
    assert CASE_PRESETS[spec.base].sfm.speed_from_recording is True
    case = variant_config({"sfm.v0_mps": 4.0}, spec, auto_shift_s=0.0).case
    assert case.sfm.v0_mps == 4.0 and case.sfm.speed_from_recording is False
    kept = variant_config({"sfm.k_des_nspm": 90.0}, spec, auto_shift_s=0.0).case
    assert kept.sfm.k_des_nspm == 90.0 and kept.sfm.speed_from_recording is True
