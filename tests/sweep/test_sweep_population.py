"""Sweeps over a rider population sampled from a rider profile (rider: {profile, sample})."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from vei.calibrate.population import RIDER_COLUMN, RIDER_PARAM_COLUMNS, sample_riders
from vei.calibrate.profile import SAMPLE_BOUNDS
from vei.config import RiderPopulationConfig, RunConfig, load_config
from vei.errors import ConfigError
from vei.sweep.run import (
    EngineEvaluator,
    read_results,
    run_sweep,
    variant_params,
    write_variant_configs,
)
from vei.sweep.spec import (
    row_params,
    spec_from_dict,
    variant_config,
    variants_table,
)


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory) -> Path:
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


def _spec(**extra):
    raw = {
        "design": "grid",
        "base": "normal",
        "seed": 4,
        "parameters": {"time_shift_s": {"min": -1.0, "max": 1.0, "num": 3}},
        "rider": {"profile": "calibrated", "sample": 8},
    }
    raw.update(extra)
    return spec_from_dict(raw)


def test_variants_cover_every_rider_for_every_design_point() -> None:
    spec = _spec()
    assert spec.rider == RiderPopulationConfig("calibrated", 8, "escooter", 4)  # spec seed
    assert spec.n_variants() == 24
    t = variants_table(spec, "scen")
    assert len(t) == 24 and t["variant_id"].is_unique
    assert sorted(t[RIDER_COLUMN].unique()) == list(range(8))
    # Each time shift runs with the same 8 riders; they are the population's seeded sample.
    riders = sample_riders(spec.rider)
    for _, grp in t.groupby("time_shift_s"):
        np.testing.assert_array_equal(grp["rider.v0_mps"], riders["v0_mps"])
        np.testing.assert_array_equal(grp["rider.k_des_nspm"], riders["k_des_nspm"])
    # Same seed -> same variants (ids and parameters); another seed -> other riders.
    again = variants_table(_spec(), "scen")
    assert again.equals(t)
    other = variants_table(_spec(seed=5), "scen")
    assert not np.array_equal(other["rider.v0_mps"], t["rider.v0_mps"])
    # Physical bounds.
    for col in ("v0_mps", "lookahead_m", "max_speed_mps", "max_accel_mps2"):
        lo, hi = SAMPLE_BOUNDS[col]
        assert t[f"rider.{col}"].between(lo, hi).all()
    assert (t["rider.k_des_nspm"] > 0).all() and (t["rider.mass_kg"] == 95.0).all()
    d = spec.to_dict()
    assert d["rider"] == {"profile": "calibrated", "sample": 8, "category": "escooter", "seed": 4}
    assert spec_from_dict(d) == spec


def test_population_spec_errors() -> None:
    with pytest.raises(ConfigError, match="rider: missing 'sample'"):
        _spec(rider={"profile": "calibrated"})
    with pytest.raises(ConfigError, match="unknown key"):
        _spec(rider={"profile": "calibrated", "sample": 3, "samples": 3})
    with pytest.raises(ConfigError, match="do not also sweep sfm.v0_mps"):
        _spec(parameters={"sfm.v0_mps": {"min": 2.0, "max": 4.0, "num": 2}})
    with pytest.raises(ConfigError, match="sample must be >= 1"):
        _spec(rider={"profile": "calibrated", "sample": 0})


def test_population_params_equal_each_rows_own_configuration(demo_scenario, tmp_path) -> None:
    from vei.sim.state import VariantParams

    spec = _spec(
        base="normal-cap",
        parameters={
            "time_shift_s": {"min": -1.0, "max": 1.0, "num": 2},
            "rider_model": {"choices": ["normal", "aggressive"]},
        },
    )
    ev = EngineEvaluator(time_shift_reference="auto", base="normal-cap")
    prep = ev.prepare(demo_scenario)
    table = variants_table(spec, prep.scenario_id)
    batch = variant_params(
        table,
        prep.arrays,
        base="normal-cap",
        time_shift_reference="auto",
        auto_shift_s=prep.auto_shift_s,
    )
    assert batch.batch_size == 32
    for i, row in table.iterrows():
        cfg = variant_config(row_params(row, spec), spec, auto_shift_s=prep.auto_shift_s)
        one = VariantParams.from_case(cfg.case, prep.arrays, 1, time_shift_s=cfg.time_shift)
        for f in dataclasses.fields(one):
            if f.name == "labels":
                continue
            got, want = getattr(batch, f.name)[i], getattr(one, f.name)[0]
            if not isinstance(want, int | float | np.number | np.bool_):  # e.g. a policy
                assert got == want, f.name
            else:
                assert got == pytest.approx(want, rel=1e-15), f.name
        factor = 2.0 if row["rider_model"] == "aggressive" else 1.0
        assert batch.k_des_nspm[i] == pytest.approx(factor * row["rider.k_des_nspm"])
        assert batch.v0_mps[i] == row["rider.v0_mps"]
    # The variant's config file runs the same rider (vei run --config reads it back).
    paths = write_variant_configs(tmp_path / "cfg", table.iloc[:2], spec, prep.auto_shift_s)
    back = load_config(paths[1], RunConfig)
    assert back.case.sfm.lookahead_m == pytest.approx(table.iloc[1]["rider.lookahead_m"])
    assert not back.case.sfm.speed_from_recording


def test_population_sweep_runs_and_scores_every_rider(demo_scenario, tmp_path) -> None:
    spec = _spec(base="normal-cap", parameters={"time_shift_s": {"min": 0.0, "max": 0.0, "num": 1}})
    run_sweep(demo_scenario, spec, tmp_path / "out", chunk_size=16, progress=False)
    res = read_results(tmp_path / "out")
    assert len(res) == 8
    assert set(RIDER_PARAM_COLUMNS) <= set(res.columns) and RIDER_COLUMN in res.columns
    assert res["collision"].dtype == bool
    # Different riders, different outcomes (the population matters to the result).
    assert res["min_gap_m"].nunique() > 1
