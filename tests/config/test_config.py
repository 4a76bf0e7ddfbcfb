"""Configuration dataclasses: paper defaults, presets, validation, loading."""

from __future__ import annotations

import json

import pytest

from vei.config import (
    CASE_PRESETS,
    PAPER_CASES,
    SFM_PRESETS,
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
    # The default rider is the calibrated one (issue 11): k_des 180 N s/m, x 2 aggressive.
    assert agg.sfm.use_vehicle_force is False and agg.sfm.k_des_effective_nspm == 360.0
    assert agg.sfm.speed_from_recording is True
    assert CASE_PRESETS["normal"].sfm is SFM_PRESETS["calibrated"]
    assert CASE_PRESETS["normal"].sfm.use_vehicle_force is True
    # The paper's rider stays available as presets.
    for name in ("normal", "aggressive", "normal-cap", "aggressive-cap"):
        paper = CASE_PRESETS[f"paper-{name}"]
        cal = CASE_PRESETS[name]
        assert (paper.name, paper.rider, paper.ego_mode) == (f"paper-{name}", "sfm", cal.ego_mode)
        assert paper.sfm.v0_mps == 5.0 and paper.sfm.speed_from_recording is False
        assert paper.sfm.use_vehicle_force is cal.sfm.use_vehicle_force
    assert CASE_PRESETS["paper-aggressive-cap"].sfm.k_des_effective_nspm == 200.0
    assert CASE_PRESETS["paper-normal"].sfm == SFMConfig()
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


def test_run_config_selects_the_papers_rider(tmp_path) -> None:
    # The documented syntax (docs/riders.md): the default 'normal' rider is the calibrated
    # one; `sfm: paper` (or `sfm: {preset: paper}`) in the case section gives the paper's.
    f = tmp_path / "run.yaml"
    f.write_text("case:\n  preset: normal-cap\n  sfm: paper\ntime_shift: auto\n")
    run = load_config(f, RunConfig)
    assert run.case.ego_mode == "cap" and run.case.sfm == SFMConfig()
    run = load_config(
        {"case": {"preset": "aggressive", "sfm": {"preset": "paper-aggressive"}}}, RunConfig
    )
    assert run.case.sfm.k_des_effective_nspm == 200.0 and not run.case.sfm.use_vehicle_force
    default = load_config({"case": "normal"}, RunConfig)
    assert default.case.sfm.speed_from_recording is True and default.case.sfm.k_des_nspm == 180.0


def test_a_speed_over_the_recorded_speed_rider_is_refused_unless_said(tmp_path) -> None:
    f = tmp_path / "run.yaml"
    f.write_text("case:\n  preset: normal\n  sfm:\n    v0_mps: 4.0\n")
    with pytest.raises(ConfigError, match=r"run\.yaml.*v0_mps would be ignored"):
        load_config(f, RunConfig)
    with pytest.raises(ConfigError, match="max_speed_mps would be ignored"):
        load_config({"preset": "calibrated", "max_speed_mps": 3.0}, SFMConfig)
    own = load_config(
        {"case": {"preset": "normal", "sfm": {"v0_mps": 4.0, "speed_from_recording": False}}},
        RunConfig,
    )
    assert own.case.sfm.v0_mps == 4.0 and own.case.sfm.speed_from_recording is False
    paper = load_config({"preset": "paper", "v0_mps": 4.0}, SFMConfig)  # no recorded speeds
    assert paper.v0_mps == 4.0 and paper.k_des_nspm == 100.0
