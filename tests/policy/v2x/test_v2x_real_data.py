"""V2X on real data: the TrafficMonitoring left-turn recording imported with every road
user (the queue of stopped cars included), its cyclist 38 as the rider; the car's V2X
links are blocked exactly when an independent geometry library (shapely) says the straight
line from the rider to the car crosses a vehicle's box, and the queue does block them."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from vei.config import SimConfig, V2XConfig
from vei.policy.observation import category_code
from vei.policy.v2x import channel as ch
from vei.policy.v2x import model

SCENARIO = "audi_10_marktkauf_linksabbiegen"


@pytest.fixture(scope="module")
def imported(trafficmonitoring_root, tmp_path_factory):
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction

    base = tmp_path_factory.mktemp("tm")
    riders = read_interaction(import_scenario(trafficmonitoring_root, SCENARIO, base / "riders"))
    every = read_interaction(
        import_scenario(trafficmonitoring_root, SCENARIO, base / "all", road_users="all")
    )
    return riders, every


def test_road_users_all_adds_vehicles_and_pedestrians_and_keeps_the_riders(imported):
    riders, every = imported
    a, b = riders.annotations, every.annotations
    assert set(a["category"]) == {"cyclist"}
    assert set(b["category"]) == {"cyclist", "vehicle", "pedestrian"}
    assert b.loc[b["category"] == "vehicle", "track_id"].nunique() >= 15
    pd.testing.assert_frame_equal(
        b[b["category"] == "cyclist"].reset_index(drop=True), a.reset_index(drop=True)
    )
    # no size from the camera: vans / buses / trucks get their class's, cars vei's default
    sized = b.dropna(subset=["length_m"])
    assert set(sized["category"]) <= {"vehicle"}


def test_v2x_links_are_blocked_exactly_where_the_line_crosses_a_vehicle(imported):
    from shapely.geometry import LineString, Polygon

    from vei.boxes import box_corners
    from vei.recon.pipeline import reconstruct
    from vei.sim.observe import object_table
    from vei.sim.state import prepare_scenario

    sc = reconstruct(imported[1], threat="38")
    arrays = prepare_scenario(sc, SimConfig())
    length, width, cats = object_table(arrays)
    veh = cats == category_code("vehicle")
    n = length.size
    # One V2X step per engine step along the recording (the ego where the INS had it); the
    # rider is the primary, sending at every check (a 0-m position trigger, every 0.1 s),
    # so every check is a link to compare.
    cfg = V2XConfig(enabled=True, position_threshold_m=0.0, position_error_std_m=0.0)
    params = model.V2XParams.from_config(cfg, 1)
    keys = np.array([7])
    cols = np.array([0])
    st = model.init_state(cfg, params, keys, cols)
    checked = blocked_seen = 0
    rider = sc.trajectories[sc.trajectories["agent_id"] == sc.primary_threat].set_index("t_s")
    ego_tr = sc.trajectories[sc.trajectories["agent_id"] == "ego"].set_index("t_s")
    for k in range(arrays.t_s.size):
        t = arrays.t_s[k]
        if t not in rider.index or t not in ego_tr.index:
            continue
        r, e = rider.loc[t], ego_tr.loc[t]
        truth = np.zeros((6, 1, n))
        truth[:, 0, 0] = [r["x_m"], r["y_m"], r["yaw_rad"], 0.0, 0.0, 1.0]
        others = np.stack([arrays.other_x_m[k], arrays.other_y_m[k], arrays.other_yaw_rad[k],
                           np.zeros(n - 1), np.zeros(n - 1),
                           arrays.other_active[k].astype(float)])  # fmt: skip
        truth[:, 0, 1:] = others
        w = model.World(x_m=truth[0], y_m=truth[1], yaw_rad=truth[2], vx_mps=truth[3],
                        vy_mps=truth[4], valid=truth[5] > 0.5, length_m=length,
                        width_m=width, is_vehicle=veh, ego_x_m=np.array([e["x_m"]]),
                        ego_y_m=np.array([e["y_m"]]))  # fmt: skip
        _, st, ev = model.step(cfg, params, st, w, cols, k, arrays.dt_s, keys)
        if not ev["sent"][0, 0]:
            continue
        line = LineString([(r["x_m"], r["y_m"]), (e["x_m"], e["y_m"])])
        hit = False
        for j in np.flatnonzero(veh & w.valid[0]):
            poly = Polygon(box_corners(w.x_m[0, j], w.y_m[0, j], w.yaw_rad[0, j], length[j],
                                       width[j]))  # fmt: skip
            ends_inside = poly.contains(line.boundary.geoms[0]) or poly.contains(
                line.boundary.geoms[1]
            )
            if not ends_inside and line.intersection(poly).length > 1e-6:
                hit = True
        assert bool(ev["blocked"][0, 0]) == hit, t
        # NLOSv (LOS path loss + the blockage drawn) where blocked, else LOS (no map
        # buildings here): the delivery is the link budget's (TR 37.885)
        state = ch.NLOSV if hit else ch.LOS
        assert ev["link"][0, 0] == state
        d = float(np.hypot(r["x_m"] - e["x_m"], r["y_m"] - e["y_m"]))
        want = ch.link_pdr(np.array([d]), np.array([state]), "its-g5",
                           blockage_db=np.nan_to_num(ev["loss_db"][0, :1]))  # fmt: skip
        assert ev["pdr"][0, 0] == pytest.approx(float(want[0]), abs=1e-12)
        checked += 1
        blocked_seen += hit
    assert checked > 100
    # The stopped queue ahead of the car hides cyclist 38 for a good share of its span.
    assert 0.2 < blocked_seen / checked < 0.95
