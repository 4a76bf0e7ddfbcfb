"""A fast stand-in for the engine's sweep evaluator (no simulation), importable by spawned
workers: it tells in each result row which process evaluated it and how many times that
process has unpickled a prepared scenario."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

#: Prepared scenarios unpickled in this process (counted by CountedScenario.__setstate__).
UNPICKLED = {"n": 0}


class CountedScenario:
    """A prepared scenario that counts how often it is unpickled (per process)."""

    def __init__(self, scenario_id: str, payload: np.ndarray) -> None:
        self.scenario_id = scenario_id
        self.payload = payload

    def __getstate__(self) -> dict[str, Any]:
        return dict(self.__dict__)

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        UNPICKLED["n"] += 1


class FakeEvaluator:
    """Evaluator protocol of vei.sweep.evaluator, by hand-computable formulas.

    collision = time_shift_s > 0; safety_index = |time_shift_s| / 3; min_gap_m =
    time_shift_s + 3 (exact in float64 for the test grids). ``prepares`` counts
    :meth:`prepare` calls in the process that holds this object.
    """

    def __init__(self) -> None:
        self.prepares = 0

    def prepare(self, scenario_dir: Path) -> CountedScenario:
        self.prepares += 1
        return CountedScenario(Path(scenario_dir).name, np.arange(100_000, dtype=np.float64))

    def scenario_id(self, prepared: CountedScenario) -> str:
        return prepared.scenario_id

    def auto_shift_s(self, prepared: CountedScenario) -> float | None:
        return 0.0

    def evaluate(self, prepared: CountedScenario, variants: pd.DataFrame) -> pd.DataFrame:
        x = variants["time_shift_s"].to_numpy(np.float64)
        return pd.DataFrame(
            {
                "variant_id": variants["variant_id"].to_numpy(),
                "collision": x > 0,
                "safety_index": np.abs(x) / 3.0,
                "min_gap_m": x + 3.0,
                "side": np.where(x > 0, "front", ""),
                "pid": os.getpid(),
                "unpickled": UNPICKLED["n"],
                "payload_sum": float(prepared.payload.sum()),
                "threads": _numba_threads(),
            }
        )


def _numba_threads() -> int:
    """numba's thread count in this process (0: numba not imported here)."""
    import sys

    numba = sys.modules.get("numba")
    return int(numba.get_num_threads()) if numba is not None else 0


def fake_scenarios(folder: Path, names: list[str]) -> list[Path]:
    """Scenario folders (a scenario.json each; FakeEvaluator never reads it)."""
    out = []
    for n in names:
        d = folder / n
        d.mkdir(parents=True, exist_ok=True)
        (d / "scenario.json").write_text("{}")
        out.append(d)
    return out
