"""Fixtures of the Gymnasium environment tests: the demo scenario folder (with its
synthetic map), written once per session."""

from __future__ import annotations

from pathlib import Path

import pytest


@pytest.fixture(scope="session")
def demo_folder(tmp_path_factory) -> Path:
    """The reconstructed demo with its synthetic map.xodr (vei.experiments.demo_map)."""
    from vei.experiments.demo_map import write_demo_scenario

    return write_demo_scenario(tmp_path_factory.mktemp("gym") / "demo")


@pytest.fixture(scope="session")
def demo_config(demo_folder):
    """An EnvConfig of the demo folder (the 'folder' source: no temp copy per env)."""
    from vei.gym import EnvConfig

    return EnvConfig(source="folder", path=demo_folder)


#: A real recording with many replayed road users (cars, pedestrians, other riders).
REAL_RECORDING = "stadtmitte_12_audi_geradeaus_03"


@pytest.fixture(scope="session")
def real_folder(tmp_path_factory) -> Path:
    """stadtmitte_12 imported and reconstructed with the Ingolstadt map, as a user would."""
    from tests.conftest import require_data
    from vei.cli.main import main

    tm = require_data("trafficmonitoring")
    net = require_data("maps", "ingolstadt_research_intersection.net.xml.gz")
    root = tmp_path_factory.mktemp("gym_real")
    inter, folder = root / "interaction", root / "scenario"
    args = ["import", "trafficmonitoring", "--root", str(tm), "--scenario", REAL_RECORDING,
            "--out", str(inter)]  # fmt: skip
    assert main(args) == 0
    args = ["reconstruct", str(inter), "--out", str(folder), "--no-figure", "--map", str(net)]
    assert main(args) == 0
    return folder
