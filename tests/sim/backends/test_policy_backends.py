"""Every backend runs any ego policy: esmini (closed loop through libesminiLib) with the
policy API's aeb / idm / a user policy equals the built-in engine."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from tests.sim.backends.conftest import MEETING_SHIFT_S, crossing_scenario
from tests.sim.backends.test_esmini import _assert_same_series
from vei.config import case_preset
from vei.sim.backends.base import run_backend
from vei.sim.backends.builtin import BuiltinBackend
from vei.sim.backends.esmini import EsminiBackend, EsminiSettings
from vei.sim.engine import run_cases

EXAMPLE = Path(__file__).resolve().parents[3] / "examples" / "my_policy.py"


def _cases():
    base = case_preset("paper-normal")
    out = []
    for pol, name in (("aeb", "aeb"), ("idm", "idm"), (f"{EXAMPLE}:MyPolicy", "mine")):
        out.append(replace(base, name=name, ego=replace(base.ego, policy=pol)))
    return out


def test_builtin_backend_with_policies_equals_the_batched_engine() -> None:
    scenario = crossing_scenario()
    cases = _cases()
    ref = run_cases(scenario, cases, time_shift_s=MEETING_SHIFT_S, kernel="numpy").to_frame()
    got = run_backend(BuiltinBackend(), scenario, cases, time_shift_s=MEETING_SHIFT_S)
    _assert_same_series(got, ref, atol=1e-6)


def test_esmini_with_aeb_equals_the_builtin_engine(tmp_path, esmini) -> None:
    from tests.sim.backends.conftest import write_straight_xodr

    write_straight_xodr(tmp_path / "map.xodr")
    scenario = crossing_scenario(tmp_path)
    cases = _cases()
    backend = EsminiBackend(EsminiSettings(root=esmini.root, work_dir=tmp_path / "work"))
    got = run_backend(backend, scenario, cases, time_shift_s=MEETING_SHIFT_S)
    ref = run_cases(scenario, cases, time_shift_s=MEETING_SHIFT_S, kernel="numpy").to_frame()
    _assert_same_series(got, ref, atol=1e-4)
    ego = ref[ref["agent_id"] == "ego"]
    # the policies act here: the AEB brakes hard on this critical crossing
    assert ego.groupby("config", sort=False)["speed_mps"].min()["aeb"] < 1.0
    assert np.isfinite(ego["speed_mps"]).all()
