"""Road geometry sampled from OpenDRIVE, against analytic shapes and CARLA's own waypoints."""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from tests.maps.odr_fixtures import lane, road, straight_road, write_odr  # noqa: E402
from vei.errors import InputError  # noqa: E402
from vei.maps.roads import draw_roads, drivable_share, load_roads  # noqa: E402


def test_straight_road_lanes_are_the_hand_computed_rectangles(tmp_path):
    roads = load_roads(write_odr(tmp_path / "s.xodr", straight_road()))
    by_id = {ln.lane_id: ln for ln in roads.lanes}
    assert set(by_id) == {1, -1, -2}
    assert by_id[-2].lane_type == "sidewalk" and not by_id[-2].drivable
    # Reference line y = 20 from x = 10 to 110; right lanes go to -y, left to +y.
    np.testing.assert_allclose(by_id[1].inner[:, 1], 20.0)
    np.testing.assert_allclose(by_id[1].outer[:, 1], 23.0)
    np.testing.assert_allclose(by_id[-1].outer[:, 1], 16.5)
    np.testing.assert_allclose(by_id[-2].outer[:, 1], 14.5)
    assert by_id[-1].inner[0, 0] == pytest.approx(10.0) and by_id[-1].inner[-1, 0] == pytest.approx(
        110.0
    )
    assert roads.drivable_area.area == pytest.approx(100.0 * (3.0 + 3.5))
    assert roads.bounds_xy == pytest.approx((10.0, 14.5, 110.0, 23.0))
    assert roads.proj_string.startswith("+proj=tmerc +lat_0=48.0")


def test_lane_offset_and_width_polynomial(tmp_path):
    # Width 3 + 0.01 s over 100 m -> area 350 m^2; lane offset +1 m shifts the inner border.
    r = road("1", 100.0, "<line/>", right=lane(-1, "driving", 3.0, 0.01),
             offset='<laneOffset s="0" a="1.0" b="0" c="0" d="0"/>')  # fmt: skip
    roads = load_roads(write_odr(tmp_path / "w.xodr", r))
    (ln,) = roads.lanes
    np.testing.assert_allclose(ln.inner[:, 1], 21.0)
    assert ln.outer[-1, 1] == pytest.approx(21.0 - 4.0)
    assert roads.drivable_area.area == pytest.approx(350.0, rel=1e-9)


def test_arc_gives_a_quarter_annulus(tmp_path):
    # Curvature 1/50 (left turn), quarter circle; right lane 4 m wide lies outside: R 50..54.
    length = 50.0 * math.pi / 2.0
    r = road("1", length, '<arc curvature="0.02"/>', right=lane(-1, "driving", 4.0), x=0.0, y=0.0)
    roads = load_roads(write_odr(tmp_path / "a.xodr", r), step_m=0.5)
    expected = math.pi / 4.0 * (54.0**2 - 50.0**2)
    assert roads.drivable_area.area == pytest.approx(expected, rel=1e-3)
    (ln,) = roads.lanes
    # End of the reference line: (50, 50) heading north; the outer border at x = 54.
    assert ln.inner[-1] == pytest.approx([50.0, 50.0], abs=1e-6)
    assert ln.outer[-1] == pytest.approx([54.0, 50.0], abs=1e-6)


def test_spiral_with_constant_curvature_equals_the_arc(tmp_path):
    length = 50.0 * math.pi / 2.0
    arc = load_roads(write_odr(tmp_path / "a.xodr", road("1", length, '<arc curvature="0.02"/>',
                                                         right=lane(-1, "driving", 4.0))))  # fmt: skip
    spi = load_roads(write_odr(tmp_path / "s.xodr", road("1", length, '<spiral curvStart="0.02" curvEnd="0.02"/>',
                                                         right=lane(-1, "driving", 4.0))))  # fmt: skip
    np.testing.assert_allclose(spi.lanes[0].outer, arc.lanes[0].outer, atol=2e-3)


def test_param_poly3_and_poly3_straight_lines(tmp_path):
    # paramPoly3 (normalized) for a 30 m line at 30 degrees; poly3 v = 0 for a line along hdg.
    c, s = 30.0 * math.cos(math.pi / 6), 30.0 * math.sin(math.pi / 6)
    pp = f'<paramPoly3 aU="0" bU="{c}" cU="0" dU="0" aV="0" bV="{s}" cV="0" dV="0" pRange="normalized"/>'
    r1 = road("1", 30.0, pp, left=lane(1, "driving", 2.0), x=0.0, y=0.0)
    r2 = road(
        "2", 30.0, '<poly3 a="0" b="0" c="0" d="0"/>', left=lane(1, "driving", 2.0), x=0.0, y=-50.0
    )
    roads = load_roads(write_odr(tmp_path / "p.xodr", r1, r2))
    lanes = {ln.road_id: ln for ln in roads.lanes}
    assert lanes["1"].inner[-1] == pytest.approx([c, s], abs=1e-6)
    # The left border is 2 m to the left of the 30-degree line.
    n = np.array([-math.sin(math.pi / 6), math.cos(math.pi / 6)])
    assert lanes["1"].outer[-1] == pytest.approx(np.array([c, s]) + 2.0 * n, abs=1e-6)
    assert lanes["2"].outer[-1] == pytest.approx([30.0, -48.0], abs=1e-6)
    assert roads.drivable_area.area == pytest.approx(2 * 60.0, rel=1e-9)


def test_drivable_share_hand_values(tmp_path):
    roads = load_roads(write_odr(tmp_path / "s.xodr", straight_road()))
    x = np.array([50.0, 50.0, 50.0, 50.0, np.nan])
    y = np.array([18.0, 21.0, 15.0, 30.0, 0.0])  # right lane, left lane, sidewalk, off-road, NaN
    assert drivable_share(roads, x, y) == pytest.approx(0.5)
    assert drivable_share(roads, [50.0], [23.9], tolerance_m=1.0) == 1.0
    assert drivable_share(roads, [50.0], [23.9]) == 0.0
    assert math.isnan(drivable_share(roads, [np.nan], [np.nan]))
    with pytest.raises(InputError):
        drivable_share(roads, [1.0, 2.0], [1.0])


def test_draw_roads_adds_the_lanes_under_everything(tmp_path):
    roads = load_roads(write_odr(tmp_path / "s.xodr", straight_road()))
    fig, ax = plt.subplots()
    (traj,) = ax.plot([0, 1], [0, 1], "r-")
    xlim = ax.get_xlim()
    artists = draw_roads(ax, roads)
    assert len(artists) == 4
    drive, other, lines, kerbs = artists
    assert len(drive.get_paths()) == 2 and len(other.get_paths()) == 1
    assert all(a.get_zorder() < traj.get_zorder() for a in artists)
    segs = lines.get_segments()
    # both borders of each driving lane (the centre line y = 20 twice)
    assert sorted(round(float(seg[0][1]), 6) for seg in segs) == [16.5, 20.0, 20.0, 23.0]
    # the kerb: the sidewalk's edge towards the carriageway (y = 20 - 3.5)
    assert kerbs.get_label() == "_kerbs"
    assert [round(float(y), 6) for y in np.unique(kerbs.get_segments()[0][:, 1])] == [16.5]
    assert ax.get_xlim() == xlim  # the map does not reframe the figure
    plt.close(fig)


def test_unsupported_geometry_and_bad_step(tmp_path):
    p = write_odr(
        tmp_path / "x.xodr", road("1", 10.0, "<clothoid/>", right=lane(-1, "driving", 3.0))
    )
    with pytest.raises(InputError, match="unsupported OpenDRIVE geometry <clothoid>"):
        load_roads(p)
    with pytest.raises(InputError, match="step_m"):
        load_roads(p, step_m=0.0)


def test_lanes_agree_with_carlas_waypoints_on_a_real_map(west_oakland_map):
    carla = pytest.importorskip("carla")
    roads = load_roads(west_oakland_map.opendrive)
    cmap = carla.Map("wo", west_oakland_map.opendrive.read_text())
    wps = cmap.generate_waypoints(2.0)
    x = np.array([w.transform.location.x for w in wps])
    y = -np.array([w.transform.location.y for w in wps])  # CARLA is left-handed: y flipped
    assert drivable_share(roads, x, y) >= 0.995
    assert drivable_share(roads, x, -y) < 0.5  # without the flip they miss


def test_lanes_agree_with_netconverts_sumo_lanes(west_oakland_map):
    import sumolib

    roads = load_roads(west_oakland_map.opendrive)
    net = sumolib.net.readNet(str(west_oakland_map.sumo_net))
    pts = np.array(
        [
            p
            for e in net.getEdges()
            for ln in e.getLanes()
            if ln.allows("passenger")
            for p in ln.getShape()
        ]
    )
    assert len(pts) > 100
    assert drivable_share(roads, pts[:, 0], pts[:, 1]) >= 0.97
