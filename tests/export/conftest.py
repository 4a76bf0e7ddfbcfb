"""Fixtures of the export tests: a crossing run on a straight two-lane road, the checker,
and the demo + real recordings (with the engine's five runs) for the esmini playback tests."""

from __future__ import annotations

import os
from dataclasses import dataclass
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


# ---- real scenarios for the playback tests (esmini) ---------------------------------------

#: The SUMO network of the recordings' area (converted to OpenDRIVE by reconstruct --map).
INGOLSTADT_NET = ("maps", "ingolstadt_research_intersection.net.xml.gz")


@dataclass(frozen=True)
class PlaybackWorld:
    """One scenario folder and the built-in engine's run of the five configurations.

    Attributes:
        name: 'demo' or the recording's name.
        folder: the scenario folder (with map.xodr for real recordings).
        scenario: the read scenario.
        frame: time series of the five paper configurations (auto time shift).
    """

    name: str
    folder: Path
    scenario: object
    frame: pd.DataFrame

    @property
    def xodr(self) -> Path | None:
        """The scenario's OpenDRIVE map, if any."""
        rel = self.scenario.maps.get("opendrive")
        return None if rel is None else self.folder / rel


@pytest.fixture(scope="session")
def playback_world(tmp_path_factory):
    """name -> :class:`PlaybackWorld`, built on first use and kept for the session.

    'demo' is the synthetic demo (no map); a recording is imported and reconstructed with
    the CLI exactly as a user would (``vei import trafficmonitoring`` + ``vei reconstruct
    --map <the Ingolstadt SUMO network>``).
    """
    from tests.conftest import require_data
    from vei.cli.main import main
    from vei.config import PAPER_CASES
    from vei.experiments.casestudy import run_casestudy
    from vei.io.scenario import read_scenario, write_scenario

    cache: dict[str, PlaybackWorld] = {}
    root = tmp_path_factory.mktemp("playback_world")

    def get(name: str) -> PlaybackWorld:
        if name in cache:
            return cache[name]
        folder = root / name / "scenario"
        if name == "demo":
            from vei.experiments.demo_data import demo_interaction
            from vei.recon.pipeline import reconstruct

            write_scenario(reconstruct(demo_interaction()), folder)
        else:
            tm = require_data("trafficmonitoring")
            net = require_data(*INGOLSTADT_NET)
            inter = root / name / "interaction"
            args = ["import", "trafficmonitoring", "--root", str(tm), "--scenario", name,
                    "--out", str(inter)]  # fmt: skip
            assert main(args) == 0, name
            args = ["reconstruct", str(inter), "--out", str(folder), "--no-figure",
                    "--map", str(net)]  # fmt: skip
            assert main(args) == 0, name
        scenario = read_scenario(folder)
        frame = run_casestudy(scenario, cases=list(PAPER_CASES), time_shift="auto").frame
        cache[name] = PlaybackWorld(name, folder, scenario, frame)
        return cache[name]

    return get
