"""Secondary collisions: every contact of a run but the ego's with the primary rider.

A policy that brakes too hard can be rear-ended by the car behind; a time-shifted rider
can ride into another recorded car. The engine latches every contact between two road
users while it runs (vei.sim.contacts) and hands each run's summary to its Trace
(``Trace.secondary``, :func:`secondary_record`); a run read from a long time series of any
backend gets it from :func:`secondary_from_timeseries`. The metrics:

- ``secondary_collision`` (bool): some secondary collision;
- ``secondary_collisions``: how many pairs of road users touched (NaN: not reported);
- ``secondary_first`` (label): the first one, ``striker -> struck`` ('' if none);
- ``secondary_time_s``: its time [s] (NaN if none);
- ``secondary_impact_speed_mps``: the highest relative speed at a first contact [m/s];
- ``rear_end_collision`` (bool): a vehicle hit the ego from behind (its centre behind the
  ego's rear bumper, heading within 30 deg of the ego's).

Striker: of the two, the one whose velocity points more into the other.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.boxes import boxes_overlap

FloatArray = npt.NDArray[np.float64]

#: The secondary-collision metrics (registry names), in summary-column order.
SECONDARY_METRICS: tuple[str, ...] = (
    "secondary_collision",
    "secondary_collisions",
    "secondary_first",
    "secondary_time_s",
    "secondary_impact_speed_mps",
    "rear_end_collision",
)
#: Keys of a run summary (Trace.secondary): [B] arrays.
KEYS = ("count", "first_t_s", "striker", "struck", "max_speed_mps", "rear_end")


def secondary_record(
    count: npt.ArrayLike,
    first_t_s: npt.ArrayLike,
    striker: Sequence[str],
    struck: Sequence[str],
    max_speed_mps: npt.ArrayLike,
    rear_end: npt.ArrayLike,
) -> dict[str, np.ndarray]:
    """The summary of B runs (:data:`KEYS`): counts, first time [s], the first contact's
    striker / struck agent ids ('' none), the highest impact speed [m/s], rear-end flag."""
    return {
        "count": np.asarray(count, dtype=np.float64),
        "first_t_s": np.asarray(first_t_s, dtype=np.float64),
        "striker": np.asarray(list(striker), dtype=object),
        "struck": np.asarray(list(struck), dtype=object),
        "max_speed_mps": np.asarray(max_speed_mps, dtype=np.float64),
        "rear_end": np.asarray(rear_end, dtype=bool),
    }


def _get(a: Any) -> Mapping[str, np.ndarray] | None:
    return getattr(getattr(a, "trace", a), "secondary", None)


def secondary_metric(name: str, a: Any) -> np.ndarray:
    """[B] one of :data:`SECONDARY_METRICS` of a Trace / TraceArrays; a trace without a
    summary (a backend that reports none) scores NaN / False / ''."""
    sec = _get(a)
    b = np.shape(getattr(a, "trace", a).ego_speed_mps)[0]
    return secondary_column(name, sec, b)


def secondary_column(name: str, sec: Mapping[str, np.ndarray] | None, b: int) -> np.ndarray:
    """[B] one of :data:`SECONDARY_METRICS` from B runs' summary (:func:`secondary_record`;
    None: not reported)."""
    if sec is None:
        if name in ("secondary_collision", "rear_end_collision"):
            return np.zeros(b, dtype=bool)
        if name == "secondary_first":
            return np.full(b, "", dtype=object)
        return np.full(b, np.nan)
    count = np.asarray(sec["count"], dtype=np.float64)
    if name == "secondary_collision":
        return count > 0
    if name == "secondary_collisions":
        return count
    if name == "secondary_first":
        s, t = np.asarray(sec["striker"], dtype=object), np.asarray(sec["struck"], dtype=object)
        return np.array(
            [f"{x} -> {y}" if n > 0 else "" for x, y, n in zip(s, t, count, strict=True)],
            dtype=object,
        )
    if name == "secondary_time_s":
        return np.where(count > 0, np.asarray(sec["first_t_s"], dtype=np.float64), np.nan)
    if name == "secondary_impact_speed_mps":
        return np.where(count > 0, np.asarray(sec["max_speed_mps"], dtype=np.float64), np.nan)
    if name == "rear_end_collision":
        return np.asarray(sec["rear_end"], dtype=bool)
    raise KeyError(name)


def secondary_from_timeseries(
    frame: Any,
    runs: Sequence[tuple[str, int]],
    dims_m: Mapping[str, tuple[float, float]],
    rider_id: str,
    ego_id: str = "ego",
) -> dict[str, np.ndarray]:
    """The secondary collisions of the runs of a long time series (TIMESERIES_COLUMNS):
    new contacts (boxes overlap, not already at the first step both are present) of the
    ego with every road user but the primary rider, of the primary rider with every other,
    and of two vehicles (category 'vehicle'). Velocities are speed * heading at the step
    before the contact (as :func:`vei.metrics.severity.impact_speed`: a contact stops the
    road users at its own step).

    Args:
        frame: the time series. runs: (config, variant) of each run, in Trace order.
        dims_m: agent id -> (length, width) [m]. rider_id: the primary rider.
    Returns:
        The summary (:func:`secondary_record`) of the runs.
    """
    out = {k: [] for k in KEYS}
    for cfg, var in runs:
        rows = frame[(frame["config"].astype(str) == cfg) & (frame["variant"].astype(int) == var)]
        rows = rows[rows["active"].astype(bool)]
        cat = dict(zip(rows["agent_id"].astype(str), rows["category"].astype(str), strict=False))
        agents = [a for a in dict.fromkeys(rows["agent_id"].astype(str)) if a in dims_m]
        per = {a: g.set_index("t_s") for a, g in rows.groupby(rows["agent_id"].astype(str))}
        pairs = [
            (p, q)
            for i, p in enumerate(agents)
            for q in agents[i + 1 :]
            if {p, q} != {ego_id, rider_id}
            and (ego_id in (p, q) or rider_id in (p, q) or cat[p] == cat[q] == "vehicle")
        ]
        count, first_t, striker, struck, vmax, rear = 0, np.nan, "", "", np.nan, False
        for p, q in pairs:
            a, b = per[p], per[q]
            t = a.index.intersection(b.index)
            if t.size == 0:
                continue
            a, b = a.loc[t], b.loc[t]
            la, wa = dims_m[p]
            lb, wb = dims_m[q]
            ov = boxes_overlap(
                a["x_m"].to_numpy(), a["y_m"].to_numpy(), a["yaw_rad"].to_numpy(), la, wa,
                b["x_m"].to_numpy(), b["y_m"].to_numpy(), b["yaw_rad"].to_numpy(), lb, wb,
            )  # fmt: skip
            if not ov.any() or ov[0]:
                continue
            k = int(np.argmax(ov))
            pa = a.iloc[k]
            pb = b.iloc[k]
            # velocities of the step before (a contact stops road users at its own step)
            qa, qb = a.iloc[max(k - 1, 0)], b.iloc[max(k - 1, 0)]
            va = qa["speed_mps"] * np.array([np.cos(qa["yaw_rad"]), np.sin(qa["yaw_rad"])])
            vb = qb["speed_mps"] * np.array([np.cos(qb["yaw_rad"]), np.sin(qb["yaw_rad"])])
            d = np.array([pb["x_m"] - pa["x_m"], pb["y_m"] - pa["y_m"]])
            d = d / max(float(np.hypot(*d)), 1e-9)
            a_st = float(va @ d) >= float(-(vb @ d))
            sp = float(np.hypot(*(va - vb)))
            s_id, t_id = (p, q) if a_st else (q, p)
            if count == 0 or float(t[k]) < first_t:
                first_t, striker, struck = float(t[k]), s_id, t_id
            count += 1
            vmax = sp if not np.isfinite(vmax) else max(vmax, sp)
            if t_id == ego_id and cat.get(s_id) == "vehicle":
                e, o = (pa, pb) if p == ego_id else (pb, pa)
                c, s = np.cos(e["yaw_rad"]), np.sin(e["yaw_rad"])
                along = (o["x_m"] - e["x_m"]) * c + (o["y_m"] - e["y_m"]) * s
                same = np.cos(o["yaw_rad"] - e["yaw_rad"]) > np.cos(np.pi / 6)
                rear = rear or bool(along < -0.5 * dims_m[ego_id][0] and same)
        for key, val in zip(KEYS, (count, first_t, striker, struck, vmax, rear), strict=True):
            out[key].append(val)
    return secondary_record(*(out[k] for k in KEYS))
