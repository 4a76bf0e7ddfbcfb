"""Sweeps over ego policies and their parameters: the batch parameters equal each row's own
run configuration, and a policy x time shift x cruise speed sweep runs."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vei.errors import ConfigError
from vei.sim.params import EGO_POLICY, VariantParams
from vei.sweep.run import EngineEvaluator, variant_params
from vei.sweep.spec import row_params, spec_from_dict, variant_config, variants_table


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory):
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


SPEC = {
    "design": "grid",
    "base": "normal-cap",
    "parameters": {
        "ego.policy": {"choices": ["paper-cap", "aeb"]},
        "time_shift_s": {"min": -1.0, "max": 1.0, "num": 3},
        "ego.cruise_speed_mps": {"min": 5.0, "max": 8.0, "num": 2},
        "ego.policy_params.ttc_partial_s": {"choices": [1.4, 1.8]},
    },
}


def test_batch_parameters_equal_each_rows_configuration(demo_scenario) -> None:
    spec = spec_from_dict(SPEC)
    ev = EngineEvaluator(time_shift_reference="auto", base="normal-cap")
    prep = ev.prepare(demo_scenario)
    table = variants_table(spec, prep.scenario_id)
    assert len(table) == 24
    batch = variant_params(table, prep.arrays, auto_shift_s=prep.auto_shift_s)
    is_aeb = table["ego.policy"].to_numpy() == "aeb"
    np.testing.assert_array_equal(batch.ego_mode == EGO_POLICY, is_aeb)
    np.testing.assert_array_equal(
        batch.aeb_ttc_partial_s, table["ego.policy_params.ttc_partial_s"].to_numpy()
    )
    for i, row in table.iterrows():
        cfg = variant_config(row_params(row, spec), spec, auto_shift_s=prep.auto_shift_s)
        assert cfg.case.policy_name == row["ego.policy"]
        if row["ego.policy"] == "aeb":
            assert cfg.case.ego.policy_params == {
                "ttc_partial_s": row["ego.policy_params.ttc_partial_s"]
            }
        one = VariantParams.from_case(cfg.case, prep.arrays, 1, time_shift_s=cfg.time_shift)
        for f in dataclasses.fields(one):
            if f.name in ("labels", "policy", "perception"):
                continue
            if f.name.startswith("aeb_") and row["ego.policy"] != "aeb":
                continue  # swept but unused by paper-cap (the batch keeps the column's value)
            assert getattr(batch, f.name)[i] == getattr(one, f.name)[0], f.name
        assert type(batch.policy[i]) is type(one.policy[0])


def test_policy_sweep_runs_and_aeb_parameters_act(demo_scenario) -> None:
    spec = spec_from_dict(SPEC)
    ev = EngineEvaluator(time_shift_reference="auto", base="normal-cap")
    prep = ev.prepare(demo_scenario)
    table = variants_table(spec, prep.scenario_id)
    out = ev.evaluate(prep, table).set_index("variant_id").loc[table["variant_id"]]
    assert np.isfinite(out["min_gap_m"].to_numpy(float)).all()
    aeb = table["ego.policy"].to_numpy() == "aeb"
    gap = out["min_gap_m"].to_numpy(float)
    # braking earlier (partial at TTC 1.8 s instead of 1.4 s) keeps a larger minimum gap
    early = aeb & (table["ego.policy_params.ttc_partial_s"].to_numpy() == 1.8)
    late = aeb & (table["ego.policy_params.ttc_partial_s"].to_numpy() == 1.4)
    assert gap[early].mean() > gap[late].mean()


def test_cap_enabled_is_replaced_by_the_policy() -> None:
    with pytest.raises(ConfigError, match=r"'cap.enabled' was replaced by 'ego.policy'"):
        spec_from_dict({"design": "grid", "parameters": {"ego.policy": "aeb", "cap.enabled": True}})
    spec = spec_from_dict({"design": "grid", "parameters": {"ego.policy": "aeb"}})
    with pytest.raises(ConfigError, match=r"'cap.enabled' was replaced by 'ego.policy'"):
        variant_config({"ego.policy": "aeb", "cap.enabled": True}, spec, auto_shift_s=0.0)
