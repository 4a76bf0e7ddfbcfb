"""esmini playback of exported files: log parsing, the comparison, and real plays of small
hand-made runs whose outcome is computed by hand (and of files broken on purpose)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest
from defusedxml import ElementTree as SafeET

from tests.export.conftest import AGENTS, crossing_run
from vei.boxes import boxes_overlap
from vei.export.openscenario import OSC_VERSIONS, export_openscenario
from vei.export.playback import (
    FileEntity,
    compare_playback,
    parse_esmini_log,
    play_xosc,
    read_file_entities,
)
from vei.types import AgentInfo

LOG = """esmini GIT REV: N/A
[] [info] Loading x.xosc (v1.2)
[] [warn] No OpenDRIVE file specified, continue without
[] [warn] 3D model car_white.osgb not located, using specified file path
[] [warn] Traffic sign mapping file traffic_signals/opendrive_traffic_signals.txt not located
[] [warn] Warning: simulationTime = 0 condition used with edge "rising" which could be missed.
[4.850] [warn] Collision between s and ego
[5.900] [warn] Collision between s and ego dissolved
[7.050] [error] Failed to deactivate obj s. Already inactive (0 in active list).
[7.100] [info] Deleted entity s
"""


def test_log_lines_are_sorted_into_collisions_warnings_and_installation_notes():
    s = parse_esmini_log(LOG)
    assert s.collisions == ((4.85, "ego", "s"),)  # names sorted, 'dissolved' not a new one
    assert s.no_map is True
    assert len(s.install_warnings) == 2
    assert s.warnings == (
        '[] [warn] Warning: simulationTime = 0 condition used with edge "rising" which could '
        "be missed.",
    )
    assert s.errors == (
        "[7.050] [error] Failed to deactivate obj s. Already inactive (0 in active list).",
    )


def test_comparison_by_hand():
    # a trajectory 0 -> 10 m along x in 1 s, present from Init, deleted after 1 s
    ent = FileEntity(
        "a",
        np.array([[0.0, 0.0, 0.0, 0.0], [1.0, 10.0, 0.0, 0.0]]),
        True,
        start_s=0.0,
        end_s=1.0 - 1e-3,
    )
    # b: added by a trigger at 0.5 s, never deleted; recorded from 0.6 s (one step late)
    ent_b = FileEntity(
        "b", np.array([[0.5, 0.0, 5.0, 0.0], [2.0, 0.0, 20.0, 0.0]]), True, 0.499, math.inf
    )
    frames = pd.DataFrame(
        [
            (0.0, "a", 0.0, 0.0),
            (0.5, "a", 5.0, 0.1),  # 0.1 m off
            (1.0, "a", 10.0, 0.0),
            (1.5, "a", 10.0, 0.0),  # after its deletion step: outside
            (1.0, "b", 0.0, 10.0 + 0.04),  # 0.04 m off; 0.5 s frame absent (allowed)
            (2.0, "b", 0.0, 20.0),  # 1.5 s frame missing
        ],
        columns=["time", "name", "x", "y"],
    )
    a, b = compare_playback(frames, {"a": ent, "b": ent_b}, dt_s=0.5, t_last_s=2.0)
    assert (a.frames, a.compared, a.outside, a.missing) == (4, 3, 1, 0)
    assert a.median_dev_m == pytest.approx(0.0) and a.max_dev_m == pytest.approx(0.1)
    assert (b.frames, b.compared, b.outside, b.missing) == (2, 2, 0, 1)
    assert b.median_dev_m == pytest.approx(0.02) and b.max_dev_m == pytest.approx(0.04)


def _short_scooter(df: pd.DataFrame) -> pd.DataFrame:
    """The crossing run with the scooter's track ending at 7 s (so it must be deleted)."""
    return df[~((df["agent_id"] == "7") & (df["t_s"] > 7.0 + 1e-9))].reset_index(drop=True)


@pytest.mark.parametrize("version", OSC_VERSIONS)
def test_crossing_run_plays_as_written(tmp_path, straight_xodr, esmini, version):
    df = _short_scooter(crossing_run())
    path = export_openscenario(df, AGENTS, tmp_path, xodr=straight_xodr, osc_version=version)
    rep = play_xosc(path, esmini=esmini, work_dir=tmp_path / "play")
    assert rep.issues() == [], rep.issues()
    assert not rep.log.no_map  # the map next to the file, by its bare name, was loaded
    e = {c.name: c for c in rep.entities}
    # ego and cyclist from the first frame to the last (201 frames at 0.05 s over 10 s)
    assert (e["ego"].frames, e["ego"].first_s, e["ego"].last_s) == (201, 0.0, 10.0)
    assert (e["c1"].frames, e["c1"].first_s, e["c1"].last_s) == (201, 0.0, 10.0)
    # the scooter: samples 2..7 s; added at the 2 s step, recorded from 2.05 s to 7 s
    assert (e["7"].first_s, e["7"].last_s, e["7"].frames) == (2.05, 7.0, 100)
    for c in e.values():
        assert c.max_dev_m < 1e-3, c  # straight lines: played exactly
    # the cyclist's abrupt stop at 6 s: standing at x = 90 m afterwards
    c1 = rep.frames[(rep.frames["name"] == "c1") & (rep.frames["time"] > 6.0)]
    assert np.allclose(c1["x"], 90.0, atol=1e-3)
    assert rep.log.collisions == ()
    assert rep.log_bytes < 50_000


def test_standing_obstacle_contact_time_by_hand(tmp_path, esmini):
    """Ego (4.7 x 1.85 m) at 5.6 m/s along y = -1.5 from x = 0; an e-scooter (1.2 x 0.6 m)
    standing at x = 30 m in the same lane from 2 s. Front bumper 5.6 t + 2.35 meets the
    scooter's rear 29.4 at t = 4.830 s: first overlapping frame 4.85 s; the ego's rear
    5.6 t - 2.35 leaves its front 30.6 at t = 5.884 s (replayed, it drives through)."""
    t = np.round(np.arange(0.0, 8.0 + 1e-9, 0.05), 6)
    rows = [(ti, "ego", "ego", 5.6 * ti, -1.5, 0.0, 5.6) for ti in t]
    rows += [(ti, "s", "escooter", 30.0, -1.5, 0.0, 0.0) for ti in t if ti >= 2.0]
    df = pd.DataFrame(
        rows, columns=["t_s", "agent_id", "category", "x_m", "y_m", "yaw_rad", "speed_mps"]
    )
    agents = (AgentInfo("ego", "ego", 4.7, 1.85), AgentInfo("s", "escooter", 1.2, 0.6))
    # vei's box geometry puts the first contact at the same frame
    ego = df[df["agent_id"] == "ego"].set_index("t_s")
    ov = boxes_overlap(ego["x_m"], ego["y_m"], 0.0, 4.7, 1.85, 30.0, -1.5, 0.0, 1.2, 0.6)
    assert float(ego.index[np.flatnonzero(ov)[0]]) == pytest.approx(4.85)
    for version in ("1.0", "1.2"):
        path = export_openscenario(df, agents, tmp_path / version, osc_version=version)
        rep = play_xosc(path, esmini=esmini, work_dir=tmp_path / version / "play")
        assert rep.issues() == []
        assert len(rep.log.collisions) == 1
        t_hit, a, b = rep.log.collisions[0]
        assert (a, b) == ("ego", "s")
        assert t_hit == pytest.approx(4.85, abs=0.05 + 1e-9)


def _edit(path, out, fn):
    tree = ET.ElementTree(SafeET.parse(path).getroot())
    fn(tree.getroot())
    tree.write(out, encoding="utf-8", xml_declaration=True)
    return out


def test_broken_files_are_caught(tmp_path, straight_xodr, esmini):
    df = _short_scooter(crossing_run())
    path = export_openscenario(df, AGENTS, tmp_path, xodr=straight_xodr, osc_version="1.2")
    assert play_xosc(path, esmini=esmini).issues() == []

    # 1. the issue's bug: the scooter's start on "time > 0, edge rising" exists from the
    #    first step, standing at its first vertex until its trajectory begins
    def rising_at_zero(root):
        ev = [e for e in root.iter("Event") if e.get("name") == "7_appear"][0]
        ev.find(".//Condition").set("conditionEdge", "rising")
        ev.find(".//SimulationTimeCondition").set("value", "0")

    bad = play_xosc(_edit(path, tmp_path / "rising.xosc", rising_at_zero), esmini=esmini)
    scooter = {c.name: c for c in bad.entities}["7"]
    assert scooter.outside == 38 and scooter.first_s == pytest.approx(0.1)  # 0.1 .. 1.95 s
    assert any("outside its span" in i for i in bad.issues())

    # 2. no DeleteEntityAction: the scooter stands at its last vertex after 7 s
    def no_delete(root):
        for man in root.iter("Maneuver"):
            for ev in list(man):
                if ev.get("name") == "7_disappear":
                    man.remove(ev)

    bad = play_xosc(_edit(path, tmp_path / "nodelete.xosc", no_delete), esmini=esmini)
    assert {c.name: c for c in bad.entities}["7"].outside == 60  # 7.05 .. 10 s
    # (the checker reads the file it is given: without the delete, the window is open;
    # so the span check is against the trajectory's own last vertex)
    ents = read_file_entities(tmp_path / "nodelete.xosc")
    assert ents["7"].end_s == math.inf and ents["7"].vertices[-1, 0] == pytest.approx(7.0)

    # 3. the ego's trajectory shifted by 1 s (Timing offset): 5.6 m off
    def offset(root):
        root.find("Storyboard/Init").find(".//Timing").set("offset", "1.0")

    bad = play_xosc(_edit(path, tmp_path / "offset.xosc", offset), esmini=esmini)
    ego = {c.name: c for c in bad.entities}["ego"]
    assert ego.median_dev_m == pytest.approx(5.6, abs=0.01)
    assert any(i.startswith("ego: played") for i in bad.issues())
    assert bad.log_bytes < 50_000  # odd files keep the log small

    # 4. a map that is not there: esmini refuses the file; an issue, not a crash
    def missing_map(root):
        root.find("RoadNetwork/LogicFile").set("filepath", "nowhere.xodr")

    bad = play_xosc(_edit(path, tmp_path / "nomap.xosc", missing_map), esmini=esmini)
    assert bad.returncode != 0 and bad.entities == ()
    assert any("could not play" in i for i in bad.issues())
    assert any("nowhere.xodr" in e for e in bad.log.errors)


def test_simulator_ego_drives_its_path_and_stops_at_its_end(tmp_path, straight_xodr, esmini):
    df = crossing_run()
    for version in ("1.0", "1.3"):
        path = export_openscenario(
            df, AGENTS, tmp_path / version, xodr=straight_xodr, osc_version=version,
            ego_controller="simulator",
        )  # fmt: skip
        rep = play_xosc(path, esmini=esmini, work_dir=tmp_path / version / "play")
        assert rep.issues() == [], rep.issues()
        ego = {c.name: c for c in rep.entities}["ego"]
        assert ego.compared == 201 and ego.max_dev_m < 0.01  # on its (straight) path
        played = rep.frames[rep.frames["name"] == "ego"]
        # cruising at 5.6 m/s from 5.6 m/s: at the path end (56 m) at 10 s
        assert played["x"].iloc[-1] == pytest.approx(56.0, abs=0.3)
        assert played["x"].max() <= 56.0 + 0.3


def test_a_file_not_written_by_vei_is_played_without_comparison(esmini, tmp_path):
    """esmini's own example (lane positions, catalogs): nothing to compare with, but it
    plays, its log is sorted and its entities are there from Init on."""
    example = esmini.root / "examples" / "xosc" / "cut-in.xosc"
    if not example.is_file():
        pytest.skip(f"{example} not in this esmini installation")
    rep = play_xosc(example, esmini=esmini, work_dir=tmp_path)
    assert rep.returncode == 0
    assert [(e.name, e.compared, e.outside) for e in rep.entities] == [
        ("Ego", 0, 0),
        ("OverTaker", 0, 0),
    ]
    assert all(e.frames > 100 for e in rep.entities)
    assert any("scene graph file" in w for w in rep.log.install_warnings)
