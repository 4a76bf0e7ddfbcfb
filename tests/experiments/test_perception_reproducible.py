"""Perception noise and missed detections are keyed by the variant's label, not its position.

With position / velocity noise and a detection probability < 1 the perception draws random
numbers (vei.policy.perception_random). They used to be keyed by a variant's index in the
simulated batch, so a sweep variant at index i > 0 of its chunk perceived differently when
re-run alone with ``vei run``. Now the key is a 64-bit hash of the variant's label (a sweep
labels a variant by its variant id; its written run configuration is named by the same id)
combined with ``PerceptionConfig.seed``.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from tests.experiments.rerun import assert_runs_equal_sweep
from vei.config import CASE_PRESETS, SFM_PRESETS, CaseConfig
from vei.config.perception import PerceptionConfig
from vei.policy.perception_random import label_keys
from vei.sim.engine import _RECORDED, simulate
from vei.sim.params import VariantParams
from vei.sweep.run import (
    DEFAULT_METRICS,
    EngineEvaluator,
    read_results,
    run_sweep,
    write_variant_configs,
)
from vei.sweep.spec import spec_from_dict

NOISY = PerceptionConfig(
    enabled=True,
    position_noise_std_m=0.4,
    velocity_noise_std_mps=0.4,
    detection_probability=0.7,
    seed=11,
)
NOISY_CAP = CaseConfig(
    name="noisy-cap", rider="sfm", sfm=SFM_PRESETS["normal"], ego_mode="cap", perception=NOISY
)


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory) -> Path:
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


@pytest.fixture(scope="module")
def prepared(demo_scenario):
    return EngineEvaluator(base="normal-cap").prepare(demo_scenario)


def test_label_keys_stable_distinct_and_position_free() -> None:
    a = label_keys(["v1", "v2", "v3"])
    b = label_keys(["v3", "v1"])
    assert a.dtype == np.uint64 and len(set(a.tolist())) == 3
    assert b[0] == a[2] and b[1] == a[0]  # a label's key, wherever it stands
    # Repeated labels in one batch still draw independently (first = the label's own key).
    rep = label_keys(["x", "x", "x"])
    assert rep[0] == label_keys(["x"])[0] and len(set(rep.tolist())) == 3


def test_single_runs_equal_one_batch_with_noise_and_missed_detections(prepared) -> None:
    arrays, auto = prepared.arrays, prepared.auto_shift_s
    b = 4
    shifts = auto + np.linspace(-1.0, 1.0, b)
    p = VariantParams.from_case(NOISY_CAP, arrays, b, time_shift_s=shifts).with_values(
        labels=np.array([f"v{i}" for i in range(b)], dtype=object)
    )
    batch = simulate(arrays, p, kernel="auto")
    rev = simulate(arrays, p.take(np.arange(b)[::-1]), kernel="auto")
    for i in range(b):
        single = simulate(arrays, p.take([i]), kernel="auto")
        for name, _, _ in _RECORDED:
            got = np.asarray(getattr(batch, name))[i]
            assert np.array_equal(np.asarray(getattr(single, name))[0], got), (i, name)
            assert np.array_equal(np.asarray(getattr(rev, name))[b - 1 - i], got), (i, name)
    # The noise acts: without it the CAP brakes differently in some variant; and the draws
    # follow the label: the same variant under another label perceives differently.
    ideal = simulate(
        arrays, p.with_values(perception=np.array([None] * b, dtype=object)), kernel="auto"
    )
    assert not np.array_equal(ideal.ego_speed_mps, batch.ego_speed_mps)
    relabelled = p.with_values(labels=np.array(["w"] * b, dtype=object)).take([2])
    other = simulate(arrays, relabelled, kernel="auto")
    assert not np.array_equal(other.ego_speed_mps[0], batch.ego_speed_mps[2])


@pytest.mark.slow
def test_vei_run_of_each_noisy_variant_equals_the_sweep_row(demo_scenario, tmp_path):
    # The spec's perception section switches the noisy sensor on for every variant.
    assert CASE_PRESETS["normal-cap"] == replace(NOISY_CAP, name="normal-cap", perception=None)
    spec = spec_from_dict(
        {
            "design": "grid",
            "base": "normal-cap",
            "perception": {
                "enabled": True,
                "position_noise_std_m": 0.4,
                "velocity_noise_std_mps": 0.4,
                "detection_probability": 0.7,
                "seed": 11,
            },
            "parameters": {
                "time_shift_s": {"min": -1.0, "max": 1.0, "num": 2},
                "ego.cruise_speed_mps": {"min": 5.0, "max": 7.0, "num": 2},
            },
        }
    )
    res = run_sweep(demo_scenario, spec, tmp_path / "sweep", chunk_size=64, progress=False)
    assert (res.n_variants, res.n_run) == (4, 4)
    df = read_results(tmp_path / "sweep")
    assert spec.perception == NOISY
    auto = EngineEvaluator(base="normal-cap").prepare(demo_scenario).auto_shift_s
    paths = write_variant_configs(tmp_path / "configs", df, spec, auto)
    for path in paths:
        doc = path.read_text()
        assert "detection_probability: 0.7" in doc and "seed: 11" in doc
    compared = assert_runs_equal_sweep(demo_scenario, paths, df, tmp_path / "runs")
    assert compared == 4 * len(DEFAULT_METRICS)
