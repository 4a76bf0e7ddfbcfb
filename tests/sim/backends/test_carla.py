"""CARLA backend: fail-fast without a server, the closed loop = the engine's step, settings,
and (only with VEI_CARLA_HOST) a run on a real server."""

from __future__ import annotations

import dataclasses
import math
import os
import socket
import time

import numpy as np
import pytest

from tests.sim.backends.conftest import MEETING_SHIFT_S, crossing_scenario
from vei.config import SimConfig, case_preset
from vei.errors import BackendError, ConfigError, InputError
from vei.sim.backends.carla import (
    CarlaSettings,
    ClosedLoop,
    EgoMeasurement,
    _xodr_text,
    connect,
    run_carla,
    run_cases_frame,
)
from vei.sim.backends.carla_frame import pure_pursuit_steer
from vei.sim.engine import run_cases
from vei.types import TIMESERIES_COLUMNS


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_no_server_fails_fast_with_host_and_port(scenario_with_map):
    port = _free_port()  # bound then closed: nothing listens there
    start = time.monotonic()
    with pytest.raises(BackendError, match=f"127.0.0.1:{port}") as exc:
        run_carla(scenario_with_map, "replay", host="127.0.0.1", port=port, timeout_s=2.0)
    elapsed = time.monotonic() - start
    assert elapsed < 2.0 + 0.5
    assert "no CARLA server" in str(exc.value)


def test_silent_server_times_out_within_the_timeout():
    # something accepts TCP connections but never speaks CARLA's protocol
    with socket.socket() as srv:
        srv.bind(("127.0.0.1", 0))
        srv.listen(4)
        port = srv.getsockname()[1]
        start = time.monotonic()
        with pytest.raises(BackendError, match=f"127.0.0.1:{port}.*did not answer"):
            connect("127.0.0.1", port, 1.0)
        assert time.monotonic() - start < 1.0 + 0.5


def test_cli_style_runner_reads_host_and_port_from_env(monkeypatch, scenario_with_map):
    port = _free_port()
    monkeypatch.setenv("VEI_CARLA_HOST", "127.0.0.1")
    monkeypatch.setenv("VEI_CARLA_PORT", str(port))
    assert CarlaSettings.from_env().port == port
    with pytest.raises(BackendError, match=f"127.0.0.1:{port}"):
        run_cases_frame(scenario_with_map, [case_preset("replay")], MEETING_SHIFT_S, SimConfig())


def test_settings_validation(monkeypatch):
    with pytest.raises(ConfigError, match="port"):
        CarlaSettings(port=70000)
    with pytest.raises(ConfigError, match="timeout_s"):
        CarlaSettings(timeout_s=0)
    with pytest.raises(ConfigError, match="unknown categories"):
        CarlaSettings(blueprints={"scooter": "vehicle.x"})
    monkeypatch.setenv("VEI_CARLA_PORT", "two-thousand")
    with pytest.raises(ConfigError, match="VEI_CARLA_PORT"):
        CarlaSettings.from_env()
    assert CarlaSettings(blueprints={"escooter": "walker.pedestrian.0001"}).blueprint(
        "escooter"
    ) == ("walker.pedestrian.0001")


def test_scenario_without_map_is_an_input_error(tmp_path):
    with pytest.raises(InputError, match="no OpenDRIVE map"):
        _xodr_text(dataclasses.replace(crossing_scenario(tmp_path), maps={}))
    scen = crossing_scenario(tmp_path)  # names map.xodr, which is not there
    with pytest.raises(InputError, match="OpenDRIVE map not found"):
        _xodr_text(scen)
    # without a server, the server is what the user hears about first
    with pytest.raises(BackendError, match="no CARLA server"):
        run_carla(crossing_scenario(), "replay", host="127.0.0.1", port=_free_port(), timeout_s=1.0)


@pytest.mark.parametrize("name", ["replay", "normal", "aggressive-cap", "normal-cap"])
def test_closed_loop_around_an_ideal_plant_equals_the_engine(name):
    """The backend's controller is the engine's step: fed back the engine's own kinematic
    ego as the 'measurement', the loop reproduces the built-in engine's time series."""
    scenario = crossing_scenario()
    case = case_preset(name)
    ref = run_cases(scenario, [case], time_shift_s=MEETING_SHIFT_S).to_frame()
    loop = ClosedLoop(scenario, case, time_shift_s=MEETING_SHIFT_S)
    st = loop.state
    meas = EgoMeasurement(
        float(st.ego_x_m[0]),
        float(st.ego_y_m[0]),
        float(st.ego_yaw_rad[0]),
        float(st.ego_v_mps[0]),
        0.0,
    )
    commands = []
    for k in range(loop.n_steps):
        loop.observe(meas)
        if k == loop.n_steps - 1:
            break
        commands.append(loop.command())
        st = loop.state  # the engine's prediction = an ideal plant
        meas = EgoMeasurement(
            float(st.ego_x_m[0]), float(st.ego_y_m[0]), float(st.ego_yaw_rad[0]), float(st.ego_v_mps[0]),
            float(st.ego_a_mps2[0]),
        )  # fmt: skip
    got = loop.to_frame()
    assert list(got.columns) == list(TIMESERIES_COLUMNS)
    assert len(got) == len(ref)
    for col in ("config", "agent_id", "category", "active", "collided", "cap_state"):
        assert got[col].tolist() == ref[col].tolist(), col
    for col in ("t_s", "x_m", "y_m", "yaw_rad", "speed_mps", "accel_mps2"):
        np.testing.assert_allclose(got[col], ref[col], atol=1e-6, err_msg=col)
    # the scenario is critical: the replayed rider meets the ego
    if name == "replay":
        assert bool(ref[ref["agent_id"] == "ego"]["collided"].any())
    if name.endswith("-cap"):
        assert min(c.u for c in commands) < -0.5  # the CAP braked through the pedal command
    # straight path, ego on it: no steering
    assert max(abs(c.steer) for c in commands) < 1e-9


def test_contact_reported_by_the_simulator_latches_the_collision():
    """A simulator's contact latches the collision while the rider is in the scene; before
    it enters (its run-in before its recording from t = 2 s, shifted by 2.5 s) a contact
    is a phantom and ignored."""
    scenario = crossing_scenario()
    loop = ClosedLoop(scenario, case_preset("normal-cap"), time_shift_s=MEETING_SHIFT_S)
    st = loop.state
    assert not bool(st.rider_active[0])
    loop.observe(
        EgoMeasurement(float(st.ego_x_m[0]), float(st.ego_y_m[0]), 0.0, 5.6, 0.0), contact=True
    )
    cmd = loop.command()
    assert not cmd.hold and not bool(loop.state.collided[0])
    while not cmd.rider_active:  # the ideal plant until the rider enters (its run-in's start)
        loop.observe(EgoMeasurement(cmd.ego_x_m, cmd.ego_y_m, cmd.ego_yaw_rad, cmd.ego_v_mps, 0.0))
        cmd = loop.command()
    enters = loop.arrays.rider_track.t0_s + MEETING_SHIFT_S  # before 4.5 s: its run-in
    assert enters < 4.5 and loop.state.k == round(enters / loop.dt_s)
    loop.observe(
        EgoMeasurement(cmd.ego_x_m, cmd.ego_y_m, cmd.ego_yaw_rad, cmd.ego_v_mps, 0.0), contact=True
    )
    cmd = loop.command()
    assert cmd.hold and cmd.u == -1.0
    assert bool(loop.state.collided[0])


def test_pure_pursuit_brings_a_bicycle_onto_a_circular_path():
    """Kinematic bicycle (vei frame) steered by pure pursuit (CARLA sign): starting 1 m
    outside a 20 m radius circle it converges onto it."""
    r, wb, ms = 20.0, 2.8, math.radians(70.0)
    a = np.linspace(0, 1.5 * math.pi, 3000)
    path = np.stack([r * np.sin(a), r - r * np.cos(a)], axis=1)  # CCW circle through the origin
    x, y, yaw, v, dt = 0.0, -1.0, 0.0, 5.0, 0.05
    errs = []
    for _ in range(300):
        rear_x, rear_y = x - 0.5 * wb * math.cos(yaw), y - 0.5 * wb * math.sin(yaw)
        steer = pure_pursuit_steer(
            rear_x, rear_y, yaw, path, lookahead_m=5.0, wheelbase_m=wb, max_steer_rad=ms
        )
        delta = -steer * ms  # CARLA's positive steer turns clockwise
        yaw += v / wb * math.tan(delta) * dt
        x += v * math.cos(yaw) * dt
        y += v * math.sin(yaw) * dt
        errs.append(abs(math.hypot(x, y - r) - r))
    assert errs[0] > 0.8
    assert max(errs[-100:]) < 0.3


@pytest.mark.carla_server
@pytest.mark.skipif(
    not os.environ.get("VEI_CARLA_HOST"),
    reason="needs a CARLA server: set VEI_CARLA_HOST (and VEI_CARLA_PORT)",
)
def test_run_on_a_real_carla_server(scenario_with_map):
    frame = run_carla(scenario_with_map, ["replay", "normal-cap"], time_shift_s=MEETING_SHIFT_S)
    assert list(frame.columns) == list(TIMESERIES_COLUMNS)
    assert frame["config"].unique().tolist() == ["replay", "normal-cap"]
    ego = frame[(frame["agent_id"] == "ego") & (frame["config"] == "normal-cap")]
    assert ego["t_s"].iloc[-1] == pytest.approx(12.0)
    # the ego drove along its lane (CARLA physics, our PID and steering)
    assert ego["x_m"].iloc[-1] > ego["x_m"].iloc[0] + 10.0
    assert (ego["y_m"] - (-1.5)).abs().max() < 1.0
    assert not ego["collided"].any()
