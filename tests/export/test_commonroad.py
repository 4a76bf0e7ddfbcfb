"""`vei export commonroad`: the CommonRoad scenario reads back equal (commonroad-io),
its lanelets are the map's lanes, and CommonRoad's own collision checker
(commonroad-drivability-checker) finds the ego's first collision at vei's step (within
one) on the demo and on every shared recording with a rider made critical (the
'replay' configuration at the automatic time shift)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from tests.helpers_data import REAL_WITH_RIDER
from vei.errors import InputError

pytest.importorskip("commonroad")
pytest.importorskip("commonroad_dc")

from vei.export.commonroad import (  # noqa: E402
    build_scenario,
    export_commonroad,
    first_collision_step,
    read_commonroad,
)
from vei.export.openscenario import timeseries_to_trajectories  # noqa: E402

DT_S = 0.05


@pytest.fixture(scope="module")
def demo_world(tmp_path_factory):
    """The demo with its synthetic map and its 'replay' run at the automatic shift."""
    from vei.experiments.casestudy import run_casestudy
    from vei.experiments.demo_map import write_demo_scenario
    from vei.io.scenario import read_scenario

    folder = write_demo_scenario(tmp_path_factory.mktemp("cr") / "demo")
    scen = read_scenario(folder)
    frame = run_casestudy(scen, cases=["replay"], time_shift="auto").frame
    return folder, scen, frame


def _vei_first_contact(frame: pd.DataFrame) -> int | None:
    hit = frame[frame["collided"].astype(bool) & (frame["agent_id"] != "ego")]
    return None if hit.empty else int(round(float(hit["t_s"].min()) / DT_S))


def _export(folder, scen, frame, out, config="replay"):
    traj = timeseries_to_trajectories(frame, config=config)
    xodr = folder / scen.maps["opendrive"]
    path = export_commonroad(traj, list(scen.agents), out, xodr=xodr, dt_s=DT_S, name="run",
                             projection=scen.projection)  # fmt: skip
    return traj, xodr, path


def test_commonroads_usual_reader_reads_the_export(demo_world, tmp_path):
    """CommonRoad's usual entry point imports beside Ray (protobuf 3.20.3: commonroad-io's
    generated protobuf modules fail on protobuf 4 and later with "Descriptors cannot be
    created directly") and reads vei's file as vei's own reader does."""
    import ray  # noqa: F401  (the distributed extra is in the same environment)
    from commonroad.common.file_reader import CommonRoadFileReader

    folder, scen, frame = demo_world
    _, _, path = _export(folder, scen, frame, tmp_path)
    usual, usual_problems = CommonRoadFileReader(str(path)).open()
    read, _ = read_commonroad(path)
    assert {o.obstacle_id for o in usual.obstacles} == {o.obstacle_id for o in read.obstacles}
    assert len(usual.lanelet_network.lanelets) == len(read.lanelet_network.lanelets) > 0
    assert len(usual_problems.planning_problem_dict) == 1


def test_round_trip_equal(demo_world, tmp_path):
    folder, scen, frame = demo_world
    traj, xodr, path = _export(folder, scen, frame, tmp_path)
    read, problems = read_commonroad(path)
    built, built_problems, ego, ids = build_scenario(
        traj, list(scen.agents), xodr, dt_s=DT_S, name="run", projection=scen.projection
    )
    assert read == built and problems == built_problems
    assert len(read.dynamic_obstacles) == len(scen.agents) - 1
    ob = read.dynamic_obstacles[0]
    assert ob.obstacle_type.name == "BICYCLE"  # the e-scooter (CommonRoad has no e-scooter)
    assert ids["agent_id"].tolist() == [scen.primary_threat]
    # the obstacle's states are the run's rows (to the written 1 um)
    rider = traj[traj["agent_id"] == scen.primary_threat].sort_values("t_s")
    states = [ob.initial_state, *ob.prediction.trajectory.state_list]
    assert len(states) == len(rider)
    xy = np.array([s.position for s in states])
    np.testing.assert_allclose(xy, rider[["x_m", "y_m"]].to_numpy(), atol=1e-6)
    assert states[0].time_step == int(round(rider["t_s"].iloc[0] / DT_S))
    # the planning problem starts where the ego starts
    pp = next(iter(problems.planning_problem_dict.values()))
    np.testing.assert_allclose(pp.initial_state.position, ego[["x_m", "y_m"]].iloc[0], atol=1e-6)
    assert read.location.gps_latitude == pytest.approx(
        float(scen.projection.split("lat_0=")[1].split()[0])
    )


def test_lanelets_are_the_map_lanes(demo_world):
    """The demo street: 3.5 m driving lanes (eastbound south of the centre line, westbound
    north) and 2.5 m sidewalks; the recorded ego track lies on the eastbound lanelet."""
    from vei.export.commonroad_map import load_lanelet_network
    from vei.maps import load_roads

    folder, scen, _ = demo_world
    net, ids = load_lanelet_network(folder / "map.xodr")
    lanes = load_roads(folder / "map.xodr").lanes
    assert len(net.lanelets) == len(lanes) == 8
    main_east = net.find_lanelet_by_id(ids[("1", 0, -1)])
    main_west = net.find_lanelet_by_id(ids[("1", 0, 1)])
    for ll, width in ((main_east, 3.5), (main_west, 3.5)):
        w = np.hypot(*(ll.left_vertices - ll.right_vertices).T)
        np.testing.assert_allclose(w, width, atol=1e-6)
    east = main_east.center_vertices[-1] - main_east.center_vertices[0]
    west = main_west.center_vertices[-1] - main_west.center_vertices[0]
    assert east[0] > 250 and west[0] < -250  # driving directions
    assert main_east.adj_left == main_west.lanelet_id
    assert main_east.adj_left_same_direction is False
    assert {t.name for t in net.find_lanelet_by_id(ids[("1", 0, -2)]).lanelet_type} == {"SIDEWALK"}
    ego = scen.track("ego")
    pts = [np.array([x, y]) for x, y in zip(ego["x_m"], ego["y_m"], strict=True)]
    on = net.find_lanelet_by_position(pts)
    assert all(main_east.lanelet_id in found for found in on)


def test_collision_checker_agrees_on_the_demo(demo_world, tmp_path):
    folder, scen, frame = demo_world
    _, _, path = _export(folder, scen, frame, tmp_path)
    read, _ = read_commonroad(path)
    ego = pd.read_csv(tmp_path / "run_ego.csv")
    info = scen.agent("ego")
    k_cr = first_collision_step(read, ego, info.length_m, info.width_m)
    k_vei = _vei_first_contact(frame)
    assert k_vei is not None and k_cr is not None and abs(k_cr - k_vei) <= 1


@pytest.mark.slow
@pytest.mark.parametrize("recording", REAL_WITH_RIDER)
def test_collision_checker_agrees_on_real_recordings(playback_world, recording, tmp_path):
    """Every shared recording with a rider made critical ('replay', automatic time shift;
    where the recorded routes never meet, the rider's route moved by the smallest plausible
    offset first: --make-critical timing+path): vei's ego hits it, and CommonRoad's checker
    finds that first contact at vei's step (measured: the same step on all seven)."""
    from vei.experiments.casestudy import run_casestudy

    world = playback_world(recording)
    frame = run_casestudy(
        world.scenario, cases=["replay"], time_shift="auto", make_critical="timing+path"
    ).frame
    _, _, path = _export(world.folder, world.scenario, frame, tmp_path)
    read, _ = read_commonroad(path)
    ego = pd.read_csv(tmp_path / "run_ego.csv")
    info = world.scenario.agent("ego")
    k_cr = first_collision_step(read, ego, info.length_m, info.width_m)
    k_vei = _vei_first_contact(frame)
    assert k_vei is not None  # made critical
    assert k_cr is not None and abs(k_cr - k_vei) <= 1, (k_cr, k_vei)


def test_cli_and_missing_map(demo_world, tmp_path, capsys):
    from vei.cli.main import main

    folder, scen, _ = demo_world
    assert (
        main(
            [
                "export",
                "commonroad",
                str(folder),
                "--config",
                "replay",
                "--out",
                str(tmp_path / "a"),
                "--check",
            ]
        )
        == 0
    )
    out = capsys.readouterr().out
    assert "vei: first ego contact at step" in out and "CommonRoad (8 lanelets, 1 obstacles" in out
    k_vei = int(out.split("vei: first ego contact at step ")[1].split()[0])
    k_cr = int(out.split("first collision at")[1].split("step ")[1].split()[0])
    assert abs(k_vei - k_cr) <= 1
    # the recorded trajectories (no --config)
    assert main(["export", "commonroad", str(folder), "--out", str(tmp_path / "b")]) == 0
    # a scenario folder without a map: a clear error, exit 2
    import dataclasses

    from vei.io.scenario import write_scenario

    nomap = write_scenario(dataclasses.replace(scen, maps={}), tmp_path / "nomap")
    assert main(["export", "commonroad", str(nomap), "--out", str(tmp_path / "c")]) == 2
    err = capsys.readouterr().err
    assert "no road map (map.xodr)" in err and "vei reconstruct --map" in err
    with pytest.raises(InputError, match="no road map"):
        export_commonroad(
            scen.trajectories, list(scen.agents), tmp_path, xodr=None, dt_s=DT_S, name="x"
        )
