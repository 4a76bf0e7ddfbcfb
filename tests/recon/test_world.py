import math
from datetime import UTC, datetime

import numpy as np
import pandas as pd
import pytest
from pyproj import Geod

from vei.errors import InputError
from vei.geo.frame import LocalFrame
from vei.recon.world import annotations_to_world, ego_track, lateral_to_left
from vei.types import Interaction, InteractionMeta

FRAME = LocalFrame(48.7665, 11.4334)
GEOD = Geod(ellps="WGS84")


def _ego(bearing_deg=90.0, speed_mps=5.0, heading=True, n=31):
    """Ego from the frame origin on a straight geodesic, 10 Hz."""
    t = np.arange(n) / 10.0
    lon, lat, _ = GEOD.fwd(
        np.full(n, FRAME.origin_lon_deg),
        np.full(n, FRAME.origin_lat_deg),
        np.full(n, bearing_deg),
        speed_mps * t,
    )
    return pd.DataFrame(
        {
            "t_s": t,
            "lat_deg": lat,
            "lon_deg": lon,
            "heading_deg": np.full(n, bearing_deg) if heading else np.full(n, np.nan),
            "speed_mps": np.full(n, speed_mps),
        }
    )


def _interaction(ego, ann, y_axis="left"):
    meta = InteractionMeta("t", "test", datetime(2021, 2, 9, 12, tzinfo=UTC), y_axis=y_axis)
    return Interaction(meta, ego, ann)


def _ann(x, y, yaw=np.nan, t=0.0):
    return pd.DataFrame(
        {
            "t_s": [t],
            "track_id": ["1"],
            "category": ["escooter"],
            "x_m": [x],
            "y_m": [y],
            "yaw_deg": [yaw],
            "length_m": [np.nan],
            "width_m": [np.nan],
        }
    )


def test_y_axis_flip_hand_case():
    # Ego at the origin heading east. 10 m forward, 4 m to the RIGHT declared as y=+4 with
    # y_axis='right' is world (10, -4); with y_axis='left' it is (10, +4).
    ego = _ego(90.0)
    right = annotations_to_world(
        _interaction(ego, _ann(10.0, 4.0, yaw=30.0), "right"),
        ego_track(_interaction(ego, _ann(0, 0)), FRAME),
    )
    left = annotations_to_world(
        _interaction(ego, _ann(10.0, 4.0, yaw=30.0), "left"),
        ego_track(_interaction(ego, _ann(0, 0)), FRAME),
    )
    assert (right["x_m"].iloc[0], right["y_m"].iloc[0]) == pytest.approx((10.0, -4.0), abs=2e-3)
    assert (left["x_m"].iloc[0], left["y_m"].iloc[0]) == pytest.approx((10.0, 4.0), abs=2e-3)
    # Relative yaw 30 deg towards +y: right of an east-heading car is -30 deg, left +30 deg.
    assert math.degrees(right["yaw_rad"].iloc[0]) == pytest.approx(-30.0, abs=1e-3)
    assert math.degrees(left["yaw_rad"].iloc[0]) == pytest.approx(30.0, abs=1e-3)


def test_y_axis_flip_is_a_pure_negation():
    assert lateral_to_left([1.0, -2.0], "right") == pytest.approx([-1.0, 2.0])
    assert lateral_to_left([1.0, -2.0], "left") == pytest.approx([1.0, -2.0])
    with pytest.raises(InputError, match="y_axis"):
        lateral_to_left([1.0], "up")


def test_moving_ego_heading_north_west():
    # Ego on bearing 315 deg at 5 m/s; at t = 2 s it is 10 m along; an object 6 m ahead
    # and 0 m lateral is 16 m from the start along 315 deg: (-16/sqrt2, 16/sqrt2).
    ego = _ego(315.0)
    inter = _interaction(ego, _ann(6.0, 0.0, t=2.0))
    world = annotations_to_world(inter, ego_track(inter, FRAME))
    s = 16.0 / math.sqrt(2)
    assert (world["x_m"].iloc[0], world["y_m"].iloc[0]) == pytest.approx((-s, s), abs=5e-3)
    assert (world["ego_x_m"].iloc[0], world["ego_y_m"].iloc[0]) == pytest.approx(
        (-10 / math.sqrt(2), 10 / math.sqrt(2)), abs=5e-3
    )


def test_heading_from_course_when_gps_has_none():
    with_heading = _interaction(_ego(60.0), _ann(8.0, -3.0, t=1.55))
    without = _interaction(_ego(60.0, heading=False), _ann(8.0, -3.0, t=1.55))
    a = ego_track(with_heading, FRAME)
    b = ego_track(without, FRAME)
    assert a.heading_source == "gps"
    assert b.heading_source == "course"
    assert b.bearing(np.array([0.0, 1.55, 3.0])) == pytest.approx([60.0, 60.0, 60.0], abs=1e-3)
    wa = annotations_to_world(with_heading, a)
    wb = annotations_to_world(without, b)
    assert wb[["x_m", "y_m"]].to_numpy() == pytest.approx(wa[["x_m", "y_m"]].to_numpy(), abs=1e-4)
    # The plane yaw of bearing 60 deg is 30 deg (minus the tiny meridian convergence here).
    assert math.degrees(float(a.yaw([1.0])[0])) == pytest.approx(30.0, abs=0.01)


def test_heading_interpolates_on_the_circle():
    ego = _ego(90.0)
    ego["heading_deg"] = np.where(ego["t_s"] < 1.0, 359.0, 1.0)  # wraps between 0.9 and 1.0 s
    track = ego_track(_interaction(ego, _ann(1, 1)), FRAME)
    mid = float(track.bearing([0.95])[0])
    assert min(mid, 360.0 - mid) == pytest.approx(0.0, abs=1e-9)  # through north, not south


def test_standing_ego_without_heading_is_an_error():
    ego = _ego(90.0, speed_mps=0.0, heading=False)
    with pytest.raises(InputError, match="heading"):
        ego_track(_interaction(ego, _ann(1, 1)), FRAME)


def test_course_held_through_a_stop():
    # Drives north 1 s, stands 1 s, drives north again: the standing part keeps bearing 0.
    t = np.arange(31) / 10.0
    dist = np.concatenate([5.0 * t[:11], np.full(10, 5.0), 5.0 + 5.0 * (t[21:] - 2.0)])
    lon, lat, _ = GEOD.fwd(
        np.full(31, FRAME.origin_lon_deg), np.full(31, FRAME.origin_lat_deg), np.zeros(31), dist
    )
    ego = pd.DataFrame(
        {"t_s": t, "lat_deg": lat, "lon_deg": lon, "heading_deg": np.nan, "speed_mps": np.nan}
    )
    track = ego_track(_interaction(ego, _ann(1, 1)), FRAME)
    b = track.bearing(t)
    assert np.minimum(b, 360 - b).max() < 1.0
