"""Configuration dataclasses: paper defaults, presets, validation, loading."""

from __future__ import annotations

import json

import pytest

from vei.config import (
    CASE_PRESETS,
    PAPER_CASES,
    CAPConfig,
    CaseConfig,
    EgoConfig,
    RunConfig,
    SFMConfig,
    SimConfig,
    case_preset,
    config_to_dict,
    load_config,
)
from vei.errors import ConfigError


def test_paper_values_are_the_defaults() -> None:
    s = SFMConfig()
    assert (s.k_des_nspm, s.a_veh_n, s.b_veh_per_m, s.v0_mps) == (100.0, 100.0, 3.5, 5.0)
    e = EgoConfig()
    assert (e.kp, e.ki, e.kd) == (0.05, 0.05, 0.05)
    c = CAPConfig()
    assert (c.t_safe_s, c.d_buf_m) == (2.0, 3.0)
    assert SimConfig().dt_s == 0.05


def test_presets_of_the_five_configurations() -> None:
    assert PAPER_CASES == ("replay", "normal", "aggressive", "normal-cap", "aggressive-cap")
    assert CASE_PRESETS["replay"].rider == "replay" and CASE_PRESETS["replay"].ego_mode == "pid"
    agg = CASE_PRESETS["aggressive-cap"]
    assert agg.rider == "sfm" and agg.ego_mode == "cap"
    assert agg.sfm.use_vehicle_force is False and agg.sfm.k_des_effective_nspm == 200.0
    assert CASE_PRESETS["normal"].sfm.use_vehicle_force is True
    assert CASE_PRESETS["replay-speed"].ego_mode == "replay-speed"
    assert case_preset("normal-cap", name="x").name == "x"
    with pytest.raises(ConfigError):
        case_preset("reckless")


@pytest.mark.parametrize(
    ("cls", "kwargs"),
    [
        (SFMConfig, {"mass_kg": 0.0}),
        (SFMConfig, {"desired_velocity": "exact"}),
        (SFMConfig, {"use_vehicle_force": 1}),
        (SFMConfig, {"k_des_nspm": float("nan")}),
        (EgoConfig, {"cruise_speed_mps": "fast"}),
        (EgoConfig, {"max_decel_mps2": -8.0}),
        (CAPConfig, {"a_min_mps2": 6.0}),
        (CAPConfig, {"braking_law": "hard"}),
        (SimConfig, {"dt_s": 0.0}),
        (SimConfig, {"duration_s": 0.0}),
    ],
)
def test_invalid_values_raise(cls, kwargs) -> None:
    with pytest.raises(ConfigError):
        cls(**kwargs)


def test_cap_needs_reachable_deceleration() -> None:
    with pytest.raises(ConfigError, match="max_decel"):
        CaseConfig(name="x", ego_mode="cap", ego=EgoConfig(max_decel_mps2=4.0))


def test_load_yaml_with_preset_and_overrides(tmp_path) -> None:
    f = tmp_path / "mine.yaml"
    f.write_text(
        "preset: normal-cap\nname: mine\ncap:\n  t_safe_s: 5\nego:\n  cruise_speed_mps: 5.6\n"
    )
    cfg = load_config(f, CaseConfig)
    assert cfg.name == "mine" and cfg.ego_mode == "cap" and cfg.rider == "sfm"
    assert cfg.cap.t_safe_s == 5.0 and cfg.cap.d_buf_m == 3.0
    assert cfg.ego.cruise_speed_mps == 5.6 and cfg.ego.kp == 0.05


def test_unknown_keys_are_errors(tmp_path) -> None:
    f = tmp_path / "typo.yaml"
    f.write_text("preset: normal\ncap:\n  t_safe: 5\n")
    with pytest.raises(ConfigError, match="t_safe") as exc:
        load_config(f, CaseConfig)
    assert str(f) in str(exc.value)
    with pytest.raises(ConfigError, match="colour"):
        load_config({"name": "x", "colour": "red"}, CaseConfig)
    with pytest.raises(ConfigError, match="preset"):
        load_config({"preset": "unknown"}, CaseConfig)
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "missing.yaml", CaseConfig)


def test_json_round_trip(tmp_path) -> None:
    run = RunConfig(case=case_preset("aggressive-cap"), sim=SimConfig(dt_s=0.02), time_shift=1.5)
    f = tmp_path / "run.json"
    f.write_text(json.dumps(config_to_dict(run)))
    assert load_config(f, RunConfig) == run
    assert load_config({"case": "normal"}, RunConfig).time_shift == "auto"
    with pytest.raises(ConfigError):
        RunConfig(case=case_preset("normal"), time_shift="later")
