"""Which samples of a run are on a continuation: the ``continuation`` column of a run's
long time series (:func:`mark_frame`), for any backend.

A replayed road user (the primary rider in a replay configuration, every other road user,
an extra rider in a replay configuration) is on its continuation while its recording
time lies outside its recorded span: t - shift for the primary rider, t for the others.
A social-force rider rides its run-in replayed (vei.sim.riders.sfm_entry_s), so it is on
its continuation before its recorded span too; from then on it has no recording time of
its own: it is on its run-out where its position is nearest to a continuation sample of
its track. The ego is never on one.
"""

from __future__ import annotations

from collections.abc import Collection

import numpy as np
import pandas as pd

from vei.continuation.scenario import is_continued, recorded_span_s
from vei.types import CONTINUATION_COLUMN, EGO_ID, Scenario

_EPS_S = 1e-6


def mark_frame(
    frame: pd.DataFrame,
    scenario: Scenario,
    *,
    rider_id: str | None,
    time_shift_s: float,
    sfm_configs: Collection[str] = (),
    sfm_agents: Collection[str] = (),
) -> pd.DataFrame:
    """``frame`` with a bool column ``continuation`` (see the module docstring).

    Args:
        frame: a run's long time series (vei.types.TIMESERIES_COLUMNS).
        scenario: the continued scenario the run was made from (a scenario without
            continuations marks nothing).
        rider_id: the primary rider (shifted by ``time_shift_s`` [s]).
        sfm_configs: names of the configurations whose primary rider (and
            ``sfm_agents``, the extra social-force riders) are social-force driven.
    Returns:
        A new DataFrame (the input is not changed).
    """
    flag = np.zeros(len(frame), dtype=bool)
    if not is_continued(scenario) or frame.empty:
        return frame.assign(**{CONTINUATION_COLUMN: flag})
    agents = frame["agent_id"].astype(str).to_numpy()
    t = frame["t_s"].to_numpy(dtype=np.float64)
    cfg = frame["config"].astype(str).to_numpy()
    active = frame["active"].to_numpy(dtype=bool)
    sfm_cfg = np.isin(cfg, list(sfm_configs))
    traj = scenario.trajectories
    for aid in np.unique(agents):
        if aid == EGO_ID:
            continue
        rows = agents == aid
        lo, hi = recorded_span_s(scenario, aid)
        if not np.isfinite(lo):
            continue
        shift = time_shift_s if aid == rider_id else 0.0
        t_rec = t[rows] - shift
        on = (t_rec < lo - _EPS_S) | (t_rec > hi + _EPS_S)
        sfm = sfm_cfg[rows] & (aid == rider_id or aid in sfm_agents)
        if sfm.any():
            tr = traj[traj["agent_id"] == aid]
            pts, lab = _labelled_points(tr)
            q = frame.loc[rows, ["x_m", "y_m"]].to_numpy(dtype=np.float64)[sfm]
            ok = np.isfinite(q).all(axis=1)
            near = np.zeros(q.shape[0], dtype=bool)
            if ok.any():
                from scipy.spatial import cKDTree

                _, j = cKDTree(pts).query(q[ok])
                near[ok] = lab[j]
            # replayed on its run-in until its first recorded sample (sfm_entry_s)
            near |= t_rec[sfm] < lo - _EPS_S
            sub = on.copy()
            sub[sfm] = near
            on = sub
        flag[np.flatnonzero(rows)] = on & active[rows]
    return frame.assign(**{CONTINUATION_COLUMN: flag})


def _labelled_points(track: pd.DataFrame) -> tuple[np.ndarray, np.ndarray]:
    """([P, 2] distinct positions of a track, [P] continuation label): a position shared
    by a recorded and a continuation sample (a standing end) counts as recorded."""
    pts = track[["x_m", "y_m"]].to_numpy(dtype=np.float64)
    lab = track[CONTINUATION_COLUMN].to_numpy(dtype=bool)
    uniq, inv = np.unique(pts, axis=0, return_inverse=True)
    out = np.ones(uniq.shape[0], dtype=bool)
    np.logical_and.at(out, inv.ravel(), lab)
    return uniq, out
