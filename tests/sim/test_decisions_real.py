"""Decisions act on real encounters (issue 32): on a shared recording where the car turns
left across a cyclist's path, the yield / go decision changes the outcome of some time
shifts, and a cautious rider collides no more often than a bold one."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from vei.config import DecisionConfig, SimConfig, case_preset
from vei.sim.engine import simulate_metrics
from vei.sim.state import VariantParams, prepare_scenario

pytestmark = pytest.mark.slow  # imports and reconstructs a shared recording


@pytest.fixture(scope="module")
def arrays(tmp_path_factory, trafficmonitoring_root):
    from vei.cli.main import main
    from vei.io.scenario import read_scenario

    root = tmp_path_factory.mktemp("dec_real")
    inter, scen = root / "inter", root / "scen"
    name = "audi_10_marktkauf_linksabbiegen"
    assert main(["import", "trafficmonitoring", "--root", str(trafficmonitoring_root),
                 "--scenario", name, "--out", str(inter)]) == 0  # fmt: skip
    assert main(["reconstruct", str(inter), "--out", str(scen), "--no-figure"]) == 0
    return prepare_scenario(read_scenario(scen), SimConfig())


def test_decisions_change_the_outcome_of_some_shifts(arrays):
    assert arrays.conflicts.n >= 1
    shifts = np.linspace(-15.0, 15.0, 301)
    out = {}
    for t_c in (None, -3.0, 0.0, 3.0):
        case = case_preset("normal")
        if t_c is not None:
            case = dataclasses.replace(
                case, decision=DecisionConfig(enabled=True, critical_gap_s=t_c)
            )
        p = VariantParams.from_case(case, arrays, shifts.size, time_shift_s=shifts)
        out[t_c] = simulate_metrics(arrays, p, names=("collision",))["collision"].to_numpy()
    assert out[None].any()  # the shifts meet the cyclist without decisions
    assert (out[0.0] != out[None]).any()  # decisions change some outcomes ...
    # ... and more caution never adds a collision with this car (which does not react)
    assert out[3.0].sum() <= out[0.0].sum() <= out[-3.0].sum()
    assert not (out[3.0] & ~out[-3.0]).any()
