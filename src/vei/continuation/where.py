"""Where a road user was at a contact: on its recorded behaviour, its run-in or its run-out.

Most of what vei counts as a collision should happen where the data says the rider was; a
collision on a continuation (issue 22's synthetic run-in or run-out) rests on vei's own
extrapolation. :func:`where` labels one moment of one road user by the same rule as the
time series' ``continuation`` column (:mod:`vei.continuation.flags`):

- a replayed road user is on its recording at recording time ``t_rec`` (``t - shift`` for
  the primary rider, ``t`` for every other): ``run-in`` before its recorded span,
  ``run-out`` after it, ``recorded`` inside;
- a social-force rider rides its run-in replayed (``run-in`` while ``t_rec`` is before
  its span); from its first recorded sample on it has no recording time of its own: it is
  where its *position* is, the label of the nearest sample of its continued track
  (a position shared by a recorded and a continuation sample counts as recorded).

The engine labels each variant's first contact from its state at the contact (a collided
rider stands where it touched: :func:`vei.sim.result.SimResult.where`), the time series of
any backend from its rows (:func:`where_from_frame`), so that a sweep's row and a
``vei run`` of the same variant say the same.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.types import CONTINUATION_COLUMN, Scenario

#: The labels of a contact, in this order everywhere ('' : no contact).
WHERE: tuple[str, ...] = ("recorded", "run-in", "run-out")
RECORDED, RUN_IN, RUN_OUT = WHERE
_EPS_S = 1e-6


@dataclass(frozen=True)
class Route:
    """One road user's continued track, labelled.

    Attributes:
        agent_id: the road user.
        span_s: (first, last) recorded time [s] (NaN, NaN: no recorded sample).
        points_m: [P, 2] the distinct positions of its track [m].
        label: [P] int8, index into :data:`WHERE` of each position (a position that a
            recorded sample shares counts as recorded).
    """

    agent_id: str
    span_s: tuple[float, float]
    points_m: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    label: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=np.int8))


def route_of(scenario: Scenario, agent_id: str) -> Route:
    """The labelled route of ``agent_id`` in a (continued or not) scenario."""
    tr = scenario.track(agent_id)
    if tr.empty:
        return Route(agent_id, (float("nan"), float("nan")))
    t = tr["t_s"].to_numpy(dtype=np.float64)
    cont = (
        tr[CONTINUATION_COLUMN].to_numpy(dtype=bool)
        if CONTINUATION_COLUMN in tr.columns
        else np.zeros(t.size, dtype=bool)
    )
    rec_t = t[~cont]
    span = (float(rec_t.min()), float(rec_t.max())) if rec_t.size else (float("nan"),) * 2
    lab = np.where(~cont, 0, np.where(t < span[0], 1, 2)).astype(np.int8)
    pts = tr[["x_m", "y_m"]].to_numpy(dtype=np.float64)
    uniq, inv = np.unique(pts, axis=0, return_inverse=True)
    best = np.full(uniq.shape[0], 127, dtype=np.int8)  # recorded (0) wins a shared position
    np.minimum.at(best, inv.ravel(), lab)
    return Route(agent_id, span, uniq, best)


def where(
    route: Route,
    t_rec_s: npt.ArrayLike,
    xy_m: npt.ArrayLike,
    sfm: npt.ArrayLike,
    contact: npt.ArrayLike,
) -> np.ndarray:
    """[B] labels (:data:`WHERE`, '' without a contact) of B moments of one road user.

    Args:
        route: the road user's labelled route (:func:`route_of`).
        t_rec_s: [B] its recording time at the moment [s] (NaN without a contact).
        xy_m: [B, 2] its position then [m] (used for a social-force rider).
        sfm: [B] bool, the road user is social-force driven in that variant.
        contact: [B] bool, there is a contact to label.
    Returns:
        [B] object array of str.
    """
    t = np.atleast_1d(np.asarray(t_rec_s, dtype=np.float64))
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    sfm_b = np.broadcast_to(np.asarray(sfm, dtype=bool), t.shape)
    hit = np.broadcast_to(np.asarray(contact, dtype=bool), t.shape)
    out = np.full(t.shape, "", dtype=object)
    lo, hi = route.span_s
    if not np.isfinite(lo):
        out[hit] = RECORDED
        return out
    code = np.where(t < lo - _EPS_S, 1, np.where(t > hi + _EPS_S, 2, 0))
    near = hit & sfm_b & (code != 1)
    if near.any() and route.points_m.shape[0]:
        q = xy[near]
        ok = np.isfinite(q).all(axis=1)
        lab = np.zeros(q.shape[0], dtype=np.int64)
        if ok.any():
            from scipy.spatial import cKDTree

            _, j = cKDTree(route.points_m).query(q[ok])
            lab[ok] = route.label[j]
        code[near] = lab
    for i, name in enumerate(WHERE):
        out[hit & (code == i)] = name
    return out


def where_from_frame(
    frame: pd.DataFrame,
    runs: list[tuple[str, int]],
    routes: dict[str, Route],
    *,
    rider_id: str,
    time_shift_s: float,
    sfm_configs: set[str],
) -> np.ndarray:
    """[B] where the primary rider was at its first contact with the ego, for each run
    (config, variant) of a long time series (vei.types.TIMESERIES_COLUMNS): its row at the
    first step ``collided`` is set ('' where it never is)."""
    out = np.full(len(runs), "", dtype=object)
    route = routes.get(rider_id)
    if route is None:
        return out
    rider = frame[frame["agent_id"].astype(str) == rider_id]
    for i, (cfg, var) in enumerate(runs):
        rows = rider[(rider["config"].astype(str) == cfg) & (rider["variant"].astype(int) == var)]
        hit = rows[rows["collided"].astype(bool)]
        if hit.empty:
            continue
        first = hit.loc[hit["t_s"].idxmin()]
        out[i] = where(
            route,
            [float(first["t_s"]) - time_shift_s],
            [[float(first["x_m"]), float(first["y_m"])]],
            [cfg in sfm_configs],
            [True],
        )[0]
    return out


def secondary_party(striker: str, struck: str, rider_id: str, ego_id: str = "ego") -> str:
    """The road user of a secondary contact whose behaviour is labelled: the one that is
    neither the ego nor the primary rider (the struck one where both are others); ''
    when there is no contact."""
    for aid in (struck, striker):
        if aid and aid not in (ego_id, rider_id):
            return aid
    return ""


def run_where(
    routes: dict[str, Route],
    rider_id: str,
    *,
    collision_time_s: npt.ArrayLike,
    time_shift_s: npt.ArrayLike,
    rider_xy_m: npt.ArrayLike,
    rider_sfm: npt.ArrayLike,
    secondary_time_s: npt.ArrayLike,
    secondary_striker: list[str],
    secondary_struck: list[str],
) -> dict[str, np.ndarray]:
    """Where each of B runs' contacts happened: {'contact': [B] the primary rider at its
    first contact with the ego, 'secondary': [B] the other road user of the first
    secondary contact (its recording time: every road user but the primary rider is on
    its recording's own clock; a reacting car or an extra social-force rider is labelled
    by the moment's recording time)}; '' where there is none.

    Args:
        collision_time_s: [B] the first contact with the ego [s] (NaN: none).
        time_shift_s: [B] the rider's shift [s]. rider_xy_m: [B, 2] the rider's position
        at the contact [m]. rider_sfm: [B] social-force driven.
        secondary_time_s: [B] the first secondary contact [s] (NaN: none);
        secondary_striker / secondary_struck: [B] its road users ('' none).
    """
    tc = np.asarray(collision_time_s, dtype=np.float64)
    shift = np.broadcast_to(np.asarray(time_shift_s, dtype=np.float64), tc.shape)
    contact = np.full(tc.shape, "", dtype=object)
    if rider_id in routes:
        contact = where(routes[rider_id], tc - shift, rider_xy_m, rider_sfm, np.isfinite(tc))
    ts = np.asarray(secondary_time_s, dtype=np.float64)
    secondary = np.full(ts.shape, "", dtype=object)
    for b in range(ts.size):
        party = secondary_party(str(secondary_striker[b]), str(secondary_struck[b]), rider_id)
        if party in routes and np.isfinite(ts[b]):
            secondary[b] = where(routes[party], [ts[b]], [[np.nan, np.nan]], [False], [True])[0]
    return {"contact": contact, "secondary": secondary}


def where_from_timeseries(
    frame: pd.DataFrame,
    runs: list[tuple[str, int]],
    scenario: Scenario,
    *,
    rider_id: str,
    time_shift_s: float,
    sfm_configs: set[str],
    secondary: dict[str, np.ndarray] | None,
) -> dict[str, np.ndarray]:
    """:func:`run_where`'s labels of the runs (config, variant) of a long time series of
    any backend, made from the continued ``scenario``: the primary rider's row at its
    first contact (:func:`where_from_frame`), the secondary contacts' from their summary
    (vei.metrics.secondary.secondary_record; None: not reported)."""
    routes = {a.agent_id: route_of(scenario, a.agent_id) for a in scenario.agents}
    contact = where_from_frame(
        frame, runs, routes, rider_id=rider_id, time_shift_s=time_shift_s,
        sfm_configs=sfm_configs,
    )  # fmt: skip
    if secondary is None:
        return {"contact": contact, "secondary": np.full(len(runs), "", dtype=object)}
    labels = run_where(
        routes, rider_id, collision_time_s=np.full(len(runs), np.nan), time_shift_s=0.0,
        rider_xy_m=np.full((len(runs), 2), np.nan), rider_sfm=False,
        secondary_time_s=secondary["first_t_s"], secondary_striker=list(secondary["striker"]),
        secondary_struck=list(secondary["struck"]),
    )  # fmt: skip
    return {"contact": contact, "secondary": labels["secondary"]}
