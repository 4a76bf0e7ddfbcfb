"""vei <-> CARLA frame conversions: known points, round trips, and CARLA's own map parser."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.sim.backends.carla_frame import (
    DEFAULT_BLUEPRINTS,
    carla_deg_to_yaw,
    carla_to_world_velocity,
    carla_to_world_xy,
    command_to_pedals,
    pure_pursuit_steer,
    world_to_carla_velocity,
    world_to_carla_xy,
    wrap_deg,
    yaw_to_carla_deg,
)


@pytest.mark.parametrize(
    ("yaw_rad", "carla_deg"),
    [
        (0.0, 0.0),  # east stays east
        (math.pi / 2, -90.0),  # north (CCW +90) is CARLA -90 (its +y points south)
        (-math.pi / 2, 90.0),  # south
        (math.pi, -180.0),  # west (wrapped to [-180, 180))
        (math.radians(30.0), -30.0),
    ],
)
def test_yaw_known_values(yaw_rad, carla_deg):
    assert yaw_to_carla_deg(yaw_rad) == pytest.approx(carla_deg)


def test_positions_known_values_and_round_trip():
    x, y = world_to_carla_xy(np.array([10.0, -3.0]), np.array([5.0, -7.5]))
    np.testing.assert_array_equal(x, [10.0, -3.0])
    np.testing.assert_array_equal(y, [-5.0, 7.5])
    bx, by = carla_to_world_xy(x, y)
    np.testing.assert_array_equal(bx, [10.0, -3.0])
    np.testing.assert_array_equal(by, [5.0, -7.5])


def test_yaw_and_velocity_round_trips():
    rng = np.random.default_rng(3)
    yaw = rng.uniform(-math.pi, math.pi, 1000)
    back = carla_deg_to_yaw(yaw_to_carla_deg(yaw))
    np.testing.assert_allclose(np.angle(np.exp(1j * (back - yaw))), 0.0, atol=1e-12)
    vx, vy = rng.normal(size=(2, 50))
    cx, cy = world_to_carla_velocity(vx, vy)
    np.testing.assert_array_equal(cy, -vy)
    bx, by = carla_to_world_velocity(cx, cy)
    np.testing.assert_array_equal((bx, by), (vx, vy))
    # heading and velocity flip consistently: a velocity along the yaw stays along it
    speed = 3.0
    vx, vy = speed * np.cos(yaw), speed * np.sin(yaw)
    cx, cy = world_to_carla_velocity(vx, vy)
    cyaw = np.radians(yaw_to_carla_deg(yaw))
    np.testing.assert_allclose(cx, speed * np.cos(cyaw), atol=1e-12)
    np.testing.assert_allclose(cy, speed * np.sin(cyaw), atol=1e-12)


def test_wrap_deg_range():
    assert wrap_deg(180.0) == -180.0
    assert wrap_deg(-190.0) == 170.0
    assert wrap_deg(725.0) == 5.0


def test_pedals_from_command():
    assert command_to_pedals(0.4) == (0.4, 0.0)
    assert command_to_pedals(-0.25) == (0.0, 0.25)
    assert command_to_pedals(-3.0) == (0.0, 1.0)
    assert command_to_pedals(0.0) == (0.0, 0.0)


def test_pure_pursuit_signs_and_value():
    path = np.stack([np.linspace(0, 50, 501), np.zeros(501)], axis=1)
    # on the path, heading along it: no steering
    assert (
        pure_pursuit_steer(0.0, 0.0, 0.0, path, lookahead_m=5.0, wheelbase_m=2.8, max_steer_rad=0.6)
        == 0.0
    )
    # 1 m right of the path (y = -1): the target is to the left -> CARLA steers left (< 0)
    steer = pure_pursuit_steer(
        10.0, -1.0, 0.0, path, lookahead_m=5.0, wheelbase_m=2.8, max_steer_rad=0.6
    )
    # target: first point >= 5 m away from (10, -1): x = 10 + sqrt(24) rounded up to the grid
    tx = 10.0 + math.ceil(math.sqrt(24.0) / 0.1) * 0.1
    ld = math.hypot(tx - 10.0, 1.0)
    alpha = math.atan2(1.0, tx - 10.0)
    expected = -math.atan(2 * 2.8 * math.sin(alpha) / ld) / 0.6
    assert steer == pytest.approx(expected, rel=1e-9)
    assert steer < 0
    # saturates at +-1
    assert (
        pure_pursuit_steer(
            10.0, 30.0, 0.0, path, lookahead_m=5.0, wheelbase_m=2.8, max_steer_rad=0.1
        )
        == 1.0
    )


def test_escooter_default_blueprint_is_documented_bicycle():
    assert DEFAULT_BLUEPRINTS["escooter"] == "vehicle.diamondback.century"
    assert DEFAULT_BLUEPRINTS["ego"].startswith("vehicle.")


def test_conversion_agrees_with_carla_opendrive_parser(tmp_path):
    """CARLA's own client library loads an OpenDRIVE map offline: a lane point of the map,
    converted with our functions, is where CARLA puts that lane, heading as CARLA says."""
    carla = pytest.importorskip("carla")
    from scenariogeneration import xodr

    road = xodr.create_road(xodr.Line(200), id=0, left_lanes=1, right_lanes=1)
    odr = xodr.OpenDrive("straight")
    odr.add_road(road)
    odr.adjust_roads_and_lanes()
    path = tmp_path / "map.xodr"
    odr.write_xml(str(path))
    cmap = carla.Map("straight", path.read_text())
    # OpenDRIVE (= vei) frame: the right lane (id -1, 3 m wide) has its centre at y = -1.5
    # and is driven towards +x (yaw 0); the left lane (id 1) at y = +1.5 towards -x.
    for (x, y), lane_id, yaw in (((50.0, -1.5), -1, 0.0), ((80.0, 1.5), 1, math.pi)):
        cx, cy = world_to_carla_xy(x, y)
        wp = cmap.get_waypoint(
            carla.Location(x=float(cx), y=float(cy), z=0.0), project_to_road=True
        )
        assert wp.lane_id == lane_id
        loc = wp.transform.location
        bx, by = carla_to_world_xy(loc.x, loc.y)
        assert (float(bx), float(by)) == pytest.approx((x, y), abs=1e-3)
        got = carla_deg_to_yaw(wp.transform.rotation.yaw)
        assert abs(math.remainder(got - yaw, 2 * math.pi)) < 1e-6
