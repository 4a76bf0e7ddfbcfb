"""Settings of the continuations: how road users that appear or vanish inside the scene
arrive and leave (:mod:`vei.continuation`). Re-exported by :mod:`vei.config`.

Imports nothing of vei but errors (see DESIGN.md, dependency direction).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from vei.errors import ConfigError

#: Reaction time [s] of the reach distance: 1.5 s, the perception-reaction time of a
#: driver to a surprise event (an object entering the path), Green 2000, "How long does
#: it take to stop?", Transportation Human Factors 2(3):195-216 (0.7-0.75 s for an
#: expected signal, ~1.25 s for an unexpected common one, ~1.5 s for a surprise).
CONTINUATION_REACTION_TIME_S = 1.5
#: Braking deceleration [m/s^2] of the reach distance: 6.0, the paper's planner's
#: largest braking (``CAPConfig.a_min_mps2``), below the car's full brake (8 m/s^2) so
#: that the distance is the longer one.
CONTINUATION_DECEL_MPS2 = 6.0


def _number(name: str, value: Any, *, positive: bool = False, nonneg: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"continuation.{name} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise ConfigError(f"continuation.{name} must be finite, got {value!r}")
    if positive and value <= 0:
        raise ConfigError(f"continuation.{name} must be > 0, got {value!r}")
    if nonneg and value < 0:
        raise ConfigError(f"continuation.{name} must be >= 0, got {value!r}")
    return float(value)


@dataclass(frozen=True)
class ContinuationConfig:
    """Run-in and run-out of every road user but the ego (vei.continuation).

    A recorded track that starts or ends inside the scene gets a continuation at both
    ends: at the start backwards in time (the run-in: where it came from), at the end
    forwards (the run-out: where it goes). Each continues the track's own motion at that
    end (speed, heading, curvature decaying so that it never curls; along the road's lane
    where the map has one), long enough that the road user enters from beyond the car's
    reach and leaves the same way: the *reach distance*
    ``D = v t_r + v^2 / (2 a)`` (reaction plus braking distance of the car at its cruise
    speed v). The recorded samples are kept unchanged; the added ones are marked
    (``continuation`` column). docs/continuations.md.

    Attributes:
        enabled: add continuations (False: the recordings as they are: road users appear
            at their first and vanish at their last recorded sample).
        ego_speed_mps: v of the reach distance [m/s]; None (default) = the recorded ego's
            median speed while moving (the default cruise speed), at least
            ``min_ego_speed_mps``. The case study takes the largest cruise speed of its
            configurations, a sweep the largest of its design.
        reaction_time_s: t_r [s]; default 1.5 s (:data:`CONTINUATION_REACTION_TIME_S`:
            Green 2000, surprise event).
        decel_mps2: a [m/s^2]; default 6.0 (:data:`CONTINUATION_DECEL_MPS2`: the CAP's
            largest braking).
        min_ego_speed_mps: the floor of v [m/s] when the recorded ego never moves; 5.6,
            the paper's cruise speed.
        standing_speed_mps: a road user slower than this [m/s] at its first / last sample
            counts as standing: its continuation stays where it is (it brakes to a stop
            at ``stop_decel_mps2`` first, so that its speed does not jump). Its duration
            is that of a road user at this speed over D. Default 0.5 m/s, the threshold
            of "moving" used for the ego's median moving speed.
        stop_decel_mps2: deceleration of a slow road user to standstill [m/s^2]; 2.0,
            a comfortable yielding deceleration of a cyclist / e-scooter rider (an
            assumption below the bicycle design value for wet pavement: friction 0.25,
            0.25 g = 2.45 m/s^2, AASHTO 1999, Guide for the Development of Bicycle
            Facilities, stopping sight distance).
        curvature_decay_m: the curvature at the end decays as exp(-s / this) along the
            continuation [m]; 5 m (about one second of riding): a turn in progress is
            finished, never continued into a circle.
        max_turn_rad: the whole continuation turns by at most this [rad] (the end
            curvature is reduced until curvature x decay length <= this); pi / 4.
        max_lat_accel_mps2: the end curvature is reduced until speed^2 x curvature <=
            this [m/s^2]; 4.0 m/s^2, the ego path's bound (SimConfig.ego_max_lat_accel_mps2),
            below the calibrated rider's acceleration limit (5.9 m/s^2).
        follow_roads: where the scenario has an OpenDRIVE map, a road user whose end lies
            on a lane (any lane type) heading along it within ``road_heading_tol_rad``
            continues along that lane (its lateral offset kept), blended in over
            ``road_blend_m``; elsewhere the free continuation (riders use pavements).
        road_heading_tol_rad: largest angle between the motion and the lane [rad]; 0.5
            (~30 deg).
        road_blend_m: length over which the free continuation is blended into the lane
            [m]; 10 m.
        avoid_buildings: where the scenario's map has building outlines (an OSM source
            kept as ``maps['osm']``), a continuation that would cross one is replaced by
            another candidate (free / along the lane / straight) or cut 0.5 m before it.
    """

    enabled: bool = True
    ego_speed_mps: float | None = None
    reaction_time_s: float = CONTINUATION_REACTION_TIME_S
    decel_mps2: float = CONTINUATION_DECEL_MPS2
    min_ego_speed_mps: float = 5.6
    standing_speed_mps: float = 0.5
    stop_decel_mps2: float = 2.0
    curvature_decay_m: float = 5.0
    max_turn_rad: float = math.pi / 4
    max_lat_accel_mps2: float = 4.0
    follow_roads: bool = True
    road_heading_tol_rad: float = 0.5
    road_blend_m: float = 10.0
    avoid_buildings: bool = True

    def __post_init__(self) -> None:
        for name in ("enabled", "follow_roads", "avoid_buildings"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(
                    f"continuation.{name} must be true or false, got {getattr(self, name)!r}"
                )
        if self.ego_speed_mps is not None:
            _number("ego_speed_mps", self.ego_speed_mps, positive=True)
        _number("reaction_time_s", self.reaction_time_s, nonneg=True)
        for name in (
            "decel_mps2",
            "min_ego_speed_mps",
            "standing_speed_mps",
            "stop_decel_mps2",
            "curvature_decay_m",
            "max_turn_rad",
            "max_lat_accel_mps2",
            "road_heading_tol_rad",
            "road_blend_m",
        ):
            _number(name, getattr(self, name), positive=True)

    def reach_m(self, ego_speed_mps: float) -> float:
        """The reach distance D = v t_r + v^2 / (2 a) [m] at ego speed v [m/s]."""
        v = float(ego_speed_mps)
        return v * self.reaction_time_s + v * v / (2.0 * self.decel_mps2)
