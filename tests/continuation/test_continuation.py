"""Continuations (vei.continuation): run-in and run-out of hand-built tracks against
hand-computed answers, plausibility bounds, lanes of a hand-written OpenDRIVE map and
buildings of a hand-written OSM file."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pandas as pd
import pytest

from tests.maps.odr_fixtures import lane, road, write_odr
from vei.config import ContinuationConfig, SimConfig
from vei.config.continuation import CONTINUATION_DECEL_MPS2, CONTINUATION_REACTION_TIME_S
from vei.continuation import (
    recorded_rows,
    recorded_span_s,
    strip_continuations,
    with_continuations,
)
from vei.continuation.path import lateral_accel
from vei.errors import ConfigError
from vei.sim.testing import TrackSpec, ego_straight, make_scenario
from vei.types import CONTINUATION_COLUMN

RATE = 20.0


def _track(t0: float, dur: float, x0: float, y0: float, hdg: float, v: float, kappa: float = 0.0):
    """A rider at constant speed v [m/s] along an arc of curvature kappa from (x0, y0)."""
    t = t0 + np.arange(int(round(dur * RATE)) + 1) / RATE
    s = v * (t - t0)
    th = hdg + kappa * s
    if kappa == 0.0:
        x, y = x0 + s * math.cos(hdg), y0 + s * math.sin(hdg)
    else:
        x = x0 + (np.sin(th) - math.sin(hdg)) / kappa
        y = y0 - (np.cos(th) - math.cos(hdg)) / kappa
    return TrackSpec("escooter", t, x, y, yaw_rad=th, speed_mps=np.full(t.size, v))


def _scenario(rider: TrackSpec, ego_speed: float = 8.0):
    return make_scenario(
        {"ego": ego_straight(ego_speed, 20.0, RATE), "escooter_1": rider},
        primary_threat="escooter_1",
    )


def _reach(v: float) -> float:
    return v * CONTINUATION_REACTION_TIME_S + v * v / (2 * CONTINUATION_DECEL_MPS2)


def test_reach_distance_by_hand() -> None:
    cfg = ContinuationConfig()
    # 8 m/s: 8 * 1.5 + 64 / 12 = 17.333 m
    assert cfg.reach_m(8.0) == pytest.approx(12.0 + 64.0 / 12.0)
    with pytest.raises(ConfigError, match="continuation.decel_mps2"):
        ContinuationConfig(decel_mps2=0.0)
    with pytest.raises(ConfigError, match="continuation.enabled"):
        ContinuationConfig(enabled="yes")  # type: ignore[arg-type]


def test_straight_rider_by_hand() -> None:
    """4 m/s east from (0, 10), t = 5 .. 8 s: the run-in comes straight from the west and
    the run-out goes on east, each D = 17.33 m long (ego median speed 8 m/s), at 4 m/s on
    the 20 Hz grid; the recorded rows are untouched."""
    scen = _scenario(_track(5.0, 3.0, 0.0, 10.0, 0.0, 4.0))
    cont = with_continuations(scen)
    d = _reach(8.0)
    assert cont.extra["continuation"]["reach_m"] == pytest.approx(d)
    tr = cont.track("escooter_1")
    c = tr[CONTINUATION_COLUMN].to_numpy()
    rec = tr[~c]
    pd.testing.assert_frame_equal(
        rec.drop(columns=CONTINUATION_COLUMN).reset_index(drop=True), scen.track("escooter_1")
    )
    inn, out = tr[c & (tr.t_s < 5.0)], tr[c & (tr.t_s > 8.0)]
    n = math.ceil(d / 4.0 / 0.05 - 1e-9)
    assert len(inn) == len(out) == n
    np.testing.assert_allclose(np.diff(tr.t_s), 0.05, atol=1e-9)  # one grid, no gap
    np.testing.assert_allclose(inn.y_m, 10.0, atol=1e-9)
    np.testing.assert_allclose(out.y_m, 10.0, atol=1e-9)
    assert inn.x_m.iloc[0] == pytest.approx(-4.0 * n * 0.05, abs=1e-6)  # from the west
    assert out.x_m.iloc[-1] == pytest.approx(12.0 + 4.0 * n * 0.05, abs=1e-6)
    np.testing.assert_allclose(tr.speed_mps, 4.0)
    np.testing.assert_allclose(tr.yaw_rad, 0.0, atol=1e-12)
    rep = cont.extra["continuation"]["agents"]["escooter_1"]
    assert rep["run_in"]["kind"] == rep["run_out"]["kind"] == "free"
    assert rep["recorded_span_s"] == [5.0, 8.0]
    assert recorded_span_s(cont, "escooter_1") == (5.0, 8.0)
    # the ego is never continued; idempotent; strip gives back the recording
    pd.testing.assert_frame_equal(
        cont.track("ego").drop(columns=CONTINUATION_COLUMN), scen.track("ego")
    )
    assert with_continuations(cont) is cont
    back = strip_continuations(cont)
    pd.testing.assert_frame_equal(
        back.trajectories,
        recorded_rows(cont.trajectories).drop(columns=CONTINUATION_COLUMN).reset_index(drop=True),
    )
    assert "continuation" not in back.extra


def test_turning_rider_finishes_its_turn() -> None:
    """Curvature 0.05 1/m at 4 m/s: the run-out starts turning at 0.05 1/m, the curvature
    decays over 5 m (total turn <= 0.05 x 5 = 0.25 rad), position / yaw / speed join the
    recording without a step beyond the recording's own."""
    k = 0.05
    scen = _scenario(_track(5.0, 3.0, 0.0, 10.0, 0.3, 4.0, kappa=k))
    tr = with_continuations(scen).track("escooter_1")
    c = tr[CONTINUATION_COLUMN].to_numpy()
    yaw = np.unwrap(tr.yaw_rad.to_numpy())
    step = np.abs(np.diff(yaw))
    rec_step = step[~(c[1:] | c[:-1])].max()  # 0.05 * 0.2 m = 0.01 rad
    assert rec_step == pytest.approx(k * 4.0 * 0.05, rel=1e-6)
    assert step.max() <= rec_step + 1e-9
    out = tr[c & (tr.t_s > 8.0)]
    turn = float(np.unwrap(out.yaw_rad)[-1] - tr[~c].yaw_rad.iloc[-1])
    assert 0.0 < turn <= k * 5.0 + 1e-6
    assert turn == pytest.approx(k * 5.0 * (1 - math.exp(-out.shape[0] * 0.2 / 5.0)), abs=0.01)
    lat = lateral_accel(tr.x_m.to_numpy(), tr.y_m.to_numpy(), tr.t_s.to_numpy())
    assert lat[c].max() <= k * 16.0 + 0.02  # v^2 kappa, decaying
    jump = np.hypot(np.diff(tr.x_m), np.diff(tr.y_m))
    np.testing.assert_allclose(jump, 0.2, rtol=1e-3)  # 4 m/s x 0.05 s everywhere


def test_sharp_turn_is_bounded() -> None:
    """A turn at 8 m/s^2 of lateral acceleration (kappa 0.5 at 4 m/s) is continued at
    most at min(4 / v^2 (max_lat_accel_mps2), (pi / 4) / 5 m (max_turn_rad over the
    decay length)) = 0.157 1/m, within 4 m/s^2, turning by at most pi / 4."""
    scen = _scenario(_track(5.0, 2.0, 0.0, 10.0, 0.0, 4.0, kappa=0.5))
    cont = with_continuations(scen)
    tr = cont.track("escooter_1")
    c = tr[CONTINUATION_COLUMN].to_numpy()
    lat = lateral_accel(tr.x_m.to_numpy(), tr.y_m.to_numpy(), tr.t_s.to_numpy())
    inner = c.copy()
    inner[np.flatnonzero(~c)[[0, -1]] + np.array([-1, 1])] = False  # the joins: one-sided
    assert lat[inner].max() <= 4.0 + 0.05
    rep = cont.extra["continuation"]["agents"]["escooter_1"]
    assert abs(rep["run_out"]["curvature_per_m"]) == pytest.approx(min(4.0 / 16.0, math.pi / 20))
    out = tr[c & (tr.t_s > 7.0)]
    course = np.unwrap(np.arctan2(np.diff(out.y_m), np.diff(out.x_m)))
    assert abs(course[-1] - rep["run_out"]["course_rad"]) <= math.pi / 4 + 1e-6
    # the body yaw goes on at the recorded yaw rate, then settles onto the course; never a
    # step beyond the recording's own (0.5 x 0.2 m = 0.1 rad per step)
    assert np.abs(np.diff(np.unwrap(tr.yaw_rad))).max() <= 0.1 + 1e-9


def test_standing_and_slow_riders() -> None:
    """A standing rider stays where it is for D / 0.5 m/s; a slow one (0.3 m/s) brakes to a
    stop at 2 m/s^2 (no speed jump) and stands."""
    stand = TrackSpec("escooter", 5.0 + np.arange(41) / RATE, np.full(41, 3.0),
                      np.full(41, 4.0), yaw_rad=np.full(41, 1.0), speed_mps=np.zeros(41))  # fmt: skip
    cont = with_continuations(_scenario(stand))
    tr = cont.track("escooter_1")
    np.testing.assert_allclose(tr[["x_m", "y_m", "yaw_rad"]], [[3.0, 4.0, 1.0]] * len(tr))
    n = math.ceil(_reach(8.0) / 0.5 / 0.05 - 1e-9)
    assert len(tr) == 41 + 2 * n
    assert cont.extra["continuation"]["agents"]["escooter_1"]["run_in"]["kind"] == "standing"
    slow = _scenario(_track(5.0, 2.0, 0.0, 0.0, 0.0, 0.3))
    tr = with_continuations(slow).track("escooter_1")
    sp = tr.speed_mps.to_numpy()
    assert np.abs(np.diff(sp)).max() <= 2.0 * 0.05 + 1e-9
    out = tr[tr.t_s > 7.0]
    assert out.speed_mps.iloc[-1] == 0.0
    assert out.x_m.iloc[-1] == pytest.approx(0.6 + 0.3**2 / 4.0, abs=1e-3)  # v^2 / 2a


def test_engine_uses_the_continuation() -> None:
    """prepare_scenario continues the rider (track from the run-in's start to the
    run-out's end, SFM goal path to the run-out's end), keeps the recorded span for the
    speeds, and runs unchanged without continuations."""
    from vei.sim.state import prepare_scenario

    scen = _scenario(_track(5.0, 3.0, 0.0, 10.0, 0.0, 4.0))
    arr = prepare_scenario(scen)
    n = math.ceil(_reach(8.0) / 4.0 / 0.05 - 1e-9)
    assert arr.rider_track.t0_s == pytest.approx(5.0 - n * 0.05)
    assert arr.rider_track.t_end_s == pytest.approx(8.0 + n * 0.05)
    assert arr.rider_recorded_span_s == (5.0, 8.0)
    assert arr.rider_path.end_x_m == pytest.approx(12.0 + 4.0 * n * 0.05)
    assert arr.rider_sfm_entry_s == 5.0  # the run-in is replayed; the SFM from its start
    off = prepare_scenario(scen, SimConfig(continuation=ContinuationConfig(enabled=False)))
    assert (off.rider_track.t0_s, off.rider_track.t_end_s) == pytest.approx((5.0, 8.0))
    assert arr.n_steps == off.n_steps  # the simulated span is the recorded one


def test_lane_following(tmp_path) -> None:
    """A rider in the right lane of an arc road (curvature 1/50) leaving with a course
    along the lane continues along the lane at its own offset (kind 'lane'); without the
    map the free continuation leaves the lane."""
    r = road("1", 120.0, '<arc curvature="0.02"/>', x=0.0, y=0.0, hdg=0.0,
             right=lane(-1, "driving", 3.5), left=lane(1, "driving", 3.5))  # fmt: skip
    write_odr(tmp_path / "map.xodr", r)
    # on the arc of radius 50 around (0, 50), 1.75 m right of the reference line
    rad = 50.0 + 1.75
    ang = np.linspace(0.0, 0.08, 41)  # 4.1 m at ~5.2 m/s over 2 s... on the lane centre
    t = 5.0 + np.arange(41) / RATE
    x, y = rad * np.sin(ang), 50.0 - rad * np.cos(ang)
    rider = TrackSpec("cyclist", t, x, y, yaw_rad=ang, speed_mps=np.full(41, rad * 0.08 / 2.0))
    scen = dataclasses.replace(_scenario(rider), root=tmp_path, maps={"opendrive": "map.xodr"})
    cont = with_continuations(scen)
    rep = cont.extra["continuation"]
    assert rep["map"]["lanes"]
    assert rep["agents"]["escooter_1"]["run_out"]["kind"] == "lane"
    tr = cont.track("escooter_1")
    out = tr[tr[CONTINUATION_COLUMN].to_numpy() & (tr.t_s > 7.0)]
    dist = np.hypot(out.x_m, out.y_m - 50.0)  # distance from the arc's centre
    np.testing.assert_allclose(dist, rad, atol=0.05)
    free = with_continuations(dataclasses.replace(scen, maps={}))
    fo = free.track("escooter_1")
    fo = fo[fo[CONTINUATION_COLUMN].to_numpy() & (fo.t_s > 7.0)]
    assert np.abs(np.hypot(fo.x_m, fo.y_m - 50.0) - rad).max() > 0.3


def _osm_with_building(path, projection: str, ring_xy: list[tuple[float, float]]) -> None:
    from vei.geo.frame import LocalFrame

    frame = LocalFrame.from_proj_string(projection)
    lat, lon = frame.to_latlon([p[0] for p in ring_xy], [p[1] for p in ring_xy])
    nodes = "".join(
        f'<node id="{i + 1}" lat="{la:.9f}" lon="{lo:.9f}"/>'
        for i, (la, lo) in enumerate(zip(lat, lon, strict=True))
    )
    refs = "".join(f'<nd ref="{i + 1}"/>' for i in range(len(ring_xy))) + '<nd ref="1"/>'
    path.write_text(
        f'<?xml version="1.0"?><osm version="0.6">{nodes}<way id="1">{refs}'
        '<tag k="building" v="yes"/></way></osm>'
    )


def test_buildings_are_not_crossed(tmp_path) -> None:
    """A building 6 m ahead of a straight rider: the run-out stops 0.5 m before its wall
    (blocked_by_building). A building ahead of a turning rider's free path: it goes
    straight instead."""
    scen = _scenario(_track(5.0, 2.0, 0.0, 10.0, 0.0, 4.0))  # ends at x = 8
    _osm_with_building(
        tmp_path / "map.osm", scen.projection, [(14, 5), (30, 5), (30, 15), (14, 15)]
    )
    scen = dataclasses.replace(scen, root=tmp_path, maps={"osm": "map.osm"})
    cont = with_continuations(scen)
    rep = cont.extra["continuation"]["agents"]["escooter_1"]
    assert cont.extra["continuation"]["map"]["buildings"]
    assert rep["run_out"]["blocked_by_building"] and not rep["run_in"]["blocked_by_building"]
    tr = cont.track("escooter_1")
    assert tr.x_m.max() <= 14.0 - 0.5 + 1e-6
    assert tr.x_m.max() >= 14.0 - 0.5 - 0.2
    # a left turn towards a 1 m x 1 m kiosk on its free path 12 m on (1.86 m left of the
    # straight line: 0.25 (12 - 5 (1 - exp(-12 / 5)))): the straight candidate passes it
    turn = _scenario(_track(5.0, 2.0, 0.0, 10.0, 0.0, 4.0, kappa=0.05))
    tr = turn.track("escooter_1")
    ex, ey, hdg = float(tr.x_m.iloc[-1]), float(tr.y_m.iloc[-1]), 0.4
    side = 0.25 * (12.0 - 5.0 * (1.0 - math.exp(-12.0 / 5.0)))
    cx = ex + 12.0 * math.cos(hdg) - side * math.sin(hdg)
    cy = ey + 12.0 * math.sin(hdg) + side * math.cos(hdg)
    _osm_with_building(tmp_path / "b.osm", turn.projection,
                       [(cx - 0.5, cy - 0.5), (cx + 0.5, cy - 0.5), (cx + 0.5, cy + 0.5), (cx - 0.5, cy + 0.5)])  # fmt: skip
    turn = dataclasses.replace(turn, root=tmp_path, maps={"osm": "b.osm"})
    rep = with_continuations(turn).extra["continuation"]["agents"]["escooter_1"]
    assert rep["run_out"]["kind"] == "straight" and not rep["run_out"]["blocked_by_building"]
