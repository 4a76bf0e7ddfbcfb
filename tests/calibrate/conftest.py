"""Session fixtures of the calibration tests: the shared TrafficMonitoring scenes, loaded once."""

from __future__ import annotations

import pytest

from vei.calibrate.tracks import SceneTracks, load_scenes


@pytest.fixture(scope="session")
def tm_scenes(trafficmonitoring_root) -> list[SceneTracks]:
    """Every shared scenario's rider segments and moving vehicles (20 Hz grid)."""
    return load_scenes(trafficmonitoring_root)
