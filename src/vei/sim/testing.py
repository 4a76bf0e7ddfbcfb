"""Small constructed scenarios (in memory) for tests, examples and benchmarks.

A straight road along +x (plane frame, Indianapolis origin), the ego driving at constant
speed along y = 0, and a rider that crosses it (or stands, or rides along). Everything is
sampled on the uniform grid k / rate_hz like a reconstructed scenario, so the engine sees
exactly what ``vei reconstruct`` would hand it. Labelled synthetic in ``extra``.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np
import pandas as pd

from vei.types import (
    DEFAULT_DIMENSIONS_M,
    EGO_CATEGORY,
    EGO_ID,
    TRAJECTORY_COLUMNS,
    AgentInfo,
    Scenario,
)

#: Origin of the constructed scenarios: downtown Indianapolis (the paper's city).
ORIGIN_LAT_DEG = 39.7684
ORIGIN_LON_DEG = -86.1581


@dataclass(frozen=True)
class TrackSpec:
    """One agent's samples for :func:`make_scenario`.

    Attributes:
        category: 'ego' or one of vei.types.CATEGORIES.
        t_s, x_m, y_m: [M] times [s] (on the k / rate_hz grid) and positions [m].
        yaw_rad, speed_mps: [M] or None (then derived from the positions).
        length_m, width_m: footprint [m] (None = the category's default).
    """

    category: str
    t_s: np.ndarray
    x_m: np.ndarray
    y_m: np.ndarray
    yaw_rad: np.ndarray | None = None
    speed_mps: np.ndarray | None = None
    length_m: float | None = None
    width_m: float | None = None


def make_scenario(
    tracks: Mapping[str, TrackSpec],
    *,
    primary_threat: str | None,
    rate_hz: float = 20.0,
    scenario_id: str = "synthetic",
) -> Scenario:
    """A Scenario from per-agent samples (the ego must be agent 'ego').

    Args:
        tracks: agent_id -> TrackSpec. primary_threat: the rider to simulate.
        rate_hz: the sample rate the tracks use [Hz]. scenario_id: id.
    Returns:
        Scenario with trajectories in TRAJECTORY_COLUMNS order.
    """
    rows = []
    agents = []
    order = sorted(tracks, key=lambda a: (a != EGO_ID, a))
    for aid in order:
        tr = tracks[aid]
        t = np.asarray(tr.t_s, dtype=np.float64)
        x = np.asarray(tr.x_m, dtype=np.float64)
        y = np.asarray(tr.y_m, dtype=np.float64)
        if tr.yaw_rad is None:
            if t.size > 1:
                yaw = np.arctan2(np.gradient(y), np.gradient(x))
            else:
                yaw = np.zeros_like(x)
        else:
            yaw = np.broadcast_to(np.asarray(tr.yaw_rad, dtype=np.float64), t.shape)
        if tr.speed_mps is None:
            sp = np.hypot(np.gradient(x, t), np.gradient(y, t)) if t.size > 1 else np.zeros_like(x)
        else:
            sp = np.broadcast_to(np.asarray(tr.speed_mps, dtype=np.float64), t.shape)
        dl, dw = DEFAULT_DIMENSIONS_M[tr.category]
        agents.append(
            AgentInfo(
                agent_id=aid,
                category=tr.category,
                length_m=float(tr.length_m or dl),
                width_m=float(tr.width_m or dw),
                source_track_id=None if aid == EGO_ID else aid,
            )
        )
        rows.append(
            pd.DataFrame(
                {
                    "t_s": t,
                    "agent_id": aid,
                    "source_track_id": None if aid == EGO_ID else aid,
                    "category": tr.category,
                    "x_m": x,
                    "y_m": y,
                    "yaw_rad": yaw,
                    "speed_mps": sp,
                }
            )
        )
    traj = pd.concat(rows, ignore_index=True)[list(TRAJECTORY_COLUMNS)]
    allx = traj["x_m"].to_numpy()
    ally = traj["y_m"].to_numpy()
    m_per_deg = 111_320.0
    coslat = np.cos(np.radians(ORIGIN_LAT_DEG))
    bounds = {
        "south_deg": ORIGIN_LAT_DEG + (ally.min() - 20) / m_per_deg,
        "north_deg": ORIGIN_LAT_DEG + (ally.max() + 20) / m_per_deg,
        "west_deg": ORIGIN_LON_DEG + (allx.min() - 20) / (m_per_deg * coslat),
        "east_deg": ORIGIN_LON_DEG + (allx.max() + 20) / (m_per_deg * coslat),
    }
    return Scenario(
        id=scenario_id,
        projection=(
            f"+proj=tmerc +lat_0={ORIGIN_LAT_DEG} +lon_0={ORIGIN_LON_DEG} +k=1 +x_0=0 +y_0=0 "
            "+ellps=WGS84 +units=m +no_defs"
        ),
        origin_lat_deg=ORIGIN_LAT_DEG,
        origin_lon_deg=ORIGIN_LON_DEG,
        start_time_utc=datetime(2025, 6, 1, 15, 0, 0, tzinfo=UTC),
        rate_hz=float(rate_hz),
        bounds=bounds,
        agents=tuple(agents),
        primary_threat=primary_threat,
        trajectories=traj,
        extra={"synthetic": True, "note": "constructed by vei.sim.testing"},
    )


def ego_straight(
    speed_mps: float = 5.6, duration_s: float = 25.0, rate_hz: float = 20.0, x0_m: float = 0.0
) -> TrackSpec:
    """Ego at constant speed along +x on y = 0 from x0 over [0, duration]."""
    t = np.arange(int(round(duration_s * rate_hz)) + 1) / rate_hz
    return TrackSpec(
        EGO_CATEGORY,
        t,
        x0_m + speed_mps * t,
        np.zeros_like(t),
        np.zeros_like(t),
        np.full_like(t, speed_mps),
    )


def crossing_scenario(
    *,
    ego_speed_mps: float = 5.6,
    rider_speed_mps: float = 4.4,
    crossing_x_m: float = 60.0,
    rider_y0_m: float = -15.0,
    rider_y1_m: float = 15.0,
    rider_t0_s: float = 2.0,
    duration_s: float = 25.0,
    rate_hz: float = 20.0,
    rider_category: str = "escooter",
    others: Sequence[tuple[str, TrackSpec]] = (),
    scenario_id: str = "synthetic-crossing",
) -> Scenario:
    """The paper-like case: ego at 5.6 m/s along +x, an e-scooter crossing at x = crossing_x_m.

    The rider rides from (crossing_x, rider_y0) towards +y at ``rider_speed_mps`` starting
    at ``rider_t0_s`` until it reaches rider_y1. With the defaults the recording is
    crash-free: the rider crosses y = 0 at t = 2 + 15 / 4.4 = 5.41 s, when the ego is at
    x = 30 m, half-way to the crossing. The time shift that puts the rider's centre on the
    ego's front-bumper centre is (crossing_x - L_ego/2) / v_ego - (t0 + |y0| / v_rider)
    = (60 - 2.35) / 5.6 - 5.409 = 4.886 s with the defaults.
    """
    ego = ego_straight(ego_speed_mps, duration_s, rate_hz)
    t_r1 = rider_t0_s + (rider_y1_m - rider_y0_m) / rider_speed_mps
    k0 = int(round(rider_t0_s * rate_hz))
    k1 = int(np.floor(t_r1 * rate_hz + 1e-9))
    t = np.arange(k0, k1 + 1) / rate_hz
    y = rider_y0_m + rider_speed_mps * (t - rider_t0_s)
    rider = TrackSpec(
        rider_category,
        t,
        np.full_like(t, crossing_x_m),
        y,
        np.full_like(t, np.pi / 2 if rider_y1_m > rider_y0_m else -np.pi / 2),
        np.full_like(t, rider_speed_mps),
    )
    tracks = {EGO_ID: ego, "rider1": rider}
    tracks.update(dict(others))
    return make_scenario(tracks, primary_threat="rider1", rate_hz=rate_hz, scenario_id=scenario_id)


def standing_rider_scenario(
    *,
    ego_speed_mps: float = 5.6,
    rider_x_m: float = 40.0,
    rider_y_m: float = 0.0,
    rider_yaw_rad: float = np.pi / 2,
    duration_s: float = 20.0,
    rate_hz: float = 20.0,
) -> Scenario:
    """Ego at constant speed along +x; an e-scooter standing at (rider_x, rider_y) throughout."""
    ego = ego_straight(ego_speed_mps, duration_s, rate_hz)
    t = ego.t_s
    rider = TrackSpec(
        "escooter",
        t,
        np.full_like(t, rider_x_m),
        np.full_like(t, rider_y_m),
        np.full_like(t, rider_yaw_rad),
        np.zeros_like(t),
    )
    return make_scenario(
        {EGO_ID: ego, "rider1": rider},
        primary_threat="rider1",
        rate_hz=rate_hz,
        scenario_id="synthetic-standing",
    )


def four_rider_scenario(more: Sequence[tuple[str, TrackSpec]] = ()) -> Scenario:
    """:func:`crossing_scenario` with three more e-scooters (several-rider benchmarks and
    the kernel's regression digests): e2 crosses the ego's lane at x = 45 m from t = 1 s at
    3 m/s, e3 at x = 75 m from t = 4 s at 4 m/s (both from y = -15 m over 30 m), and e4
    rides along y = 8 m towards -x at 1.8 m/s from x = 75 m at t = 2 s; ``more``: further
    road users (id, track)."""

    def crossing(x_m: float, t0_s: float, speed_mps: float) -> TrackSpec:
        t = np.arange(round(t0_s * 20), round((t0_s + 30.0 / speed_mps) * 20) + 1) / 20.0
        y = -15.0 + speed_mps * (t - t0_s)
        return TrackSpec("escooter", t, np.full_like(t, x_m), y, np.full_like(t, np.pi / 2),
                         np.full_like(t, speed_mps))  # fmt: skip

    t = np.arange(40, 301) / 20.0
    along = TrackSpec("escooter", t, 75.0 - 1.8 * (t - 2.0), np.full_like(t, 8.0),
                      np.full_like(t, np.pi), np.full_like(t, 1.8))  # fmt: skip
    others = [("e2", crossing(45.0, 1.0, 3.0)), ("e3", crossing(75.0, 4.0, 4.0)), ("e4", along)]
    return crossing_scenario(others=[*others, *more])


def follower_scenario(
    speed_mps: float = 10.0, headway_s: float = 1.0, wave_mps: float = 0.0
) -> Scenario:
    """The ego at ``speed_mps`` along +x for 15 s (20 Hz), a car (4.7 m) ``headway_s``
    behind it bumper to bumper at the same speed (a reacting car where traffic.cars_react
    is on: it notices a braking ego), and an e-scooter standing far away (400, 40) m.
    ``wave_mps``: both drive speed_mps + wave_mps sin(0.5 t) [m/s] instead (the same
    distance apart), a recorded speed that varies."""
    t = np.arange(0, 301) * 0.05
    z = np.zeros_like(t)
    v = speed_mps + wave_mps * np.sin(0.5 * t)
    x = 20.0 + speed_mps * t + wave_mps * (1.0 - np.cos(0.5 * t)) / 0.5
    ego = TrackSpec("ego", t, x, z, z, v)
    fol = TrackSpec("vehicle", t, x - 4.7 - speed_mps * headway_s, z, z, v)
    rider = TrackSpec("escooter", t, np.full_like(t, 400.0), np.full_like(t, 40.0),
                      np.full_like(t, np.pi / 2), z)  # fmt: skip
    return make_scenario({EGO_ID: ego, "car1": fol, "r1": rider}, primary_threat="r1")
