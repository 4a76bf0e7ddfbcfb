"""The rider's decisions and the reacting cars in the esmini closed loop: the engine's step
runs inside the loop, so a yielding rider yields in esmini as in the built-in engine."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from tests.sim.backends.conftest import MEETING_SHIFT_S, crossing_scenario
from tests.sim.backends.test_esmini import _assert_same_series
from vei.config import DecisionConfig, TrafficConfig, case_preset
from vei.sim.backends.base import run_backend
from vei.sim.backends.esmini import EsminiBackend, EsminiSettings
from vei.sim.engine import run_cases


def test_esmini_closed_loop_with_decisions_equals_the_builtin_engine(tmp_path, esmini) -> None:
    from tests.sim.backends.conftest import write_straight_xodr

    root = tmp_path / "crossing"
    root.mkdir()
    write_straight_xodr(root / "map.xodr")
    scenario = crossing_scenario(root)
    cases = [
        replace(
            case_preset("paper-normal"),
            name=f"decide-{tc:g}",
            decision=DecisionConfig(enabled=True, critical_gap_s=tc),
            traffic=TrafficConfig(cars_react=True),
        )  # fmt: skip
        for tc in (-5.0, 5.0)
    ]
    backend = EsminiBackend(EsminiSettings(root=esmini.root, work_dir=tmp_path / "work"))
    got = run_backend(backend, scenario, cases, time_shift_s=MEETING_SHIFT_S)
    ref = run_cases(scenario, cases, time_shift_s=MEETING_SHIFT_S)
    _assert_same_series(got, ref.to_frame(), atol=1e-4)
    # the two riders decide differently (one goes, one yields) and esmini shows it
    assert ref.rider_decision[0].max() == 1 and ref.rider_decision[1].max() == 2
    rider = got[got["agent_id"] == ref.rider_id]
    r0, r1 = (rider[rider["config"] == c.name]["speed_mps"] for c in cases)
    assert len(r0) and len(r1)
    assert not np.allclose(r0.to_numpy(), r1.to_numpy())
