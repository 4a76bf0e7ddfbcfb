"""V2XConfig: validated on construction, errors name the field; read from run configs."""

from __future__ import annotations

import dataclasses

import pytest
import yaml

from vei.config import RunConfig, V2XConfig, config_to_dict, load_config
from vei.config.v2x import DEFAULT_LATENCY, check_pdr_table
from vei.errors import ConfigError


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"penetration_rate": 1.2}, "v2x.penetration_rate must be <= 1, got 1.2"),
        ({"penetration_rate": -0.1}, "v2x.penetration_rate must be >= 0, got -0.1"),
        ({"latency_s": -0.01}, "v2x.latency_s must be >= 0, got -0.01"),
        ({"latency_jitter_s": -1.0}, "v2x.latency_jitter_s must be >= 0"),
        ({"pdr_distance_m": [0, 50, 100], "pdr": [1.0, 0.7, 0.9]},
         "v2x.pdr must not increase with distance: 0.9 at 100 m after 0.7 at 50 m (v2x.pdr[2])"),
        ({"pdr_distance_m": [0, 50], "pdr": [1.1, 0.5]}, "v2x.pdr[0] must be in [0, 1], got 1.1"),
        ({"pdr_distance_m": [0, 50], "pdr": [1.0, -0.2]}, "v2x.pdr[1] must be in [0, 1]"),
        ({"pdr_distance_m": [0, 50, 50], "pdr": [1.0, 0.5, 0.4]},
         "v2x.pdr_distance_m must increase strictly"),
        ({"pdr_distance_m": [0, 50], "pdr": [1.0]}, "v2x.pdr has 1 values but v2x.pdr_distance_m has 2"),
        ({"pdr": [1.0, 0.5]}, "v2x.pdr_distance_m and v2x.pdr go together"),
        ({"pdr_factor": 1.5}, "v2x.pdr_factor must be <= 1"),
        ({"technology": "5g"}, "v2x.technology must be one of its-g5, c-v2x-pc5"),
        ({"t_check_vam_gen_s": 0.2}, "v2x.t_check_vam_gen_s (0.2) must be <= v2x.t_gen_vam_min_s"),
        ({"position_error_tau_s": 0.0}, "v2x.position_error_tau_s must be > 0"),
        ({"sender_categories": ["escooter", "tram"]}, "v2x.sender_categories: unknown 'tram'"),
        ({"enabled": "yes"}, "v2x.enabled must be true or false"),
        ({"latency_distribution": "normal"}, "v2x.latency_distribution must be one of"),
        ({"seed": 1.5}, "v2x.seed must be an integer"),
        ({"environment": "rural"}, "v2x.environment must be one of urban, highway"),
        ({"nlos_loss_db": 9.0}, "v2x.nlos_loss_db and v2x.nlos_loss_std_db go together"),
        ({"nlos_loss_db": -1.0, "nlos_loss_std_db": 1.0}, "v2x.nlos_loss_db must be >= 0"),
        ({"rider_antenna_height_m": 0.0}, "v2x.rider_antenna_height_m must be > 0"),
        ({"pdr_slope_db_per_decade": 0.0}, "v2x.pdr_slope_db_per_decade must be > 0"),
        ({"buildings": 1}, "v2x.buildings must be true or false"),
    ],
)  # fmt: skip
def test_bad_settings_are_errors_naming_the_field(kwargs, message):
    with pytest.raises(ConfigError) as exc:
        V2XConfig(**kwargs)
    assert message in str(exc.value)


def test_defaults_and_technology_defaults():
    cfg = V2XConfig()
    assert not cfg.enabled and cfg.technology == "its-g5"
    assert (cfg.t_gen_vam_min_s, cfg.t_gen_vam_max_s, cfg.t_check_vam_gen_s) == (0.1, 5.0, 0.1)
    assert (cfg.position_threshold_m, cfg.speed_threshold_mps, cfg.heading_threshold_deg) == (
        4.0, 0.5, 4.0,
    )  # fmt: skip
    assert cfg.latency == DEFAULT_LATENCY["its-g5"]
    # the link budget unless a measured table is given; TR 37.885's blockage by case
    assert cfg.pdr_table is None and cfg.nlos_loss_db is None and cfg.environment == "urban"
    assert (cfg.rider_antenna_height_m, cfg.car_antenna_height_m) == (1.5, 1.6)
    pc5 = V2XConfig(technology="c-v2x-pc5")
    assert pc5.latency == DEFAULT_LATENCY["c-v2x-pc5"] == (0.001, 0.044, "uniform")
    assert V2XConfig(technology="c-v2x-pc5", latency_s=0.02).latency == (0.02, 0.044, "uniform")
    assert pc5.default_for("latency_jitter_s") == 0.044
    d, p = check_pdr_table([0, 10.0], [1, 1])
    assert d == (0.0, 10.0) and p == (1.0, 1.0)


def test_run_config_reads_writes_and_refuses_unknown_keys(tmp_path):
    path = tmp_path / "run.yaml"
    raw = {"case": {"preset": "normal-cap", "v2x": {"enabled": True, "technology": "c-v2x-pc5",
           "penetration_rate": 0.5, "latency_s": 0, "pdr_distance_m": [0, 100],
           "pdr": [1, 0.5]}}, "time_shift": 0.0}  # fmt: skip
    path.write_text(yaml.safe_dump(raw))
    cfg = load_config(path, RunConfig)
    assert cfg.case.v2x.penetration_rate == 0.5 and cfg.case.v2x.latency_s == 0.0
    assert cfg.case.v2x.pdr == (1.0, 0.5)
    back = load_config(config_to_dict(cfg), RunConfig)
    assert back == cfg
    raw["case"]["v2x"]["penetration"] = 0.5
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError, match="unknown key.*penetration"):
        load_config(path, RunConfig)
    raw["case"]["v2x"] = {"enabled": True, "penetration_rate": 2}
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError, match=f"{path}.*v2x.penetration_rate must be <= 1"):
        load_config(path, RunConfig)
    # without the section: off
    assert not load_config({"case": "normal-cap"}, RunConfig).case.v2x.enabled
    assert dataclasses.asdict(V2XConfig())["enabled"] is False
