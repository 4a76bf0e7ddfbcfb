"""Fusion of perception and V2X per road user, against hand-computed values."""

from __future__ import annotations

import numpy as np
import pytest

from vei.policy.observation import SOURCE_BOTH, SOURCE_NONE, SOURCE_SENSOR, SOURCE_V2X
from vei.policy.v2x.fusion import fuse
from vei.policy.v2x.model import V2XObjects


def case(sensor_valid, v2x_valid, v2x_std=2.0):
    """One variant, road users [rider (sender), van]; the rider seen at (10, 0) moving at
    (0, 3), heard at (12, 1) moving (0, 2)."""
    world = np.zeros((6, 1, 2))
    world[:, 0, 0] = [10.0, 0.0, 1.5, 0.0, 3.0, float(sensor_valid)]
    world[:, 0, 1] = [20.0, -2.0, 0.0, 0.0, 0.0, 1.0]
    valid = np.array([[sensor_valid, True]])
    age = np.array([[0.3 if sensor_valid else np.inf, 0.3]])
    objs = V2XObjects(
        valid=np.array([[v2x_valid]]), x_m=np.array([[12.0]]), y_m=np.array([[1.0]]),
        vx_mps=np.array([[0.0]]), vy_mps=np.array([[2.0]]), yaw_rad=np.array([[1.2]]),
        age_s=np.array([[0.1]]), std_m=np.array([[v2x_std]]),
    )  # fmt: skip
    return world, valid, age, objs


def test_sensor_and_v2x_are_averaged_by_inverse_variance():
    world, valid, age, objs = case(True, True, v2x_std=2.0)
    out, val, a, src, std = fuse(world, valid, age, 1.0, objs, [0])
    # weights 1/1 and 1/4: x = (10 * 1 + 12 * 0.25) / 1.25 = 10.4, y = 0.25 / 1.25 = 0.2
    assert out[0, 0, 0] == pytest.approx(10.4) and out[1, 0, 0] == pytest.approx(0.2)
    assert out[3:5, 0, 0].tolist() == [0.0, 3.0] and out[2, 0, 0] == 1.5  # the sensor's
    assert std[0, 0] == pytest.approx((1 / (1 + 0.25)) ** 0.5)
    assert a[0, 0] == 0.1 and src[0].tolist() == [SOURCE_BOTH, SOURCE_SENSOR]
    assert val.all() and std[0, 1] == 1.0
    np.testing.assert_array_equal(out[:, 0, 1], world[:, 0, 1])  # the van untouched


def test_a_noiseless_sensor_wins_and_v2x_alone_is_the_track():
    world, valid, age, objs = case(True, True)
    out, *_ = fuse(world, valid, age, 0.0, objs, [0])
    assert out[0:2, 0, 0].tolist() == [10.0, 0.0]
    world, valid, age, objs = case(False, True)
    out, val, a, src, std = fuse(world, valid, age, 0.0, objs, [0])
    assert out[:, 0, 0].tolist() == [12.0, 1.0, 1.2, 0.0, 2.0, 1.0]
    assert val[0, 0] and a[0, 0] == 0.1 and src[0, 0] == SOURCE_V2X and std[0, 0] == 2.0
    world, valid, age, objs = case(False, False)
    out, val, a, src, std = fuse(world, valid, age, 0.0, objs, [0])
    assert not val[0, 0] and src[0, 0] == SOURCE_NONE and np.isinf(std[0, 0])
