"""The road network under every picture (issue 26): bird's-eye figures, the case-study and
sweep panels and the catalogue report's map / replay draw the scenario's own lanes, lane
borders and kerbs in the tracks' coordinates; a scenario without a map still draws and
says so."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from matplotlib.path import Path as MplPath

from vei.maps.roads import NO_MAP_NOTE


@pytest.fixture(scope="module")
def real_folder(tmp_path_factory):
    """stadtmitte_12 reconstructed with the Ingolstadt map (it has sidewalks and bike lanes)."""
    from tests.conftest import require_data
    from vei.cli.main import main

    tm = require_data("trafficmonitoring")
    net = require_data("maps", "ingolstadt_research_intersection.net.xml.gz")
    root = tmp_path_factory.mktemp("roads")
    inter, folder = root / "interaction", root / "scenario"
    assert main(["import", "trafficmonitoring", "--root", str(tm), "--scenario",
                 "stadtmitte_12_audi_geradeaus_03", "--out", str(inter)]) == 0  # fmt: skip
    assert (
        main(["reconstruct", str(inter), "--out", str(folder), "--no-figure", "--map", str(net)])
        == 0
    )
    return folder


def _drawn_polygons(ax, label: str) -> list[MplPath]:
    coll = next(c for c in ax.collections if c.get_label() == label)
    return list(coll.get_paths())


def _inside(paths: list[MplPath], x, y) -> np.ndarray:
    pts = np.column_stack([x, y])
    hit = np.zeros(len(pts), dtype=bool)
    for p in paths:
        hit |= p.contains_points(pts)
    return hit


def test_recorded_car_track_lies_on_the_drawn_lanes(real_folder):
    """The bird's-eye figure draws the map in the tracks' plane: the recorded car's track
    lies on the drawn drivable lanes (the INS track on the OpenDRIVE map of the same area)."""
    from vei.io.scenario import read_scenario
    from vei.report.birdseye import plot_birdseye

    scen = read_scenario(real_folder)
    fig = plot_birdseye(scen)
    ax = fig.axes[0]
    ego = scen.track("ego")
    on = _inside(_drawn_polygons(ax, "drivable lanes"), ego["x_m"], ego["y_m"])
    assert on.mean() >= 0.95, on.mean()
    # the riders ride partly off the carriageway (bike lanes, sidewalks): not all on it
    kerbs = next(c for c in ax.collections if c.get_label() == "_kerbs")
    assert len(kerbs.get_segments()) > 10  # the map has sidewalks: kerbs drawn
    assert not any(t.get_label() == "_no road map" for t in ax.texts)
    # shifted coordinates would not match: the check can fail
    off = _inside(_drawn_polygons(ax, "drivable lanes"), ego["x_m"] + 40.0, ego["y_m"] + 40.0)
    assert off.mean() < on.mean()


def test_kerbs_are_the_sidewalk_edges(real_folder):
    from vei.maps import load_roads

    roads = load_roads(real_folder / "map.xodr")
    sidewalks = [ln for ln in roads.lanes if ln.lane_type == "sidewalk"]
    assert len(roads.kerbs) == len(sidewalks) > 0
    assert all(np.array_equal(k, s.inner) for k, s in zip(roads.kerbs, sidewalks, strict=True))


def test_case_study_panels_draw_the_roads_or_say_there_is_none(real_folder):
    from vei.experiments.casestudy import run_casestudy
    from vei.io.scenario import read_scenario
    from vei.report.birdseye import scenario_roads
    from vei.report.casestudy_figures import plot_birdseye_configs

    scen = read_scenario(real_folder)
    frame = run_casestudy(scen, cases=["replay", "normal"], time_shift="auto").frame
    fig = plot_birdseye_configs(frame, other_id=scen.primary_threat, roads=scenario_roads(scen))
    for ax in fig.axes[:2]:
        ego = frame[(frame["config"] == "replay") & (frame["agent_id"] == "ego")]
        on = _inside(_drawn_polygons(ax, "drivable lanes"), ego["x_m"], ego["y_m"])
        assert on.mean() >= 0.95
    fig = plot_birdseye_configs(frame, other_id=scen.primary_threat, roads=None)
    for ax in fig.axes[:2]:
        assert [t.get_text() for t in ax.texts if t.get_label() == "_no road map"] == [NO_MAP_NOTE]


def test_birdseye_without_map_says_so(real_folder, tmp_path):
    from vei.io.scenario import read_scenario, write_scenario
    from vei.report.birdseye import plot_birdseye

    scen = read_scenario(real_folder)
    nomap = read_scenario(write_scenario(dataclasses.replace(scen, maps={}), tmp_path / "s"))
    ax = plot_birdseye(nomap).axes[0]
    assert not ax.collections or all(c.get_label() != "drivable lanes" for c in ax.collections)
    assert any(t.get_text() == NO_MAP_NOTE for t in ax.texts)
    assert len(ax.get_lines()) > 3  # the tracks are still drawn


def test_report_road_layers(real_folder, tmp_path):
    """The report's data: drivable lanes, sidewalks, lane borders and kerbs in the tracks'
    plane (the recorded car on the lanes); a scenario without a map gives the note."""
    import shapely

    from vei.catalogue.report_data import _road_layers, _roads
    from vei.io.scenario import read_scenario, write_scenario

    roads = _roads(real_folder)
    layers = _road_layers(real_folder)
    assert {"sidewalks", "lines", "kerbs"} <= set(layers) and all(
        layers[k] for k in ("sidewalks", "lines", "kerbs")
    )
    xs, ys = roads["x"], roads["y"]
    rings, cur = [], []
    for x, y in zip(xs, ys, strict=True):
        if x is None:
            rings.append(cur)
            cur = []
        else:
            cur.append((x, y))
    area = shapely.union_all([shapely.Polygon(r).buffer(0) for r in rings if len(r) >= 4])
    ego = read_scenario(real_folder).track("ego")
    on = shapely.contains_xy(area.buffer(0.3), ego["x_m"].to_numpy(), ego["y_m"].to_numpy())
    assert on.mean() >= 0.95, on.mean()
    scen = read_scenario(real_folder)
    nomap = write_scenario(dataclasses.replace(scen, maps={}), tmp_path / "s")
    assert _road_layers(nomap) == {"note": NO_MAP_NOTE} and _roads(nomap) is None
