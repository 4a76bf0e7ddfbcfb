"""A small crossing scenario (folder with an OpenDRIVE map) for the CARLA backend tests."""

from __future__ import annotations

import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from vei.types import TRAJECTORY_COLUMNS, AgentInfo, Scenario

#: Rider time shift [s] that makes the replayed rider meet the ego at x = 40 m.
MEETING_SHIFT_S = 2.5


def crossing_scenario(root: Path | None = None) -> Scenario:
    """Ego east along y = -1.5 (right lane of a straight two-lane road) at 5.6 m/s for 12 s;
    an e-scooter crossing north at x = 40 m at 4 m/s from t = 2 s (recording time) to the
    far side; a replayed cyclist riding west in the left lane. 20 Hz."""
    t = np.round(np.arange(0.0, 12.0 + 1e-9, 0.05), 6)
    rows = []
    for ti in t:
        rows.append((ti, "ego", None, "ego", 5.6 * ti, -1.5, 0.0, 5.6))
        if 2.0 <= ti <= 7.0:
            rows.append(
                (ti, "s7", "7", "escooter", 40.0, -12.0 + 4.0 * (ti - 2.0), math.pi / 2, 4.0)
            )
        rows.append((ti, "c1", "12", "cyclist", 150.0 - 5.0 * ti, 1.5, math.pi, 5.0))
    traj = pd.DataFrame(rows, columns=list(TRAJECTORY_COLUMNS))
    return Scenario(
        id="crossing",
        projection="+proj=tmerc +lat_0=48.7 +lon_0=11.4 +k=1 +x_0=0 +y_0=0 +ellps=WGS84 +units=m",
        origin_lat_deg=48.7,
        origin_lon_deg=11.4,
        start_time_utc=datetime(2021, 2, 9, 10, 0, tzinfo=UTC),
        rate_hz=20.0,
        bounds={"south_deg": 48.69, "west_deg": 11.39, "north_deg": 48.71, "east_deg": 11.41},
        agents=(
            AgentInfo("ego", "ego", 4.7, 1.85),
            AgentInfo("s7", "escooter", 1.2, 0.6, "7"),
            AgentInfo("c1", "cyclist", 1.8, 0.6, "12"),
        ),
        primary_threat="s7",
        trajectories=traj,
        maps={"opendrive": "map.xodr"} if root is not None else {},
        root=root,
    )


def write_straight_xodr(path: Path) -> Path:
    """A 200 m straight road, one 3 m lane each way, along +x from the origin."""
    from scenariogeneration import xodr

    road = xodr.create_road(xodr.Line(200), id=0, left_lanes=1, right_lanes=1)
    odr = xodr.OpenDrive("straight")
    odr.add_road(road)
    odr.adjust_roads_and_lanes()
    odr.write_xml(str(path))
    return path


@pytest.fixture()
def scenario_with_map(tmp_path) -> Scenario:
    """crossing_scenario() with its folder holding map.xodr."""
    write_straight_xodr(tmp_path / "map.xodr")
    return crossing_scenario(tmp_path)
