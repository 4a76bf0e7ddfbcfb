import math

import numpy as np
import pytest

from vei.errors import InputError
from vei.geo.frame import Bounds, LocalFrame, wrap_angle

INGOLSTADT = LocalFrame(48.7665, 11.4334)


def test_origin_maps_to_zero_and_back():
    x, y = INGOLSTADT.to_xy(48.7665, 11.4334)
    assert float(x) == pytest.approx(0.0, abs=1e-6)
    assert float(y) == pytest.approx(0.0, abs=1e-6)
    lat, lon = INGOLSTADT.to_latlon(123.4, -56.7)
    x2, y2 = INGOLSTADT.to_xy(lat, lon)
    assert float(x2) == pytest.approx(123.4, abs=1e-6)
    assert float(y2) == pytest.approx(-56.7, abs=1e-6)


def test_one_arcsecond_of_latitude_is_about_30_9_m_north():
    # Meridian arc per degree at 48.77 deg on WGS84: 111,200 m (hand value from the
    # series M = 111132.954 - 559.822 cos 2phi + 1.175 cos 4phi).
    phi = math.radians(48.7665)
    per_deg = 111132.954 - 559.822 * math.cos(2 * phi) + 1.175 * math.cos(4 * phi)
    x, y = INGOLSTADT.to_xy(48.7665 + 1 / 3600, 11.4334)
    assert float(x) == pytest.approx(0.0, abs=1e-6)
    assert float(y) == pytest.approx(per_deg / 3600, rel=1e-4)


def test_ego_relative_forward_east_heading():
    # Ego at origin heading due east (90 deg): 10 m forward is +x, 4 m left is +y (north).
    x, y = INGOLSTADT.ego_relative_to_world(48.7665, 11.4334, 90.0, 10.0, 4.0)
    assert float(x) == pytest.approx(10.0, abs=2e-3)
    assert float(y) == pytest.approx(4.0, abs=2e-3)


def test_ego_relative_heading_north_and_southwest():
    # Heading north: forward is +y, left is -x.
    x, y = INGOLSTADT.ego_relative_to_world(48.7665, 11.4334, 0.0, 3.0, 2.0)
    assert (float(x), float(y)) == pytest.approx((-2.0, 3.0), abs=2e-3)
    # Heading 225 deg (south-west): forward (1,0) -> (-1,-1)/sqrt2 * 20 m.
    x, y = INGOLSTADT.ego_relative_to_world(48.7665, 11.4334, 225.0, 20.0, 0.0)
    assert (float(x), float(y)) == pytest.approx((-20 / math.sqrt(2), -20 / math.sqrt(2)), abs=5e-3)


def test_bearing_yaw_round_trip_and_convergence():
    # Away from the central meridian grid north differs from true north by the meridian
    # convergence gamma ~= dlon * sin(lat); at 0.01 deg east that is 0.01*sin(48.77) deg.
    lat, lon = 48.7665, 11.4434
    yaw_north = INGOLSTADT.bearing_to_yaw(0.0, lat, lon)
    gamma_deg = 0.01 * math.sin(math.radians(lat))
    assert math.degrees(float(yaw_north)) == pytest.approx(90.0 + gamma_deg, abs=2e-4)
    bearings = np.array([0.0, 45.0, 179.0, 181.0, 359.5])
    x, y = INGOLSTADT.to_xy(lat, lon)
    yaw = INGOLSTADT.bearing_to_yaw(bearings, lat, lon)
    back = INGOLSTADT.yaw_to_bearing(yaw, x, y)
    assert back == pytest.approx(bearings, abs=1e-6)


def test_proj_string_round_trip_and_rejects_other_projections():
    assert LocalFrame.from_proj_string(INGOLSTADT.proj_string) == INGOLSTADT
    with pytest.raises(InputError, match="tmerc"):
        LocalFrame.from_proj_string("+proj=utm +zone=32 +ellps=WGS84")
    with pytest.raises(InputError, match="k=0.9996"):
        LocalFrame.from_proj_string("+proj=tmerc +lat_0=1 +lon_0=2 +k=0.9996")
    with pytest.raises(InputError, match="latitude"):
        LocalFrame(91.0, 0.0)


def test_wrap_angle():
    assert wrap_angle(np.array([3 * math.pi, -math.pi, 0.5])) == pytest.approx(
        [math.pi, math.pi, 0.5]
    )


def test_bounds_margin():
    b = Bounds.around([48.0, 48.001], [11.0, 11.002], margin_m=111.132)
    assert b.south_deg == pytest.approx(48.0 - 0.001, abs=1e-9)
    assert b.north_deg == pytest.approx(48.001 + 0.001, abs=1e-9)
    assert b.west_deg < 11.0 - 0.0014
    assert Bounds.from_dict(b.as_dict()) == b
    with pytest.raises(InputError):
        Bounds.around([float("nan")], [float("nan")])
