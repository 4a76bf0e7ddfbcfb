"""OpenSCENARIO export: XSD validity, round trip, decimation, entities, errors."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest
from defusedxml import ElementTree as SafeET

from tests.export.conftest import AGENTS, crossing_run
from vei.errors import ConfigError, InputError
from vei.export.openscenario import (
    OSC_VERSIONS,
    decimate_indices,
    export_openscenario,
    read_openscenario_trajectories,
    timeseries_to_trajectories,
)
from vei.export.validate import declared_version, validate_openscenario


def _interp_error(df: pd.DataFrame, back: pd.DataFrame, agent_id: str) -> tuple[float, float]:
    """Largest position / yaw distance between the full-rate track and the read-back
    polyline interpolated linearly in time at the track's sample times."""
    tr = df[df["agent_id"] == agent_id].sort_values("t_s")
    vx = back[(back["agent_id"] == agent_id) & (back["kind"] == "vertex")].sort_values("t_s")
    t = tr["t_s"].to_numpy()
    x = np.interp(t, vx["t_s"], vx["x_m"])
    y = np.interp(t, vx["t_s"], vx["y_m"])
    yaw = np.interp(t, vx["t_s"], np.unwrap(vx["yaw_rad"]))
    dpos = np.hypot(x - tr["x_m"].to_numpy(), y - tr["y_m"].to_numpy())
    dyaw = np.abs(np.angle(np.exp(1j * (yaw - tr["yaw_rad"].to_numpy()))))
    return float(dpos.max()), float(dyaw.max())


@pytest.mark.parametrize("version", OSC_VERSIONS)
def test_export_validates_against_official_xsd_and_round_trips(
    tmp_path, run_df, straight_xodr, version
):
    path = export_openscenario(run_df, AGENTS, tmp_path, xodr=straight_xodr, osc_version=version)
    assert path == tmp_path / "vei_scenario.xosc"
    assert declared_version(path) == version
    assert validate_openscenario(path) == []
    back = read_openscenario_trajectories(path)
    for agent in ("ego", "7", "c1"):
        dpos, dyaw = _interp_error(run_df, back, agent)
        assert dpos <= 0.05 + 1e-4  # the decimation bound (+ rounding to 0.1 mm)
        assert dyaw <= 0.05 + 1e-4
        # every vertex is one of the samples, to the written precision
        vx = back[(back["agent_id"] == agent) & (back["kind"] == "vertex")]
        tr = run_df[run_df["agent_id"] == agent].set_index("t_s")
        ref = tr.loc[vx["t_s"].round(6)]
        np.testing.assert_allclose(vx["x_m"], ref["x_m"], atol=1e-4)
        np.testing.assert_allclose(vx["y_m"], ref["y_m"], atol=1e-4)
    # initial poses = first samples; the scooter appears at 2 s
    init = back[back["kind"] == "init"].set_index("agent_id")
    assert init.loc["7", ["x_m", "y_m"]].tolist() == pytest.approx([40.0, -12.0])
    assert init.loc["7", "yaw_rad"] == pytest.approx(math.pi / 2, abs=1e-5)
    first = back[(back["agent_id"] == "7") & (back["kind"] == "vertex")]["t_s"].min()
    assert first == pytest.approx(2.0)


def test_straight_constant_speed_decimates_to_exactly_10_hz(run_df):
    ego = run_df[run_df["agent_id"] == "ego"]
    t = ego["t_s"].to_numpy()
    idx = decimate_indices(t, ego[["x_m", "y_m"]].to_numpy(), ego["yaw_rad"].to_numpy())
    # 0..10 s at 10 Hz: 101 vertices, every second sample
    assert idx.tolist() == list(range(0, 201, 2))


def test_abrupt_stop_gets_an_extra_vertex_within_the_bound():
    # 20 Hz samples; constant 5 m/s to t = 0.525 s... then standing: the stop falls between
    # two 10 Hz vertices, so the uniform polyline cuts the corner by 5 m/s * 0.05 s / 2.
    t = np.arange(0, 21) * 0.05
    x = 5.0 * np.minimum(t, 0.55)
    xy = np.stack([x, np.zeros_like(x)], axis=1)
    coarse = decimate_indices(t, xy, np.zeros_like(t), max_position_error_m=1.0)
    assert coarse.tolist() == list(range(0, 21, 2))
    fine = decimate_indices(t, xy, np.zeros_like(t), max_position_error_m=0.05)
    assert 11 in fine.tolist() and len(fine) == len(coarse) + 1
    # the refined polyline reproduces every sample exactly (piecewise linear motion)
    np.testing.assert_allclose(np.interp(t, t[fine], x[fine]), x, atol=1e-12)


def test_decimation_keeps_everything_when_asked():
    t = np.arange(5) * 0.05
    assert decimate_indices(t, np.zeros((5, 2)), np.zeros(5), vertex_rate_hz=None).tolist() == [
        0,
        1,
        2,
        3,
        4,
    ]


def test_entities_categories_dimensions_and_map_reference(tmp_path, run_df, straight_xodr):
    path = export_openscenario(
        run_df, AGENTS, tmp_path / "out", xodr=straight_xodr, osc_version="1.2"
    )
    root = SafeET.parse(path).getroot()
    assert root.find("RoadNetwork/LogicFile").get("filepath") == "map.xodr"
    assert (tmp_path / "out" / "map.xodr").read_bytes() == straight_xodr.read_bytes()
    objs = {o.get("name"): o for o in root.iter("ScenarioObject")}
    assert set(objs) == {"ego", "7", "c1"}
    scooter = objs["7"].find("Vehicle")
    assert scooter.get("vehicleCategory") == "bicycle"
    props = {p.get("name"): p.get("value") for p in scooter.iter("Property")}
    assert props["vei:category"] == "escooter"
    assert props["vei:source_track_id"] == "7"
    dims = scooter.find("BoundingBox/Dimensions")
    assert float(dims.get("length")) == pytest.approx(1.2)
    assert float(dims.get("width")) == pytest.approx(0.6)
    center = scooter.find("BoundingBox/Center")
    assert (float(center.get("x")), float(center.get("y"))) == (0.0, 0.0)
    ego_props = {p.get("name"): p.get("value") for p in objs["ego"].iter("Property")}
    assert ego_props["type"] == "ego_vehicle"
    assert objs["ego"].find("Vehicle").get("vehicleCategory") == "car"
    # absolute timing, position following, stop trigger at the end time
    for fta in root.iter("FollowTrajectoryAction"):
        timing = fta.find("TimeReference/Timing")
        assert timing.get("domainAbsoluteRelative") == "absolute"
        assert float(timing.get("scale")) == 1.0 and float(timing.get("offset")) == 0.0
        assert fta.find("TrajectoryFollowingMode").get("followingMode") == "position"
    # the stop trigger marks the end time (1 ms early, so that a player step on 10 s fires it)
    stop = root.find("Storyboard/StopTrigger")
    cond = stop.find(".//SimulationTimeCondition")
    assert float(cond.get("value")) == pytest.approx(10.0 - 1e-3)
    assert cond.get("rule") == "greaterThan"
    assert stop.find(".//Condition").get("conditionEdge") == "none"
    # present from t = 0: trajectory in Init; the scooter (2 s .. 10 s) is added at 2 s
    init_privs = {p.get("entityRef"): p for p in root.find("Storyboard/Init").iter("Private")}
    assert set(init_privs) == {"ego", "c1"}
    assert init_privs["ego"].find(".//FollowTrajectoryAction") is not None
    adds = list(root.iter("AddEntityAction"))
    assert len(adds) == 1 and not list(root.iter("DeleteEntityAction"))
    event = [e for e in root.iter("Event") if e.find(".//AddEntityAction") is not None][0]
    assert event.find(".//EntityAction").get("entityRef") == "7"
    assert event.find(".//FollowTrajectoryAction") is not None
    start = event.find(".//SimulationTimeCondition")
    assert float(start.get("value")) == pytest.approx(2.0 - 1e-3)
    # the reference point is the box centre and the rear axle sits on it
    assert float(scooter.find("Axles/RearAxle").get("positionX")) == 0.0
    assert scooter.get("model3d") == ""


def test_ego_left_to_the_simulator_gets_its_path_without_timing(tmp_path, run_df, straight_xodr):
    path = export_openscenario(
        run_df, AGENTS, tmp_path, xodr=straight_xodr, ego_controller="simulator"
    )
    assert validate_openscenario(path) == []
    back = read_openscenario_trajectories(path)
    ego = back[back["agent_id"] == "ego"]
    vx = ego[ego["kind"] == "vertex"]
    # the path: samples 0.28 m apart, one kept each >= 0.5 m: every second one (0.56 m),
    # 56 m / 0.56 m + 1 = 101 vertices, no times
    assert len(vx) == 101 and vx["t_s"].isna().all()
    assert vx["x_m"].iloc[-1] == pytest.approx(56.0)
    root = SafeET.parse(path).getroot()
    priv = [p for p in root.find("Storyboard/Init").iter("Private") if p.get("entityRef") == "ego"]
    assert float(priv[0].find(".//AbsoluteTargetSpeed").get("value")) == pytest.approx(5.6)
    assert priv[0].find(".//FollowTrajectoryAction") is None  # no path in Init (conflicts)
    events = {e.get("name"): e for e in root.iter("Event")}
    fta = events["ego_path"].find(".//FollowTrajectoryAction")
    assert fta.find("TimeReference/None") is not None
    assert fta.find("TrajectoryFollowingMode").get("followingMode") == "follow"
    start = events["ego_path"].find(".//SimulationTimeCondition")
    assert (float(start.get("value")), start.get("rule")) == (0.0, "greaterThan")
    cruise = events["ego_cruise"]
    assert float(cruise.find(".//AbsoluteTargetSpeed").get("value")) == pytest.approx(5.6)
    assert cruise.find(".//SpeedActionDynamics").get("dynamicsShape") == "linear"
    end = events["ego_path_end"].find(".//StoryboardElementStateCondition")
    assert (end.get("storyboardElementRef"), end.get("state")) == (
        "ego_follow_path",
        "endTransition",
    )
    assert float(events["ego_path_end"].find(".//AbsoluteTargetSpeed").get("value")) == 0.0


def test_a_track_that_ends_early_is_deleted_then(tmp_path, run_df):
    short = run_df[~((run_df["agent_id"] == "7") & (run_df["t_s"] > 7.0 + 1e-9))]
    path = export_openscenario(short, AGENTS, tmp_path, osc_version="1.0")
    assert validate_openscenario(path) == []
    root = SafeET.parse(path).getroot()
    dels = [e for e in root.iter("Event") if e.find(".//DeleteEntityAction") is not None]
    assert len(dels) == 1
    assert dels[0].find(".//EntityAction").get("entityRef") == "7"
    assert float(dels[0].find(".//SimulationTimeCondition").get("value")) == pytest.approx(
        7.0 - 1e-3
    )
    assert dels[0].get("priority") == "parallel"


def test_export_is_deterministic(tmp_path, run_df, straight_xodr):
    a = export_openscenario(run_df, AGENTS, tmp_path / "a", xodr=straight_xodr)
    b = export_openscenario(run_df, AGENTS, tmp_path / "b", xodr=straight_xodr)
    assert a.read_bytes() == b.read_bytes()


def test_speed_is_derived_from_positions_when_absent(tmp_path, run_df):
    path = export_openscenario(
        run_df.drop(columns="speed_mps"), AGENTS, tmp_path, ego_controller="simulator"
    )
    root = SafeET.parse(path).getroot()
    speeds = {
        p.get("entityRef"): float(p.find(".//AbsoluteTargetSpeed").get("value"))
        for p in root.find("Storyboard/Init").iter("Private")
        if p.find(".//AbsoluteTargetSpeed") is not None
    }
    assert speeds == pytest.approx({"ego": 5.6})


def test_timeseries_rows_of_one_config_and_active_only():
    df = crossing_run(duration_s=1.0)
    ts = pd.concat([df.assign(config="replay"), df.assign(config="normal-cap")])
    ts["variant"] = 0
    ts["active"] = ~((ts["agent_id"] == "c1") & (ts["t_s"] < 0.5))
    out = timeseries_to_trajectories(ts, config="normal-cap")
    assert len(out) == len(df) - 10
    assert out["t_s"][out["agent_id"] == "c1"].min() == pytest.approx(0.5)
    with pytest.raises(InputError, match="several configs"):
        timeseries_to_trajectories(ts)
    with pytest.raises(InputError, match="not in the time series"):
        timeseries_to_trajectories(ts, config="aggressive")


def test_errors_name_field_and_row(tmp_path, run_df):
    bad = run_df.copy()
    bad.loc[5, "x_m"] = np.nan
    with pytest.raises(InputError) as exc:
        export_openscenario(bad, AGENTS, tmp_path)
    assert exc.value.field == "x_m" and exc.value.row == 6
    with pytest.raises(InputError, match="no AgentInfo"):
        export_openscenario(run_df, AGENTS[:1], tmp_path)
    with pytest.raises(InputError, match="lack column"):
        export_openscenario(run_df.drop(columns="yaw_rad"), AGENTS, tmp_path)
    with pytest.raises(ConfigError, match="osc_version"):
        export_openscenario(run_df, AGENTS, tmp_path, osc_version="2.0")
    with pytest.raises(ConfigError, match="ego_controller"):
        export_openscenario(run_df, AGENTS, tmp_path, ego_controller="autopilot")
    with pytest.raises(InputError, match="OpenDRIVE map not found"):
        export_openscenario(run_df, AGENTS, tmp_path, xodr=tmp_path / "missing.xodr")
    assert not list(tmp_path.glob("*.xosc"))  # nothing half-written


def test_xsd_validation_catches_a_broken_file(tmp_path, run_df):
    path = export_openscenario(run_df, AGENTS, tmp_path)
    text = path.read_text().replace('vehicleCategory="bicycle"', 'vehicleCategory="escooter"', 1)
    broken = tmp_path / "broken.xosc"
    broken.write_text(text)
    errors = validate_openscenario(broken)
    assert len(errors) == 1 and "vehicleCategory" in errors[0]


def test_everyone_present_throughout_and_a_standing_simulator_ego(tmp_path):
    # ego standing (two samples at one place, as vei's esmini backend writes it) and a
    # cyclist from 0 s to the end: nothing to trigger, yet the act holds a (idle) group
    df = crossing_run(duration_s=2.0)
    df = df[df["agent_id"] != "7"].copy()
    ego = df["agent_id"] == "ego"
    df.loc[ego, ["x_m", "y_m"]] = (0.0, -1.5)
    for version in ("1.0", "1.3"):
        path = export_openscenario(
            df, AGENTS, tmp_path / version, osc_version=version, ego_controller="simulator"
        )
        assert validate_openscenario(path) == []
        root = SafeET.parse(path).getroot()
        assert [g.get("name") for g in root.iter("ManeuverGroup")] == ["vei_idle"]
        assert not list(root.iter("Event"))
        init = {p.get("entityRef") for p in root.find("Storyboard/Init").iter("Private")}
        assert init == {"ego", "c1"}


def test_entity_names_are_the_carla_backends_blueprints():
    from vei.export.openscenario import ENTITY_NAMES
    from vei.sim.backends.carla_frame import DEFAULT_BLUEPRINTS

    assert ENTITY_NAMES == DEFAULT_BLUEPRINTS


def test_export_does_not_import_the_simulation_layer():
    import subprocess
    import sys

    code = (
        "import sys, tempfile, pandas as pd\n"
        "from vei.export.openscenario import export_openscenario\n"
        "from vei.export.playback import play_xosc\n"
        "from vei.types import AgentInfo\n"
        "df = pd.DataFrame({'t_s': [0.0, 1.0], 'agent_id': 'ego', 'category': 'ego',\n"
        "                   'x_m': [0.0, 5.0], 'y_m': 0.0, 'yaw_rad': 0.0})\n"
        "export_openscenario(df, [AgentInfo('ego', 'ego', 4.7, 1.85)], tempfile.mkdtemp())\n"
        "print(sorted(m for m in sys.modules if m.startswith('vei.sim')))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
