"""Fixtures of the export tests: a crossing run on a straight two-lane road, the checker."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vei.types import AgentInfo


def crossing_run(dt_s: float = 0.05, duration_s: float = 10.0) -> pd.DataFrame:
    """Ego at 5.6 m/s along +x in the right lane; an e-scooter crossing from the south at
    4 m/s from t = 2 s (it appears then); a cyclist riding west in the left lane, braking
    to a stop at t = 6 s within one step (an abrupt stop, like a collision)."""
    t = np.round(np.arange(0.0, duration_s + 1e-9, dt_s), 6)
    rows = []
    for ti in t:
        rows.append((ti, "ego", "ego", 5.6 * ti, -1.5, 0.0, 5.6))
        if ti >= 2.0:
            rows.append((ti, "7", "escooter", 40.0, -12.0 + 4.0 * (ti - 2.0), np.pi / 2, 4.0))
        xc = 120.0 - 5.0 * min(ti, 6.0)
        rows.append((ti, "c1", "cyclist", xc, 1.5, np.pi, 5.0 if ti < 6.0 else 0.0))
    return pd.DataFrame(
        rows, columns=["t_s", "agent_id", "category", "x_m", "y_m", "yaw_rad", "speed_mps"]
    )


AGENTS = (
    AgentInfo("ego", "ego", 4.7, 1.85),
    AgentInfo("7", "escooter", 1.2, 0.6, "7"),
    AgentInfo("c1", "cyclist", 1.8, 0.6, "12"),
)


@pytest.fixture()
def run_df() -> pd.DataFrame:
    """The crossing run at 20 Hz (see crossing_run)."""
    return crossing_run()


@pytest.fixture(scope="session")
def straight_xodr(tmp_path_factory) -> Path:
    """A 200 m straight two-lane road (one lane each way, 3 m wide) made by scenariogeneration."""
    from scenariogeneration import xodr

    road = xodr.create_road(xodr.Line(200), id=0, left_lanes=1, right_lanes=1)
    odr = xodr.OpenDrive("straight")
    odr.add_road(road)
    odr.adjust_roads_and_lanes()
    path = tmp_path_factory.mktemp("map") / "map.xodr"
    odr.write_xml(str(path))
    return path


@pytest.fixture(scope="session")
def qc_bin() -> Path:
    """The ASAM checker executable: required when VEI_QC_BIN is set, else skip if absent."""
    from vei.errors import DependencyError
    from vei.export.qc import find_qc_openscenario

    if os.environ.get("VEI_QC_BIN"):
        return find_qc_openscenario()  # make test sets it: a missing tool is a failure
    try:
        return find_qc_openscenario()
    except DependencyError as exc:
        pytest.skip(f"ASAM quality checker absent and VEI_QC_BIN unset: {exc}")
