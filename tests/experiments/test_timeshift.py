"""Automatic time shift on constructed crossings with known answers."""

from __future__ import annotations

import numpy as np
import pytest

from vei.config import CaseConfig, EgoConfig, SimConfig
from vei.errors import InputError
from vei.sim.engine import run_cases
from vei.sim.testing import crossing_scenario
from vei.sim.timeshift import find_time_shift, parse_time_shift


def test_finds_the_meeting_on_the_default_crossing() -> None:
    sc = crossing_scenario()
    res = find_time_shift(sc)
    # Ego front (centre + 2.35 m) reaches x = 60 at (60 - 2.35) / 5.6 = 10.2946 s; the
    # recorded rider crosses y = 0 at 2 + 15 / 4.4 = 5.4091 s.
    expected = (60.0 - 2.35) / 5.6 - (2.0 + 15.0 / 4.4)
    assert res.time_shift_s == pytest.approx(expected, abs=2e-3)
    assert float(res) == res.time_shift_s
    assert res.miss_distance_m < 0.02
    assert res.meet_time_s == pytest.approx((60.0 - 2.35) / 5.6, abs=0.01)
    assert (res.meet_x_m, res.meet_y_m) == pytest.approx((60.0, 0.0), abs=0.02)
    assert res.cruise_speed_mps == pytest.approx(5.6)
    # Under this shift the replay configuration hits the rider head-on.
    r = run_cases(sc, ["replay"], time_shift_s=res.time_shift_s)
    assert bool(r.collision[0])
    assert r.collision_time_s[0] == pytest.approx(res.meet_time_s - (0.3 + 0.0) / 5.6, abs=0.1)


def test_other_geometry_and_negative_shift() -> None:
    # Faster ego (8 m/s), slower rider (3 m/s) crossing at x = 30 from y = -9, starting at
    # t = 6 s: it crosses y = 0 at 9 s, the ego front reaches x = 30 at 27.65 / 8 = 3.456 s,
    # so the rider must come 5.544 s earlier (negative shift).
    sc = crossing_scenario(
        ego_speed_mps=8.0,
        rider_speed_mps=3.0,
        crossing_x_m=30.0,
        rider_y0_m=-9.0,
        rider_y1_m=9.0,
        rider_t0_s=6.0,
    )
    plain = CaseConfig(name="replay", ego=EgoConfig(run_up_m=0.0))
    res = find_time_shift(sc, case=plain)
    assert res.time_shift_s == pytest.approx(27.65 / 8.0 - 9.0, abs=2e-3)
    assert res.time_shift_s < 0


def test_auto_run_up_gives_the_ego_its_approach_time() -> None:
    # Same crossing: the conflict point lies 30 m along the ego path, but at 8 m/s the
    # default approach time of 6 s needs 48 m, so 'auto' starts the ego 18 m earlier and
    # the meeting moves 18 / 8 s later.
    sc = crossing_scenario(
        ego_speed_mps=8.0,
        rider_speed_mps=3.0,
        crossing_x_m=30.0,
        rider_y0_m=-9.0,
        rider_y1_m=9.0,
        rider_t0_s=6.0,
    )
    res = find_time_shift(sc)
    assert res.time_shift_s == pytest.approx((27.65 + 18.0) / 8.0 - 9.0, abs=2e-3)
    r = run_cases(sc, ["replay", "normal-cap"], time_shift_s=res.time_shift_s)
    assert r.ego_x_m[:, 0] == pytest.approx([-18.0, -18.0])
    assert bool(r.collision[0]) and not bool(r.collision[1])
    # The paper's case (conflict 60 m ahead at 5.6 m/s: 33.6 m needed) gets no run-up.
    assert run_cases(crossing_scenario(), ["replay"]).ego_x_m[0, 0] == pytest.approx(0.0)


def test_ego_motion_is_the_replay_configuration() -> None:
    # A different cruise speed moves the meeting: front reaches x = 60 at 57.65 / 7.
    sc = crossing_scenario()
    case = CaseConfig(name="replay", ego=EgoConfig(cruise_speed_mps=7.0))
    res = find_time_shift(sc, case=case, sim=SimConfig())
    assert res.time_shift_s == pytest.approx(57.65 / 7.0 - (2.0 + 15.0 / 4.4), abs=2e-3)
    assert res.cruise_speed_mps == 7.0


def test_search_range_and_parse() -> None:
    sc = crossing_scenario()
    res = find_time_shift(sc, search_range_s=(-5.0, 2.0))
    # The best shift within [-5, 2] is the upper end (closest to the true 4.89).
    assert res.time_shift_s == pytest.approx(2.0, abs=1e-9)
    assert res.miss_distance_m > 5.0
    with pytest.raises(InputError):
        find_time_shift(sc, search_range_s=(3.0, 1.0))
    assert parse_time_shift("auto") == "auto"
    assert parse_time_shift(" 2.5 ") == 2.5
    assert parse_time_shift(-1) == -1.0
    for bad in ("soon", "nan", "inf"):
        with pytest.raises(InputError):
            parse_time_shift(bad)
    assert np.isfinite(res.as_dict()["meet_time_s"])


def test_run_up_moves_the_meeting_later() -> None:
    # Starting 20 m before the recorded start adds 20 / 5.6 s to the ego's arrival.
    sc = crossing_scenario()
    case = CaseConfig(name="replay", ego=EgoConfig(run_up_m=20.0))
    res = find_time_shift(sc, case=case)
    assert res.time_shift_s == pytest.approx(77.65 / 5.6 - (2.0 + 15.0 / 4.4), abs=2e-3)
    r = run_cases(sc, [case], time_shift_s=res.time_shift_s)
    assert r.ego_x_m[0, 0] == pytest.approx(-20.0)
    assert bool(r.collision[0])


def test_a_given_shift_is_evaluated_and_one_that_keeps_the_rider_out_is_refused() -> None:
    from vei.sim.timeshift import evaluate_time_shift

    sc = crossing_scenario()
    auto = find_time_shift(sc)
    assert auto.paths_meet and auto.meet_tolerance_m == pytest.approx(0.5 * (1.85 + 0.6))
    given = evaluate_time_shift(sc, auto.time_shift_s)
    assert given.miss_distance_m == pytest.approx(auto.miss_distance_m, abs=0.05)
    assert given.search_min_s == given.search_max_s == auto.time_shift_s
    # One second later the rider is 4.4 m short of the crossing when the ego's front is
    # there; the closest approach of the two is then a few metres: not meeting.
    late = evaluate_time_shift(sc, auto.time_shift_s + 1.0)
    assert not late.paths_meet and late.miss_distance_m > 2.0
    assert "NOT CRITICAL" in late.message() and f"{late.miss_distance_m:.2f} m" in late.message()
    # The rider's recording spans [2, 2 + 30 / 4.4] s; the run [0, 25] s.
    with pytest.raises(InputError, match=r"keeps rider .* out of the run.*\[2\.00, 8\.80\] s"):
        evaluate_time_shift(sc, 1000.0)


def test_paths_that_never_meet_are_reported_with_the_miss_distance() -> None:
    # The rider (4 m/s, last sample at y = -3 exactly) stops 3 m short of the ego's line: the best any shift can do
    # is a miss of 3 m between its centre and the ego's front centre.
    sc = crossing_scenario(rider_y1_m=-3.0, rider_speed_mps=4.0)
    res = find_time_shift(sc)
    assert res.miss_distance_m == pytest.approx(3.0, abs=0.01)
    assert not res.paths_meet
    assert res.message().startswith("NOT CRITICAL") and "3.00 m" in res.message()
    assert res.as_dict()["paths_meet"] is False
