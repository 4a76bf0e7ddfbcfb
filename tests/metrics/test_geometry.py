import math

import numpy as np
import pytest

from vei.boxes import box_gap as _box_gap
from vei.metrics.geometry import box_corners, boxes_overlap, time_to_contact


def box_gap(corners_a, corners_b):
    """The single box gap of vei, called with the centre/heading/size of corner sets."""

    def parts(c):
        centre = c.mean(axis=-2)
        length = np.linalg.norm(c[..., 1, :] - c[..., 0, :], axis=-1)
        width = np.linalg.norm(c[..., 2, :] - c[..., 1, :], axis=-1)
        front = c[..., 1, :] - c[..., 0, :]
        return (
            centre[..., 0],
            centre[..., 1],
            np.arctan2(front[..., 1], front[..., 0]),
            length,
            width,
        )

    return _box_gap(*parts(corners_a), *parts(corners_b))


def test_corners_counter_clockwise_from_rear_right():
    c = box_corners([1.0, 2.0], 0.0, 4.0, 2.0)
    assert c.tolist() == [[-1.0, 1.0], [3.0, 1.0], [3.0, 3.0], [-1.0, 3.0]]
    r = box_corners([0.0, 0.0], math.pi / 2, 4.0, 2.0)
    # heading north: front (+2) is +y, right (-1 across) is +x
    assert r[1] == pytest.approx([1.0, 2.0])
    assert r[3] == pytest.approx([-1.0, -2.0])


def test_axis_aligned_gap_and_overlap():
    a = box_corners([0.0, 0.0], 0.0, 4.0, 2.0)
    b = box_corners([5.0, 0.0], 0.0, 1.0, 1.0)
    assert float(box_gap(a, b)) == pytest.approx(2.5)
    assert not bool(boxes_overlap(a, b))


def test_corner_to_corner_gap():
    a = box_corners([0.0, 0.0], 0.0, 4.0, 2.0)
    b = box_corners([5.0, 4.0], 0.0, 1.0, 1.0)
    assert float(box_gap(a, b)) == pytest.approx(math.hypot(2.5, 2.5))


def test_rotated_box_gap():
    a = box_corners([0.0, 0.0], math.pi / 4, 2.0, 2.0)  # diamond reaching x = sqrt(2)
    b = box_corners([3.0, 0.0], 0.0, 1.0, 1.0)
    assert float(box_gap(a, b)) == pytest.approx(2.5 - math.sqrt(2))


def test_touching_counts_as_overlap_and_gap_zero():
    a = box_corners([0.0, 0.0], 0.0, 4.0, 2.0)
    b = box_corners([2.5, 0.0], 0.0, 1.0, 1.0)
    assert bool(boxes_overlap(a, b))
    assert float(box_gap(a, b)) == 0.0


def test_rotated_overlap_that_axis_aligned_bounds_would_miss():
    # A 45-degree diamond whose bounding square overlaps the other box, but the boxes do not.
    a = box_corners([0.0, 0.0], math.pi / 4, 2.0, 2.0)
    b = box_corners([1.2, 1.2], 0.0, 0.6, 0.6)
    assert not bool(boxes_overlap(a, b))
    # distance from the diamond's edge x + y = sqrt(2) to corner (0.9, 0.9)
    assert float(box_gap(a, b)) == pytest.approx((1.8 - math.sqrt(2)) / math.sqrt(2))
    c = box_corners([0.9, 0.9], 0.0, 0.6, 0.6)
    assert bool(boxes_overlap(a, c))


def test_time_to_contact_head_on_and_diamond():
    a = box_corners([0.0, 0.0], 0.0, 4.0, 2.0)
    b = box_corners([17.5, 0.0], 0.0, 1.0, 1.0)
    assert float(time_to_contact(a, b, np.array([-10.0, 0.0]))) == pytest.approx(1.5)
    d = box_corners([10.0, 0.0], math.pi / 4, 1.0, 1.0)
    assert float(time_to_contact(a, d, np.array([-5.0, 0.0]))) == pytest.approx(
        (8.0 - math.sqrt(0.5)) / 5.0
    )


def test_time_to_contact_miss_receding_and_overlap():
    a = box_corners([0.0, 0.0], 0.0, 4.0, 2.0)
    b = box_corners([10.0, 5.0], 0.0, 1.0, 1.0)
    assert math.isinf(float(time_to_contact(a, b, np.array([-10.0, 0.0]))))  # passes beside
    assert math.isinf(
        float(time_to_contact(a, box_corners([10.0, 0.0], 0.0, 1.0, 1.0), np.array([3.0, 0.0])))
    )
    assert (
        float(time_to_contact(a, box_corners([1.0, 0.0], 0.0, 1.0, 1.0), np.array([3.0, 0.0])))
        == 0.0
    )


def test_time_to_contact_crossing_from_the_side():
    # Axis-aligned boxes translating: contact is the first time both the x and the y
    # extents overlap. Other at (13.5, 8) moving (-20, -5) relative to the ego: x extents
    # overlap for t in [0.55, 0.8] s, y extents for t in [1.3, 1.9] s: never together.
    a = box_corners([0.0, 0.0], 0.0, 4.0, 2.0)
    b = box_corners([13.5, 8.0], 0.0, 1.0, 1.0)
    assert math.isinf(float(time_to_contact(a, b, np.array([-20.0, -5.0]))))
    # At (13.5, 8) moving (-10, -5): x overlap [1.1, 1.6] s, y overlap [1.3, 1.9] s -> 1.3 s.
    assert float(time_to_contact(a, b, np.array([-10.0, -5.0]))) == pytest.approx(1.3)
    # At (12.5, 5.5) moving (-10, -4): x overlap [1.0, 1.5], y overlap [1.0, 1.75] -> 1.0 s.
    c = box_corners([12.5, 5.5], 0.0, 1.0, 1.0)
    assert float(time_to_contact(a, c, np.array([-10.0, -4.0]))) == pytest.approx(1.0)
