"""A sweep spec's ``v2x`` section and ``v2x.*`` parameters: parsed, applied to every variant,
written into the variants' run configurations, and ``vei run --config`` of a variant equals
its sweep row bit for bit (the V2X draws are keyed by the variant id)."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from tests.experiments.rerun import assert_runs_equal_sweep
from vei.config import RunConfig, V2XConfig, load_config
from vei.errors import ConfigError
from vei.sweep.run import DEFAULT_METRICS, read_results, run_sweep, write_variant_configs
from vei.sweep.spec import load_spec, spec_from_dict, variant_config

SPEC = {
    "design": "grid",
    "base": "replay",
    "time_shift_reference": "zero",
    "perception": {"enabled": True},
    "v2x": {"enabled": True, "seed": 4},
    "parameters": {
        "ego.policy": "paper-cap",
        "time_shift_s": {"min": -5.0, "max": -3.0, "num": 3},
        "v2x.latency_s": {"choices": [0.0, 1.0]},
        "v2x.pdr_factor": {"choices": [1.0, 0.3]},
        "v2x.penetration_rate": {"choices": [1.0]},
    },
}


@pytest.fixture(scope="module")
def occluded(tmp_path_factory) -> Path:
    from vei.experiments.v2x_study import occluded_crossing
    from vei.io.scenario import write_scenario

    return write_scenario(occluded_crossing(), tmp_path_factory.mktemp("v2x") / "scenario")


def test_v2x_section_round_trips_and_sets_the_variants(tmp_path):
    path = tmp_path / "spec.yaml"
    path.write_text(yaml.safe_dump(SPEC))
    spec = load_spec(path)
    assert spec.v2x == V2XConfig(enabled=True, seed=4)
    again = spec_from_dict(spec.to_dict())
    assert again == spec and again.digest() == spec.digest()
    cfg = variant_config({"v2x.latency_s": 0.5, "v2x.pdr_factor": 0.2, "time_shift_s": -4.0},
                         spec)  # fmt: skip
    assert cfg.case.v2x == V2XConfig(enabled=True, seed=4, latency_s=0.5, pdr_factor=0.2)
    assert cfg.time_shift == -4.0


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"v2x": None}, "parameters v2x.penetration_rate, v2x.latency_s, v2x.pdr_factor need V2X"),
        ({"v2x": {"enabled": False}}, "need V2X: add 'v2x: {enabled: true}'"),
        ({"v2x": {"enabled": True, "penetration": 1}}, "v2x: unknown key(s) penetration"),
        ({"v2x": {"enabled": True, "pdr_distance_m": [0, 9], "pdr": [0.5, 0.9]}},
         "v2x.pdr must not increase with distance"),
        ({"v2x": [1]}, "'v2x' must be a mapping"),
    ],
)  # fmt: skip
def test_bad_v2x_sections_are_errors_naming_the_file(tmp_path, change, message):
    raw = {**SPEC, **change}
    if raw["v2x"] is None:
        del raw["v2x"]
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(ConfigError) as exc:
        load_spec(path)
    assert str(path) in str(exc.value) and message in str(exc.value)


@pytest.mark.parametrize(
    ("param", "value", "message"),
    [
        ("v2x.penetration_rate", 1.5, "v2x.penetration_rate must be <= 1"),
        ("v2x.latency_s", -0.1, "v2x.latency_s must be >= 0"),
        ("v2x.pdr_factor", -0.5, "v2x.pdr_factor must be >= 0"),
    ],
)
def test_swept_values_outside_their_bounds_are_refused(param, value, message):
    raw = {**SPEC, "parameters": {**SPEC["parameters"], param: {"choices": [value]}}}
    with pytest.raises(ConfigError, match=message):
        spec_from_dict(raw)


@pytest.mark.slow
def test_vei_run_of_each_v2x_variant_equals_the_sweep_row(occluded, tmp_path):
    spec = spec_from_dict(SPEC)
    run_sweep(occluded, spec, tmp_path / "sweep", chunk_size=5, progress=False,
              record_critical=False)  # fmt: skip
    df = read_results(tmp_path / "sweep")
    assert len(df) == 12
    # Losses and latency change outcomes: both occur in this grid.
    assert df["collision"].any() and not df["collision"].all()
    paths = write_variant_configs(tmp_path / "configs", df, spec, 0.0)
    for p in paths[:2]:
        assert load_config(p, RunConfig).case.v2x.enabled
    compared = assert_runs_equal_sweep(occluded, paths, df, tmp_path / "runs")
    assert compared == 12 * len(DEFAULT_METRICS)


def test_the_shipped_v2x_examples_are_valid():
    root = Path(__file__).resolve().parents[2] / "examples"
    spec = load_spec(root / "v2x_sweep.yaml")
    assert spec.v2x is not None and spec.v2x.enabled and spec.n_variants() == 9 * 3 * 3
    cfg = load_config(root / "v2x_occluded.yaml", RunConfig)
    assert cfg.case.v2x.enabled and cfg.case.perception.enabled and cfg.time_shift == -4.1
