"""Road users that arrive and leave: run-ins and run-outs of recorded tracks (issue 22).

A recorded road user that appears or vanishes inside the scene gets a continuation at
both ends (:func:`with_continuations`): where it came from and where it goes, long enough
that it enters from beyond the car's reach. The recorded samples stay as they are; the
added ones are marked (``vei.types.CONTINUATION_COLUMN``). See docs/continuations.md.

- :mod:`vei.continuation.path`: the geometry of one end (speed, course, decaying curvature).
- :mod:`vei.continuation.lanes`: along the map's lane; :mod:`.buildings`: OSM outlines.
- :mod:`vei.continuation.tracks`: one track's run-in and run-out.
- :mod:`vei.continuation.scenario`: Scenario -> Scenario.
- :mod:`vei.continuation.flags`: which samples of a run are on a continuation.
"""

from vei.continuation.scenario import (
    EXTRA_KEY,
    is_continued,
    reach_speed_mps,
    recorded_rows,
    recorded_span_s,
    strip_continuations,
    with_continuations,
)

__all__ = [
    "EXTRA_KEY",
    "is_continued",
    "reach_speed_mps",
    "recorded_rows",
    "recorded_span_s",
    "strip_continuations",
    "with_continuations",
]
