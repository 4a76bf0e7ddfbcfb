"""V2X runs through the same controller code in every backend: the built-in closed loop
and esmini's (libesminiLib) equal the batched engine with perception + V2X."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tests.sim.backends.conftest import crossing_scenario
from tests.sim.backends.test_esmini import _assert_same_series
from vei.config import PerceptionConfig, V2XConfig, case_preset
from vei.sim.backends.base import run_backend
from vei.sim.backends.builtin import BuiltinBackend
from vei.sim.backends.esmini import EsminiBackend, EsminiSettings
from vei.sim.engine import run_cases

#: A rider time shift at which the V2X car brakes for the rider it knows from its messages,
#: where the 8 m sensor alone lets it drive on (the outcomes differ).
SHIFT_S = 0.5


def _cases():
    base = case_preset("paper-normal")
    cap = replace(base, ego=replace(base.ego, policy="paper-cap"),
                  perception=PerceptionConfig(enabled=True, range_m=8.0))  # fmt: skip
    # A lossy, late channel and the default GNSS error: the random draws are exercised.
    v2x = V2XConfig(enabled=True, pdr_factor=0.7, latency_s=0.1, latency_jitter_s=0.2,
                    latency_distribution="uniform")  # fmt: skip
    return [replace(cap, name="perception"), replace(cap, name="v2x", v2x=v2x)]


def test_builtin_backend_with_v2x_equals_the_batched_engine() -> None:
    scenario = crossing_scenario()
    cases = _cases()
    ref = run_cases(scenario, cases, time_shift_s=SHIFT_S, kernel="numpy").to_frame()
    got = run_backend(BuiltinBackend(), scenario, cases, time_shift_s=SHIFT_S)
    _assert_same_series(got, ref, atol=1e-6)
    ego = ref[ref["agent_id"] == "ego"]
    speeds = {c: g["speed_mps"].to_numpy() for c, g in ego.groupby("config", sort=False)}
    # V2X changes the car's behaviour here (it brakes for the rider it hears of)
    assert np.abs(speeds["v2x"] - speeds["perception"]).max() > 1.0


def test_esmini_with_v2x_equals_the_builtin_engine(tmp_path, esmini) -> None:
    from tests.sim.backends.conftest import write_straight_xodr

    write_straight_xodr(tmp_path / "map.xodr")
    scenario = crossing_scenario(tmp_path)
    cases = _cases()
    backend = EsminiBackend(EsminiSettings(root=esmini.root, work_dir=tmp_path / "work"))
    got = run_backend(backend, scenario, cases, time_shift_s=SHIFT_S)
    ref = run_cases(scenario, cases, time_shift_s=SHIFT_S, kernel="numpy").to_frame()
    _assert_same_series(got, ref, atol=1e-4)
