"""Which links are blocked: vehicle blocker heights (TR 37.885's vehicle types), building
outlines of the scenario's OpenStreetMap source (NLOS), read the way the continuations
read them."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from shapely.geometry import Polygon

from vei.config import V2XConfig
from vei.policy.v2x import channel as ch
from vei.policy.v2x import model
from vei.policy.v2x.links import Buildings, blocker_heights_m, scene_buildings, tallest_blocker_m
from vei.sim.testing import TrackSpec, ego_straight, make_scenario


def test_blocker_heights_by_length():
    assert blocker_heights_m(np.array([4.5, 5.5, 5.9, 12.0]), 5.5) == pytest.approx(
        [1.6, 1.6, 3.0, 3.0]
    )


def test_the_tallest_of_several_blockers_counts():
    # two boxes across the line from (0, 0) to (20, 0): a car (1.6 m) and a van (3 m)
    h = tallest_blocker_m(
        np.array([20.0, 20.0]), np.array([0.0, 8.0]), np.zeros(2), np.zeros(2),
        np.array([[5.0, 12.0]] * 2), np.zeros((2, 2)), np.zeros((2, 2)),
        np.array([[4.5, 5.9]] * 2), np.array([[1.8, 2.1]] * 2), np.array([[1.6, 3.0]] * 2),
        np.ones((2, 2), bool),
    )  # fmt: skip
    # the second link runs from (20, 8) to (0, 0): y = 0.4 x, 1.1 m at the car's rear
    # (x = 2.75) and 3.6 m at the van's (x = 9.05): clear of both (half widths 0.9, 1.05)
    assert h == pytest.approx([3.0, 0.0])


def test_buildings_block_links_through_them_not_from_inside():
    b = Buildings([Polygon([(20, 5), (30, 5), (30, 15), (20, 15)])])
    sx = np.array([40.0, 40.0, 25.0, 40.0])
    sy = np.array([20.0, 0.0, 10.0, 40.0])
    got = b.blocks(sx, sy, np.zeros(4), np.zeros(4))
    # through it; beside it (y = 0); from inside it (an arcade: ignored); above it
    assert got.tolist() == [True, False, False, False]
    import pickle

    again = pickle.loads(pickle.dumps(b))
    assert again.blocks(sx, sy, np.zeros(4), np.zeros(4)).tolist() == got.tolist()


def _osm(path, projection: str, rings) -> None:
    from vei.geo.frame import LocalFrame

    frame = LocalFrame.from_proj_string(projection)
    nodes, ways, nid = [], [], 0
    for w, ring in enumerate(rings, start=1):
        lat, lon = frame.to_latlon([p[0] for p in ring], [p[1] for p in ring])
        refs = []
        for la, lo in zip(lat, lon, strict=True):
            nid += 1
            nodes.append(f'<node id="{nid}" lat="{la:.9f}" lon="{lo:.9f}"/>')
            refs.append(f'<nd ref="{nid}"/>')
        refs.append(refs[0])
        ways.append(f'<way id="{w}">{"".join(refs)}<tag k="building" v="yes"/></way>')
    path.write_text(
        f'<?xml version="1.0"?><osm version="0.6">{"".join(nodes)}{"".join(ways)}</osm>'
    )


def _corner_scenario(tmp_path, with_map: bool = True):
    """The car along y = 0; a cyclist waiting at (60, 20) behind a building at the corner
    (x 40..55, y 4..30); a second building 2 km away (outside the scene: dropped)."""
    t = np.arange(0, 201) / 20.0
    n = t.size
    rider = TrackSpec("cyclist", t, np.full(n, 60.0), np.full(n, 20.0), np.full(n, -math.pi / 2),
                      np.zeros(n))  # fmt: skip
    sc = make_scenario({"ego": ego_straight(8.0, 10.0, 20.0), "cyclist_1": rider},
                       primary_threat="cyclist_1")  # fmt: skip
    if not with_map:
        return sc
    _osm(tmp_path / "map.osm", sc.projection,
         [[(40, 4), (55, 4), (55, 30), (40, 30)], [(2000, 0), (2010, 0), (2010, 10), (2000, 10)]])  # fmt: skip
    return dataclasses.replace(sc, root=tmp_path, maps={"osm": "map.osm"})


def test_scene_buildings_reads_the_osm_outlines_near_the_scene(tmp_path):
    sc = _corner_scenario(tmp_path)
    b = scene_buildings(sc)
    assert b is not None and len(b) == 1
    assert b.polygons[0].area == pytest.approx(15 * 26, rel=1e-3)
    assert scene_buildings(_corner_scenario(tmp_path, with_map=False)) is None


def test_prepared_arrays_carry_the_buildings_and_links_through_them_are_nlos(tmp_path):
    from vei.config import SimConfig
    from vei.sim.state import prepare_scenario

    arrays = prepare_scenario(_corner_scenario(tmp_path), SimConfig())
    assert arrays.buildings is not None and len(arrays.buildings) == 1
    # the car at (0, 0): the line to (60, 20) crosses the building (y = x / 3: 13.3 m at
    # x = 40); at (58, 0) it runs beside it (x 58..60 > 55)
    for ego_x, state in ((0.0, ch.NLOS), (58.0, ch.LOS)):
        b = 2000
        w = model.World(
            x_m=np.full((b, 1), 60.0), y_m=np.full((b, 1), 20.0), yaw_rad=np.zeros((b, 1)),
            vx_mps=np.zeros((b, 1)), vy_mps=np.zeros((b, 1)), valid=np.ones((b, 1), bool),
            length_m=np.array([1.8]), width_m=np.array([0.6]), is_vehicle=np.array([False]),
            ego_x_m=np.full(b, ego_x), ego_y_m=np.zeros(b), buildings=arrays.buildings,
        )  # fmt: skip
        cfg = V2XConfig(enabled=True, position_error_std_m=0.0, technology="c-v2x-pc5")
        params = model.V2XParams.from_config(cfg, b)
        keys = np.arange(b)
        st = model.init_state(cfg, params, keys, np.array([0]))
        _, _, ev = model.step(cfg, params, st, w, np.array([0]), 0, 0.05, keys)
        assert (ev["link"][:, 0] == state).all() and (ev["nlos"][:, 0] == (state == ch.NLOS)).all()
        d = math.hypot(60.0 - ego_x, 20.0)
        want = float(ch.link_pdr(np.array([d]), np.array([state]), "c-v2x-pc5")[0])
        assert ev["pdr"][:, 0] == pytest.approx(want, abs=1e-12)
    off = dataclasses.replace(cfg, buildings=False)
    _, _, ev = model.step(off, params, model.init_state(off, params, keys, np.array([0])),
                          dataclasses.replace(w, ego_x_m=np.zeros(b)), np.array([0]), 0, 0.05,
                          keys)  # fmt: skip
    assert (ev["link"][:, 0] == ch.LOS).all()


def test_a_run_through_a_building_delivers_next_to_nothing(tmp_path):
    """End to end (prepare_scenario -> the engine's V2X -> SimResult.v2x): a rider waiting
    300 m off the car's road behind a building; its VAMs are NLOS (ITS-G5 at 240-320 m:
    delivery 0.03 to 0.002) with the map, LOS (delivery 1.0) without it."""
    from vei.config import SimConfig
    from vei.experiments.v2x_study import study_case
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario

    t = np.arange(0, 201) / 20.0
    n = t.size
    rider = TrackSpec("cyclist", t, np.full(n, 300.0), np.full(n, 120.0), np.zeros(n), np.zeros(n))
    sc = make_scenario({"ego": ego_straight(8.0, 10.0, 20.0), "cyclist_1": rider},
                       primary_threat="cyclist_1")  # fmt: skip
    _osm(tmp_path / "map.osm", sc.projection, [[(190, 30), (210, 30), (210, 110), (190, 110)]])
    with_map = dataclasses.replace(sc, root=tmp_path, maps={"osm": "map.osm"})
    case = study_case(V2XConfig(enabled=True, position_error_std_m=0.0))
    got = {}
    for name, scen in (("map", with_map), ("no map", sc)):
        arrays = prepare_scenario(scen, SimConfig())
        p = VariantParams.from_case(case, arrays, 20)
        p = p.with_values(labels=np.array([f"v{i}" for i in range(20)], dtype=object))
        res = simulate(arrays, p, record="none")
        got[name] = (res.v2x["v2x_sent"].sum(), res.v2x["v2x_delivered"].sum())
    sent, delivered = got["map"]
    assert sent == got["no map"][0] >= 40  # a standing rider: t = 0 and every 5.1 s
    assert got["no map"][1] == sent
    assert delivered <= 3
