"""Scenes the property tests draw from: the demo encounter and shared recordings, each
reconstructed once per process, and the rigid motion of a whole scene.

``scene(name) -> Scenario``: "demo" (vei.experiments.demo_data: the rider rides ahead of
the car in its lane, then crosses) or a TrafficMonitoring recording of the shared data
(imported at the paper's 1 Hz annotations and reconstructed; skipped without the data;
the name + ALL_ROAD_USERS: with the vehicles and pedestrians too).
``prepared(name) -> (ScenarioArrays, auto time shift [s])`` with the default SimConfig.
``moved(scenario, angle_rad, dx_m, dy_m)``: the scene rotated by angle_rad about the
plane's origin, then translated by (dx_m, dy_m).
"""

from __future__ import annotations

import dataclasses
import functools
import math
import tempfile
from pathlib import Path

import numpy as np
import pandas as pd

from tests.conftest import require_data
from vei.types import Scenario

DEMO = "demo"
#: Suffix of a recording's name: imported with every road user the camera tracked (also
#: vehicles and pedestrians), not only the riders.
ALL_ROAD_USERS = "+all"
#: Shared recordings whose encounter collides at some shifts within 2 s of the auto shift:
#: a cyclist ahead of the car going straight (1,223 steps, six other road users), the car
#: turning left across a cyclist's path (1,089 steps), a right turn (149 steps).
RECORDINGS = (
    "stadtmitte_12_audi_geradeaus_03",
    "audi_10_marktkauf_linksabbiegen",
    "audi_08_klinikum_rechtsabbiegen_02",
)


@functools.cache
def _reconstructed(name: str) -> Scenario:
    from vei.recon.pipeline import reconstruct

    if name == DEMO:
        from vei.experiments.demo_data import demo_interaction

        return reconstruct(demo_interaction())
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction

    root = require_data("trafficmonitoring")
    recording = name.removesuffix(ALL_ROAD_USERS)
    with tempfile.TemporaryDirectory(prefix="vei_props_") as tmp:
        out = Path(tmp) / recording
        import_scenario(root, recording, out, rate_hz=1.0,
                        road_users="all" if name.endswith(ALL_ROAD_USERS) else "riders")  # fmt: skip
        return reconstruct(read_interaction(out))


def scene(name: str) -> Scenario:
    """The reconstructed scene ``name`` (DEMO or one of RECORDINGS); skipped when the
    shared data are absent."""
    if name != DEMO:
        require_data("trafficmonitoring")
    return _reconstructed(name)


@functools.cache
def _prepared(name: str):
    from vei.config import SimConfig
    from vei.sim.state import prepare_scenario
    from vei.sim.timeshift import find_time_shift

    s = _reconstructed(name)
    return prepare_scenario(s, SimConfig()), float(find_time_shift(s))


def prepared(name: str):
    """(ScenarioArrays with the default SimConfig, the auto time shift [s]) of ``name``."""
    scene(name)
    return _prepared(name)


def _rotate(df: pd.DataFrame, c: float, s: float, dx: float, dy: float, a: float):
    x = df["x_m"].to_numpy(dtype=np.float64)
    y = df["y_m"].to_numpy(dtype=np.float64)
    yaw = df["yaw_rad"].to_numpy(dtype=np.float64)
    # yaw stays in (-pi, pi] as the reconstruction writes it
    yaw2 = np.arctan2(np.sin(yaw + a), np.cos(yaw + a))
    return df.assign(x_m=c * x - s * y + dx, y_m=s * x + c * y + dy, yaw_rad=yaw2)


def moved(scenario: Scenario, angle_rad: float, dx_m: float, dy_m: float) -> Scenario:
    """``scenario`` rotated by ``angle_rad`` [rad] (CCW) about the plane's origin and then
    translated by (dx_m, dy_m) [m]: every trajectory and keyframe (x_m, y_m [m], yaw_rad
    [rad]); speeds, times, dimensions unchanged. Only for scenes without maps (a map
    would have to move too)."""
    if scenario.maps:
        raise ValueError(f"scenario {scenario.id} has maps {sorted(scenario.maps)}: not moved")
    c, s = math.cos(angle_rad), math.sin(angle_rad)
    kf = scenario.keyframes
    return dataclasses.replace(
        scenario,
        trajectories=_rotate(scenario.trajectories, c, s, dx_m, dy_m, angle_rad),
        keyframes=None if kf is None else _rotate(kf, c, s, dx_m, dy_m, angle_rad),
    )


def props(max_examples: int):
    """Hypothesis settings of the property tests: ``max_examples`` examples, drawn from a
    fixed seed (derandomize: CI sees the same examples every run), no deadline (a first
    call may compile the kernel), no example database."""
    from hypothesis import HealthCheck, settings

    return settings(
        max_examples=max_examples,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=[HealthCheck.too_slow],
    )
