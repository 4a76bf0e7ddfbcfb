"""A sweep spec's ``perception`` section: parsed into PerceptionConfig, applied to every
variant (variant_config and the engine's variant_params), and written into the variants'
run configurations."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from vei.config import RunConfig, load_config
from vei.config.perception import PerceptionConfig
from vei.errors import ConfigError
from vei.sweep.run import read_results, run_sweep, write_variant_configs
from vei.sweep.spec import load_spec, spec_from_dict, variant_config

PERCEPTION = {"enabled": True, "fov_deg": 60, "detection_probability": 0.7, "seed": 3}
SPEC = {
    "design": "grid",
    "base": "normal-cap",
    "parameters": {
        "time_shift_s": {"min": -1.0, "max": 1.0, "num": 3},
        "ego.cruise_speed_mps": {"min": 5.0, "max": 8.0, "num": 3},
    },
}


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory) -> Path:
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


def test_perception_section_round_trips(tmp_path) -> None:
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump({**SPEC, "perception": PERCEPTION}))
    spec = load_spec(path)
    assert spec.perception == PerceptionConfig(
        enabled=True, fov_deg=60.0, detection_probability=0.7, seed=3
    )
    again = spec_from_dict(spec.to_dict())
    assert again == spec and again.digest() == spec.digest()
    assert spec.digest() != spec_from_dict(SPEC).digest()  # resume refuses the other one
    cfg = variant_config({"time_shift_s": 0.5}, spec, auto_shift_s=1.0)
    assert cfg.case.perception == spec.perception and cfg.time_shift == 1.5
    assert variant_config({}, spec_from_dict(SPEC), auto_shift_s=0.0).case.perception is None


@pytest.mark.parametrize(
    ("section", "message"),
    [
        ({"enabled": True, "fov": 60}, "unknown key(s) fov"),
        ({"enabled": True, "detection_probability": 1.5}, "detection_probability must be <= 1"),
        ({"enabled": "yes"}, "perception.enabled must be true or false"),
        ([1, 2], "'perception' must be a mapping"),
    ],
)
def test_perception_section_errors_name_the_file_and_key(tmp_path, section, message) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump({**SPEC, "perception": section}))
    with pytest.raises(ConfigError) as exc:
        load_spec(path)
    assert str(path) in str(exc.value) and message in str(exc.value)


@pytest.mark.slow
def test_perception_changes_the_sweep_and_is_written_into_variant_configs(
    demo_scenario, tmp_path
) -> None:
    plain = spec_from_dict(SPEC)
    seen = spec_from_dict({**SPEC, "perception": PERCEPTION})
    run_sweep(demo_scenario, plain, tmp_path / "plain", chunk_size=64, progress=False)
    run_sweep(demo_scenario, seen, tmp_path / "seen", chunk_size=64, progress=False)
    a, b = read_results(tmp_path / "plain"), read_results(tmp_path / "seen")
    assert list(a["variant_id"]) == list(b["variant_id"])  # same design points
    # A narrower, unreliable sensor: the CAP reacts later, somewhere the runs differ.
    cols = ["min_gap_m", "peak_decel_mps2", "ego_speed_min_mps"]
    assert not a[cols].equals(b[cols])
    paths = write_variant_configs(tmp_path / "cfg", b.head(2), seen, auto_shift_s=0.0)
    for p in paths:
        cfg = load_config(p, RunConfig)
        assert cfg.case.perception == seen.perception
