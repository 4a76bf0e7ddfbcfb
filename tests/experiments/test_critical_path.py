"""--make-critical timing+path on constructed crossings with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from vei.errors import ConfigError
from vei.experiments.critical_path import (
    PathSearch,
    find_path_perturbation,
    make_critical,
    transform_xy_yaw,
)
from vei.sim.engine import run_cases
from vei.sim.testing import crossing_scenario


def test_a_rider_stopping_short_is_moved_onto_the_ego_path_by_the_smallest_offset() -> None:
    # The rider rides north along x = 60 and stops at y = -3 (3 m short of the ego's line
    # y = 0). The smallest offset towards the ego path that brings it within 0.2 m is
    # 2.8 m (grid 0.05 m), along +y: longitudinal for this rider, no lateral part.
    sc = crossing_scenario(rider_y1_m=-3.0, rider_speed_mps=4.0)
    pert, moved, shift = find_path_perturbation(sc)
    assert pert.kind == "offset"
    assert pert.path_distance_m == pytest.approx(3.0, abs=0.01)
    assert pert.offset_m == pytest.approx(2.8, abs=1e-6)
    assert (pert.dir_x, pert.dir_y) == pytest.approx((0.0, 1.0), abs=1e-3)
    assert pert.longitudinal_m == pytest.approx(2.8, abs=1e-3)
    assert pert.lateral_m == pytest.approx(0.0, abs=1e-3)
    assert pert.size == pytest.approx(2.8 / pert.plausible_offset_m) and pert.plausible
    rider = sc.primary_threat
    before = sc.track(rider)
    after = moved.track(rider)
    assert after["y_m"].to_numpy() == pytest.approx(before["y_m"].to_numpy() + 2.8)
    assert after["x_m"].to_numpy() == pytest.approx(before["x_m"].to_numpy())
    assert moved.extra["criticality"]["perturbation"]["kind"] == "offset"
    # On the changed path the time shift meets, and replay collides.
    assert shift.paths_meet and shift.miss_distance_m < 0.25
    r = run_cases(moved, ["replay"], time_shift_s=shift.time_shift_s)
    assert bool(r.collision[0])


def test_a_meeting_recording_needs_no_change_and_modes_are_checked() -> None:
    sc = crossing_scenario()
    pert, moved, shift = find_path_perturbation(sc)
    assert pert.kind == "none" and pert.size == 0.0 and moved is sc and shift.paths_meet
    scen, tau, info, crit = make_critical(sc, mode="timing")
    assert crit["paths_meet"] and crit["perturbation"] is None and info["mode"] == "auto"
    with pytest.raises(ConfigError, match="timing\\+path"):
        make_critical(sc, mode="timing+path", time_shift=2.0)
    with pytest.raises(ConfigError, match="--make-critical"):
        make_critical(sc, mode="path")
    with pytest.raises(Exception, match="tolerance_m"):
        PathSearch(tolerance_m=0.0)


def test_rotation_about_the_pivot_hand_values() -> None:
    x, y, yaw = transform_xy_yaw(
        np.array([1.0, 2.0]), np.array([0.0, 0.0]), np.zeros(2),
        pivot=(1.0, 0.0), rotation_rad=np.pi / 2, shift=(0.5, 0.0),
    )  # fmt: skip
    assert x == pytest.approx([1.5, 1.5]) and y == pytest.approx([0.0, 1.0])
    assert yaw == pytest.approx([np.pi / 2, np.pi / 2])
