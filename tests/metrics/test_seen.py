"""When was the other road user first seen, could the car have reacted, and the paper's
safety index on the relative-velocity TTC (vei.metrics.seen) on hand-built runs."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from tests.metrics.helpers import make_trace
from vei.metrics import MetricsConfig, get_metric, summarize
from vei.metrics.seen import flag_counts, flagged_mask

DT = 0.05
EGO = (4.7, 1.85)
RIDER = (1.2, 0.6)


def _values(trace, *names, params=None):
    row = summarize(trace, names=list(names), params=params)
    return [row[n].iloc[0] for n in names]


def _pass(clearance_m: float, *, ego_v: float, rider_v: float, ahead_m: float, seconds: float):
    """The car (ego_v east along y = 0) and a rider (rider_v east; negative = oncoming)
    whose box passes ``clearance_m`` to the car's left; the rider's centre starts
    ``ahead_m`` ahead of the car's."""
    n = int(round(seconds / DT)) + 1
    t = np.arange(n) * DT
    lateral = clearance_m + 0.5 * (EGO[1] + RIDER[1])
    ego = np.column_stack([ego_v * t, np.zeros(n)])
    rider = np.column_stack([ahead_m + rider_v * t, np.full(n, lateral)])
    return make_trace(
        ego_xy=ego, other_xy=rider, ego_speed=ego_v, other_vel=(rider_v, 0.0), dt=DT,
        ego_dims=EGO, other_dims=RIDER,
    )  # fmt: skip


def _paper_si_by_hand(clearance_m: float, *, ego_v: float, rider_v: float, ahead_m: float,
                      seconds: float) -> float:  # fmt: skip
    """The paper's index of :func:`_pass` from the geometry: a step is safe or attention
    when the rider is not ahead (centre x <= the car's), the car stands (TTC inf), or the
    box gap g gives g / v_ego > 1 s."""
    n = int(round(seconds / DT)) + 1
    t = np.arange(n) * DT
    dx = ahead_m + (rider_v - ego_v) * t
    half = 0.5 * (EGO[0] + RIDER[0])
    gap = np.hypot(np.maximum(np.abs(dx) - half, 0.0), clearance_m)
    ok = (dx <= 0.0) | (ego_v <= 1e-3) | (gap > ego_v * 1.0)
    return float(ok.sum() / n)


def test_overtake_and_pass_paper_index_and_relative_index() -> None:
    """Issue 28.7. A plain overtake (car 5.6 m/s, rider 4.4 m/s ahead, 2.9 m lateral
    clearance) keeps the rider ahead and within 5.6 m for most of the run: the paper's
    index (TTC = gap / v_ego) is 0.12; a rider passing a standing car at 1.0 m scores
    1.0 (TTC = inf while the car stands). The relative TTC is never finite in either
    (parallel courses never meet): safety_index_rel is 1.0 for both. It scores time on a
    collision course, not how close a pass comes (that is min_gap_m)."""
    overtake = {"ego_v": 5.6, "rider_v": 4.4, "ahead_m": 8.3, "seconds": 4.0}
    tr = _pass(2.9, **overtake)
    si, si_rel, ttc_rel, gap = _values(
        tr, "safety_index", "safety_index_rel", "min_ttc_rel_s", "min_gap_m"
    )
    assert si == pytest.approx(_paper_si_by_hand(2.9, **overtake), abs=1e-12)
    assert si == pytest.approx(0.12, abs=0.01)
    assert math.isinf(ttc_rel) and si_rel == 1.0
    assert gap == pytest.approx(math.hypot(8.3 - 1.2 * 4.0 - 0.5 * (EGO[0] + RIDER[0]), 2.9))
    passing = {"ego_v": 0.0, "rider_v": -4.0, "ahead_m": 16.0, "seconds": 8.0}
    tr = _pass(1.0, **passing)
    si, si_rel, gap = _values(tr, "safety_index", "safety_index_rel", "min_gap_m")
    assert si == _paper_si_by_hand(1.0, **passing) == 1.0
    assert si_rel == 1.0 and gap == pytest.approx(1.0)
    # the same pass with the car driving (5.6 m/s): the paper's index falls, the relative not
    moving = {**passing, "ego_v": 5.6}
    tr = _pass(1.0, **moving)
    si, si_rel = _values(tr, "safety_index", "safety_index_rel")
    assert si == pytest.approx(_paper_si_by_hand(1.0, **moving), abs=1e-12) and si < 0.9
    assert si_rel == 1.0


def test_standing_rider_ahead_both_indices_agree() -> None:
    """A rider standing in the lane 60 m ahead of a car at 8 m/s for 7 s (never reached):
    relative TTC = paper TTC = gap / 8, so the two indices are equal: the share of steps
    with gap > 8 m."""
    n = int(round(7.0 / DT)) + 1
    t = np.arange(n) * DT
    centre = 60.3 + 0.5 * (EGO[0] + RIDER[0])  # no step at TTC 1 s exactly
    tr = make_trace(ego_xy=np.column_stack([8.0 * t, np.zeros(n)]), other_xy=(centre, 0.0),
                    ego_speed=8.0, dt=DT, ego_dims=EGO, other_dims=RIDER)  # fmt: skip
    si, si_rel = _values(tr, "safety_index", "safety_index_rel")
    gap = 60.3 - 8.0 * t
    assert si == si_rel == pytest.approx((gap / 8.0 > 1.0).mean(), abs=1e-12)
    assert si < 1.0


def _appears(gap_m: float, *, ego_v=8.0, first=20, n=60, standing=True):
    """A rider standing in the car's lane that appears at step ``first`` ``gap_m`` ahead
    of the car's front; the car drives on at ego_v (boxes aligned)."""
    t = np.arange(n) * DT
    ego = np.column_stack([ego_v * (t - t[first]), np.zeros(n)])
    centre = gap_m + 0.5 * (EGO[0] + RIDER[0])
    act = np.arange(n) >= first
    return make_trace(ego_xy=ego, other_xy=(centre, 0.0), ego_speed=ego_v, active=act, dt=DT,
                      ego_dims=EGO, other_dims=RIDER)  # fmt: skip


def test_first_seen_and_the_flag_by_hand() -> None:
    """Stopping distance at 8 m/s: 8 x 0.5 s + 64 / (2 x 8 m/s^2) = 8 m. A rider that
    appears 5 m ahead on course is flagged (TTC 5 / 8 = 0.625 s); one that appears 20 m
    ahead is not (TTC 2.5 s); with the car's brake at 4 m/s^2 (stop 12 m) neither is 12.5 m."""
    near = _appears(5.0)
    g, t, flag = _values(near, "first_seen_gap_m", "first_seen_ttc_s", "seen_too_late")
    assert g == pytest.approx(5.0) and t == pytest.approx(5.0 / 8.0) and flag
    far = _appears(20.0)
    g, t, flag = _values(far, "first_seen_gap_m", "first_seen_ttc_s", "seen_too_late")
    assert g == pytest.approx(20.0) and t == pytest.approx(2.5) and not flag
    mid = _appears(10.0)
    assert not _values(mid, "seen_too_late")[0]
    soft = {"ego_max_decel_mps2": 4.0}  # 8 x 0.5 + 64 / 8 = 12 m
    assert _values(mid, "seen_too_late", params=soft)[0]
    # a rider beside the car (not on course) is never flagged, however close
    side = make_trace(ego_xy=(0.0, 0.0), other_xy=(0.0, 3.0), ego_speed=8.0, other_vel=(8.0, 0.0),
                      dt=DT, ego_dims=EGO, other_dims=RIDER)  # fmt: skip
    g, t, flag = _values(side, "first_seen_gap_m", "first_seen_ttc_s", "seen_too_late")
    assert g == pytest.approx(3.0 - 0.5 * (EGO[1] + RIDER[1])) and math.isinf(t) and not flag
    # never present: NaN, not flagged
    none = make_trace(ego_xy=(0.0, 0.0), other_xy=(9.0, 0.0), ego_speed=8.0, active=False, dt=DT)
    g, t, flag = _values(none, "first_seen_gap_m", "first_seen_ttc_s", "seen_too_late")
    assert math.isnan(g) and math.isnan(t) and not flag


def test_contact_within_the_reaction_time_is_flagged() -> None:
    """Contact 0.4 s after the rider appears (reaction time 0.5 s): flagged, whatever the
    gap; contact at its first present step (no approach: impact speed NaN) too; contact
    1.0 s after: not by time (and 8 m gap at 8 m/s is not closer than the 8 m stop)."""
    n = 60
    for after, expect in ((8, True), (0, True), (20, False)):
        act = np.arange(n) >= 20
        coll = np.arange(n) >= 20 + after
        tr = make_trace(ego_xy=(0.0, 0.0), other_xy=(40.0, 0.0), ego_speed=0.0, active=act,
                        collided=coll, dt=DT, ego_dims=EGO, other_dims=RIDER)  # fmt: skip
        flag = get_metric("seen_too_late").compute(tr)[0]
        assert bool(flag) is expect, after
    cfg = MetricsConfig(reaction_time_s=1.5)
    assert bool(get_metric("seen_too_late").compute(tr, cfg)[0])


def test_sensor_range_decides_first_seen() -> None:
    """A sensor 1 m ahead of the car's centre with a 10 m range sees the standing rider
    once 2 of its 5 points (its rear corners) are within 10 m: gap + 1.35 m <= sqrt(100 -
    0.3^2), i.e. gap <= 8.6455 m; without a sensor it is seen at its first present step."""
    n = int(round(8.0 / DT)) + 1
    t = np.arange(n) * DT
    centre = 60.0 + 0.5 * (EGO[0] + RIDER[0])
    tr = make_trace(ego_xy=np.column_stack([8.0 * t, np.zeros(n)]), other_xy=(centre, 0.0),
                    ego_speed=8.0, dt=DT, ego_dims=EGO, other_dims=RIDER)  # fmt: skip
    sensor = {"sensor_range_m": 10.0, "sensor_fov_deg": 90.0, "sensor_x_m": 1.0,
              "sensor_y_m": 0.0, "sensor_min_visible_fraction": 0.4}  # fmt: skip
    (g,) = _values(tr, "first_seen_gap_m", params=sensor)
    limit = math.sqrt(100.0 - 0.09) - (2.35 - 1.0)
    assert limit - 8.0 * DT < g <= limit
    assert _values(tr, "first_seen_gap_m")[0] == pytest.approx(60.0)


def test_flag_counts_and_mask() -> None:
    table = pd.DataFrame(
        {
            "collision": [True, True, True, False, False],
            "impact_speed_mps": [np.nan, 3.0, np.nan, np.nan, np.nan],
            "seen_too_late": [True, False, False, True, None],
        }
    )
    np.testing.assert_array_equal(flagged_mask(table), [True, False, False, True, False])
    fc = flag_counts(table)
    assert fc == {
        "runs": 5, "flagged": 2, "flagged_share": 0.4, "collisions": 3, "collisions_flagged": 1,
        "collisions_unflagged": 2, "collisions_without_approach": 2,
        "collisions_without_approach_unflagged": 1,
    }  # fmt: skip
    assert not flagged_mask(table.drop(columns="seen_too_late")).any()
