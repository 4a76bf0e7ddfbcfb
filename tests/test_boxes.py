"""vei.boxes: oriented boxes, separating-axis overlap, closest point, gap (hand-computed cases)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from vei.boxes import (
    box_corners,
    box_gap,
    boxes_overlap,
    closest_point_on_box,
    corners_overlap,
    time_to_contact,
)


def test_corners_of_rotated_box() -> None:
    c = box_corners(1.0, 2.0, math.pi / 2, 4.0, 2.0)
    # Heading +y: rear-right = centre - 2 (heading) + 1 (right = +x).
    assert c == pytest.approx(np.array([[2.0, 0.0], [2.0, 4.0], [0.0, 4.0], [0.0, 0.0]]), abs=1e-12)


def test_axis_aligned_apart_touching_overlapping() -> None:
    # A: 4 x 2 at the origin, B: 2 x 2 to its right at centre x.
    xs = np.array([4.0, 3.0, 2.5])  # gap 1 m, touching, overlapping by 0.5 m
    ov = boxes_overlap(0.0, 0.0, 0.0, 4.0, 2.0, xs, 0.0, 0.0, 2.0, 2.0)
    assert ov.tolist() == [False, True, True]
    gap = box_gap(0.0, 0.0, 0.0, 4.0, 2.0, xs, 0.0, 0.0, 2.0, 2.0)
    assert gap == pytest.approx([1.0, 0.0, 0.0], abs=1e-12)


def test_rotated_thin_box_near_corner_is_apart_although_bounding_boxes_overlap() -> None:
    # A: 2 x 2 square at the origin. B: 4 x 0.2 bar centred at (2, 2), heading -45 deg.
    # B's axis-aligned bounding box overlaps A, but the bar's centre line is sqrt(2) from
    # A's corner (1, 1): gap = sqrt(2) - 0.1.
    ov = boxes_overlap(0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2.0, -math.pi / 4, 4.0, 0.2)
    assert not bool(ov)
    gap = box_gap(0.0, 0.0, 0.0, 2.0, 2.0, 2.0, 2.0, -math.pi / 4, 4.0, 0.2)
    assert float(gap) == pytest.approx(math.sqrt(2) - 0.1, abs=1e-9)
    # Moved towards A along the diagonal until it cuts the corner: overlap.
    d = 2.0 - (math.sqrt(2) - 0.05) / math.sqrt(2)  # centre so that the line passes 0.05 m inside
    assert bool(boxes_overlap(0.0, 0.0, 0.0, 2.0, 2.0, d, d, -math.pi / 4, 4.0, 0.2))


def test_rotated_boxes_touching_corner_to_edge() -> None:
    # B: unit square rotated 45 deg whose left corner touches A's right edge (x = 1).
    h = math.sqrt(2) / 2
    assert bool(boxes_overlap(0.0, 0.0, 0.0, 2.0, 2.0, 1.0 + h, 0.0, math.pi / 4, 1.0, 1.0))
    assert not bool(
        boxes_overlap(0.0, 0.0, 0.0, 2.0, 2.0, 1.0 + h + 1e-6, 0.0, math.pi / 4, 1.0, 1.0)
    )
    assert float(
        box_gap(0.0, 0.0, 0.0, 2.0, 2.0, 1.1 + h, 0.0, math.pi / 4, 1.0, 1.0)
    ) == pytest.approx(0.1, abs=1e-9)


def test_overlap_is_symmetric_and_batched() -> None:
    rng = np.random.default_rng(0)
    n = 500
    a = (rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), rng.uniform(-4, 4, n), 4.7, 1.85)
    b = (rng.uniform(-3, 3, n), rng.uniform(-3, 3, n), rng.uniform(-4, 4, n), 1.2, 0.6)
    ab = boxes_overlap(*a, *b)
    ba = boxes_overlap(*b, *a)
    assert ab.shape == (n,)
    assert np.array_equal(ab, ba)
    # Consistent with the exact gap: overlap <=> gap == 0.
    gap = box_gap(*a, *b)
    assert np.array_equal(ab, gap == 0.0)
    assert ab.any() and (~ab).any()


def test_closest_point_on_box() -> None:
    qx, qy = closest_point_on_box(
        np.array([3.0, 0.5, -5.0]), np.array([0.5, 0.2, 4.0]), 0.0, 0.0, 0.0, 2.0, 1.0
    )
    assert qx == pytest.approx([1.0, 0.5, -1.0])
    assert qy == pytest.approx([0.5, 0.2, 0.5])
    # Rotated 90 deg: length along y.
    qx, qy = closest_point_on_box(3.0, 0.0, 0.0, 0.0, math.pi / 2, 2.0, 1.0)
    assert (float(qx), float(qy)) == pytest.approx((0.5, 0.0))


def _brute_force_gap(a, b):
    """Reference: min corner-to-edge distance over both boxes' corners (0 on overlap)."""

    def seg(p, q0, q1):
        d = q1 - q0
        t = np.clip(np.sum((p - q0) * d, -1) / np.sum(d * d, -1), 0.0, 1.0)
        return np.linalg.norm(p - (q0 + t[..., None] * d), axis=-1)

    ca, cb = box_corners(*a), box_corners(*b)
    best = np.full(ca.shape[:-2], np.inf)
    for p, q in ((ca, cb), (cb, ca)):
        for i in range(4):
            for j in range(4):
                best = np.minimum(best, seg(p[..., i, :], q[..., j, :], q[..., (j + 1) % 4, :]))
    return np.where(boxes_overlap(*a, *b), 0.0, best)


def test_box_gap_equals_the_brute_force_corner_to_edge_distance() -> None:
    rng = np.random.default_rng(4)
    n = 5000
    ax, ay, bx, by = rng.uniform(-4, 4, (4, n))
    ayaw, byaw = rng.uniform(-4, 4, (2, n))
    a, b = (ax, ay, ayaw, 4.7, 1.85), (bx, by, byaw, 1.2, 0.6)
    ref = _brute_force_gap(a, b)
    assert 0.05 < (ref == 0).mean() < 0.5  # both overlapping and apart cases
    assert box_gap(*a, *b) == pytest.approx(ref, abs=1e-12)


def test_the_two_forms_of_the_overlap_test_agree() -> None:
    """Corner sets (corners_overlap, the metrics' form) and components (boxes_overlap, the
    engine's form) give the same answer on random boxes, at least 1e-6 m from touching."""
    rng = np.random.default_rng(7)
    n = 5000
    ax, ay, bx, by = rng.uniform(-4, 4, (4, n))
    ayaw, byaw = rng.uniform(-4, 4, (2, n))
    a, b = (ax, ay, ayaw, 4.7, 1.85), (bx, by, byaw, 1.2, 0.6)
    clear = box_gap(*a, *b) > 1e-6
    touching = ~clear & ~boxes_overlap(*a, *b)  # gap 0 but SAT apart: none expected
    assert not touching.any()
    by_corners = corners_overlap(box_corners(*a), box_corners(*b))
    assert 0.05 < by_corners.mean() < 0.5
    assert (by_corners == boxes_overlap(*a, *b)).all()
    assert (by_corners == ~clear).all()


def test_time_to_contact_is_the_gap_over_the_closing_speed_head_on() -> None:
    """B (1 x 1) straight ahead of A (4 x 2), closing at 10 m/s along x: the time is the
    gap over the speed (hand: gap = 17.5 - 2 - 0.5 = 15 m -> 1.5 s); receding -> inf."""
    ca = box_corners(0.0, 0.0, 0.0, 4.0, 2.0)
    cb = box_corners(17.5, 0.0, 0.0, 1.0, 1.0)
    assert float(box_gap(0.0, 0.0, 0.0, 4.0, 2.0, 17.5, 0.0, 0.0, 1.0, 1.0)) == pytest.approx(15.0)
    assert float(time_to_contact(ca, cb, np.array([-10.0, 0.0]))) == pytest.approx(1.5)
    assert math.isinf(float(time_to_contact(ca, cb, np.array([10.0, 0.0]))))
    assert float(time_to_contact(ca, ca, np.array([1.0, 0.0]))) == 0.0  # overlapping
