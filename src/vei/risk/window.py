"""The default time-shift window: where the recorded rider's span meets the car's path
(issue 31.4).

With ``time_shift_reference: auto`` the offset ``time_shift_s`` moves the rider's arrival
around the automatic shift, the shift that puts the rider on the car's front bumper. An
offset delta puts the rider, when the car reaches the meeting point, at recording time
``r_m - delta`` (:meth:`vei.sim.timeshift.TimeShiftResult.recorded_window_s`): offsets
outside ``[r_m - r1, r_m - r0]`` meet the car with the rider on its synthetic run-in or
run-out (issue 22's continuations), not on its recording. With ``time_shift_window:
recorded`` (the default) a uniform ``time_shift_s`` is narrowed to that window, so that
the collisions counted happen on recorded behaviour; where the recorded paths never meet
(or the window keeps less than MIN_WIDTH_S of it) the window stays whole and the answer
says once that its risk is continuation-driven.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

#: Time-shift window modes of a risk spec.
TIME_SHIFT_WINDOWS: tuple[str, ...] = ("recorded", "full")
#: Narrowest window kept [s]; a narrower overlap keeps the spec's window (and says so).
MIN_WIDTH_S = 0.5
#: The line every answer on an encounter whose recorded paths never meet carries.
CONTINUATION_DRIVEN = (
    "this risk is continuation-driven: the recorded paths never meet, so its collisions "
    "happen where vei continues the rider beyond its recording, not on recorded behaviour"
)


def narrow_time_shift(dist: Any, shift: Any, mode: str) -> tuple[Any, str]:
    """The time_shift_s distribution for one scenario and a note on its window.

    Args:
        dist: the spec's time_shift_s Distribution (None: not varied).
        shift: the scenario's automatic TimeShiftResult (None: reference 'zero').
        mode: 'recorded' (narrow a uniform window to the recorded span) or 'full'.
    Returns:
        (distribution, note): the distribution (narrowed or as given) and one line for the
        answer ('' when nothing needs saying).
    """
    if shift is None:
        return dist, ""
    if not shift.paths_meet:
        return dist, CONTINUATION_DRIVEN
    if mode != "recorded" or dist is None or dist.kind != "uniform":
        return dist, ""
    lo, hi = shift.recorded_window_s()
    # to 1 us (and no -0.0)
    new_lo, new_hi = round(max(dist.low, lo), 6) + 0.0, round(min(dist.high, hi), 6) + 0.0
    if not (math.isfinite(new_lo) and math.isfinite(new_hi)) or new_hi - new_lo < MIN_WIDTH_S:
        return dist, (
            f"time_shift_s kept at [{dist.low:g}, {dist.high:g}] s: the rider's recorded span "
            f"meets the car's path only for offsets [{lo:+.2f}, {hi:+.2f}] s; the risk is "
            "mostly continuation-driven"
        )
    if (new_lo, new_hi) == (dist.low, dist.high):
        return dist, ""
    note = (
        f"time_shift_s narrowed from [{dist.low:g}, {dist.high:g}] to [{new_lo:+.2f}, "
        f"{new_hi:+.2f}] s, the offsets at which the recorded rider meets the car's path "
        "(time_shift_window: recorded); probabilities are conditional on that window"
    )
    return dataclasses.replace(dist, low=float(new_lo), high=float(new_hi)), note
