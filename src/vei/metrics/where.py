"""Where a run's contacts happened: on the road user's recorded behaviour, on its run-in
or on its run-out (issue 31).

The engine (and a long time series of any backend) labels each run's contacts
(vei.continuation.where.run_where) and hands the labels to its Trace (``Trace.where``);
these metrics read them:

- ``contact_where`` (label): where the primary rider was at its first contact with the
  ego: 'recorded', 'run-in', 'run-out' ('' without a contact);
- ``secondary_where`` (label): where the other road user of the first secondary contact
  was ('' without one);
- ``collision_recorded`` (bool): a collision of the ego with the primary rider on the
  rider's recorded behaviour (the collisions the data itself supports).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: The metrics of this module (registry names).
WHERE_METRICS: tuple[str, ...] = ("contact_where", "secondary_where", "collision_recorded")


def where_metric(name: str, a: Any) -> np.ndarray:
    """[B] one of :data:`WHERE_METRICS` of a Trace / TraceArrays; a trace without labels
    (a source that reports none) scores '' / False."""
    trace = getattr(a, "trace", a)
    labels = getattr(trace, "where", None)
    b = np.shape(trace.ego_speed_mps)[0]
    return where_column(name, labels, b)


def where_column(name: str, labels: Any, b: int) -> np.ndarray:
    """[B] one of :data:`WHERE_METRICS` from B runs' labels ({'contact', 'secondary'} [B]
    arrays; None: not reported)."""
    if name not in WHERE_METRICS:
        raise KeyError(name)
    key = "secondary" if name == "secondary_where" else "contact"
    col = (
        np.full(b, "", dtype=object)
        if labels is None
        else np.asarray(labels[key], dtype=object).reshape(b)
    )
    if name == "collision_recorded":
        return col == "recorded"
    return col
