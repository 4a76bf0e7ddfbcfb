import math

import numpy as np
import pytest

from vei.metrics.conflict import drac_series, gap_series, max_drac, min_gap, pet

from .helpers import make_trace


def test_min_gap_over_active_steps_only():
    other = [[12.5, 0.0], [8.5, 0.0], [5.0, 3.0], [4.5, 0.0]]
    tr = make_trace(
        ego_xy=[0.0, 0.0], other_xy=other, ego_speed=5.0, active=[True, True, True, False]
    )
    g = gap_series(tr)[0]
    assert g[:3] == pytest.approx([10.0, 6.0, math.hypot(2.5, 1.5)])
    assert math.isnan(g[3])
    assert min_gap(tr)[0] == pytest.approx(math.hypot(2.5, 1.5))


def test_drac_hand_values():
    # gap 20 m, ego 10 m/s: standing rider -> 100 / 40; rider at 4 m/s ahead -> 36 / 40
    standing = make_trace(ego_xy=[0.0, 0.0], other_xy=[22.5, 0.0], ego_speed=10.0)
    assert drac_series(standing)[0, 0] == pytest.approx(2.5)
    moving = make_trace(
        ego_xy=[0.0, 0.0], other_xy=[22.5, 0.0], ego_speed=10.0, other_vel=(4.0, 0.0)
    )
    assert max_drac(moving)[0] == pytest.approx(0.9)
    behind = make_trace(ego_xy=[0.0, 0.0], other_xy=[-22.5, 0.0], ego_speed=10.0)
    assert max_drac(behind)[0] == 0.0


def _crossing(other_start_y: float, collided=False):
    # Ego (4 m long) from x = -50 at 10 m/s along +x; other (1 m) along +y at 2 m/s from
    # (0, other_start_y); 101 steps of 0.1 s.
    t = np.arange(101) * 0.1
    ego = np.stack([-50.0 + 10.0 * t, 0.0 * t], axis=1)
    oth = np.stack([0.0 * t, other_start_y + 2.0 * t], axis=1)
    return make_trace(
        ego_xy=ego,
        other_xy=oth,
        ego_speed=10.0,
        other_yaw=math.pi / 2,
        other_vel=(0.0, 2.0),
        collided=collided,
    )


def test_pet_ego_first_then_rider():
    # ego occupies (0, 0) while its centre is within 2 m: t in [4.8, 5.2] s; the rider
    # (half length 0.5 m) from y = -16: t in [7.75, 8.25] s -> PET = 7.75 - 5.2
    assert pet(_crossing(-16.0))[0] == pytest.approx(2.55)


def test_pet_rider_first_then_ego():
    # rider from y = -6: occupies the point for t in [2.75, 3.25]; ego arrives at 4.8
    assert pet(_crossing(-6.0))[0] == pytest.approx(1.55)


def test_pet_zero_when_occupancies_overlap_or_collision_and_nan_without_crossing():
    assert pet(_crossing(-10.0))[0] == 0.0  # rider occupies [4.75, 5.25]
    assert pet(_crossing(-16.0, collided=True))[0] == 0.0
    parallel = make_trace(
        ego_xy=np.stack([np.arange(20.0), np.zeros(20)], 1),
        other_xy=np.stack([np.arange(20.0), np.full(20, 5.0)], 1),
        ego_speed=10.0,
    )
    assert math.isnan(pet(parallel)[0])
