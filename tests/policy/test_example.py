"""The example user policy (examples/my_policy.py): loaded by file path, vectorised and
per-variant loop versions agree, and it runs from the CLI on the demo."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from vei.cli.main import main
from vei.config import CaseConfig, EgoConfig, case_preset
from vei.policy.load import load_policy
from vei.sim.engine import prepare_scenario, simulate
from vei.sim.params import VariantParams
from vei.sim.testing import crossing_scenario, standing_rider_scenario

EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "my_policy.py"


@pytest.fixture(scope="module")
def demo_folder(tmp_path_factory):
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


def test_loads_by_file_path_with_parameters() -> None:
    pol = load_policy(f"{EXAMPLE}:MyPolicy", {"ttc_brake_s": 2.5})
    assert type(pol).__name__ == "MyPolicy" and pol.ttc_brake_s == 2.5


def test_vectorised_and_loop_versions_give_the_same_result() -> None:
    arrays = prepare_scenario(crossing_scenario())
    shifts = np.linspace(3.0, 6.0, 7)
    out = []
    for cls in ("MyPolicy", "MyLoopPolicy"):
        case = replace_policy(case_preset("normal"), f"{EXAMPLE}:{cls}")
        out.append(
            simulate(
                arrays, VariantParams.from_case(case, arrays, shifts.size, time_shift_s=shifts)
            )
        )
    np.testing.assert_array_equal(out[0].ego_speed_mps, out[1].ego_speed_mps)
    np.testing.assert_array_equal(out[0].collision_time_s, out[1].collision_time_s)
    assert (out[0].cap_state == 1).any()  # it brakes somewhere


def test_it_stops_before_a_standing_rider() -> None:
    arrays = prepare_scenario(standing_rider_scenario(ego_speed_mps=8.0, rider_x_m=40.0))
    case = CaseConfig(
        name="mine", ego=EgoConfig(cruise_speed_mps=8.0, run_up_m=0.0, policy=f"{EXAMPLE}:MyPolicy")
    )
    r = simulate(arrays, VariantParams.from_case(case, arrays, 1))
    # brakes at TTC 1.8 s (gap 14.4 m) at 6 m/s^2: stops after ~5.3 m + lag, short of the rider
    assert np.isnan(r.collision_time_s[0]) and r.ego_speed_mps[0, -1] < 0.5


def replace_policy(case, spec):
    from vei.cli.sim_cmd import with_policy

    return with_policy(case, spec)


def test_cli_run_with_the_example_policy(demo_folder, tmp_path, capsys) -> None:
    dest = tmp_path / "run"
    spec = f"{EXAMPLE}:MyPolicy"
    code = main(
        ["run", str(demo_folder), "--config", "normal", "--policy", spec, "--out", str(dest),
         "--time-shift", "0", "--no-figures"]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().out
    doc = json.loads((dest / "metrics.json").read_text())
    assert doc["case_config"]["ego"]["policy"] == spec
    assert doc["case_config"]["ego_mode"] == "policy"


def test_cli_casestudy_compares_policies(demo_folder, tmp_path, capsys) -> None:
    dest = tmp_path / "cs"
    code = main(
        ["casestudy", str(demo_folder), "--out", str(dest), "--no-figures",
         "--policy", "none", "--policy", "paper-cap", "--policy", "aeb",
         "--policy", f"{EXAMPLE}:MyPolicy"]
    )  # fmt: skip
    text = capsys.readouterr().out
    assert code == 0, text
    rows = json.loads((dest / "summary.json").read_text())["configs"]
    assert [r["name"] for r in rows] == ["none", "paper-cap", "aeb", "MyPolicy"]
    coll = {r["name"]: r["collision"] for r in rows}
    # auto shift: the uncontrolled ego meets the rider; the three avoiding policies do not
    assert coll == {"none": True, "paper-cap": False, "aeb": False, "MyPolicy": False}


def test_bad_policy_spec_exits_2(demo_folder, tmp_path, capsys) -> None:
    code = main(
        ["run", str(demo_folder), "--config", "normal", "--policy", "nosuch.module:X",
         "--out", str(tmp_path / "x"), "--no-figures"]
    )  # fmt: skip
    cap = capsys.readouterr()
    assert code == 2
    assert "nosuch.module:X" in cap.out + cap.err


def test_the_example_documents_what_users_copy() -> None:
    """Users copy the example: its methods say what obs holds (shapes, units) and what
    to return."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("my_policy_doc", EXAMPLE)
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    for meth, words in (
        (mod.MyPolicy.init_state, ("batch_size", "act")),
        (mod.MyPolicy.act, ("[B]", "[B, N]", "m/s", "path_gap_m", "PolicyAction", "Returns")),
        (mod.MyLoopPolicy.act_one, ("[N]", "m/s^2", "Returns", "stateful")),
    ):
        doc = meth.__doc__ or ""
        missing = [w for w in words if w not in doc]
        assert not missing, f"{meth.__qualname__}: docstring lacks {missing}"
