"""Contacts between any two road users, and the run's secondary collisions (NumPy step).

The engine has always latched the ego's contacts with the primary rider (``collided``,
both stop), with every replayed other (``hit_other``) and every extra rider
(``extra_hit``). This module adds the rider's contacts with the others
(``rider_hit_other``) and a reacting car's with any other (``car_hit``, its partner in
``car_hit_with``); a reacting car stops at its first contact. Every new contact but the
ego's with the primary rider is a *secondary collision*: the run counts them
(``sec_count``), keeps the first (``sec_first_t_s``, its striker and struck road user
``sec_striker`` / ``sec_struck``: codes of :func:`agent_code`), the highest relative
speed at a first contact (``sec_max_speed_mps``) and whether a following vehicle hit the
ego from behind (``rear_end``). The compiled kernel does the same on scalars.

Agent codes: 0 the ego, 1 the primary rider, 2 + j replayed other j, 2 + n_o + m extra
rider m. Striker: the one of the two whose velocity points more into the other (ties: the
first); impact speed: the norm of the relative velocity. Both from the positions at the
first contact step and the velocities of the step before (speed times heading, a car its
recorded speed while it replays): as :func:`vei.metrics.secondary.secondary_from_
timeseries` scores a run's time series (a contact stops a reacting car at its own step),
so that ``vei run`` of a sweep's variant reproduces its row.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from vei.boxes import boxes_overlap
from vei.models import traffic_core

FloatArray = npt.NDArray[np.float64]

#: SimState fields of the contacts: [B, n_o] / [B, C] latches, then the [B] summaries.
CONTACT_FIELDS = (
    "rider_hit_other", "car_hit", "car_hit_with", "sec_count", "sec_first_t_s",
    "sec_striker", "sec_struck", "sec_max_speed_mps", "rear_end",
)  # fmt: skip


def agent_code(kind: str, j: int = 0, n_others: int = 0) -> int:
    """The code of a road user: kind 'ego', 'rider', 'other' (index j) or 'extra' (j)."""
    return {"ego": 0, "rider": 1, "other": 2 + j, "extra": 2 + n_others + j}[kind]


def agent_name(
    code: int, rider_id: str, other_ids: tuple[str, ...], extra_ids: tuple[str, ...]
) -> str:
    """The agent id of a code ('' for -1: none)."""
    if code < 0:
        return ""
    if code == 0:
        return "ego"
    if code == 1:
        return rider_id
    n_o = len(other_ids)
    return other_ids[code - 2] if code - 2 < n_o else extra_ids[code - 2 - n_o]


def collide_ego_others(
    arrays: Any,
    k: int,
    ex: FloatArray,
    ey: FloatArray,
    eyaw: FloatArray,
    hit: npt.NDArray[np.bool_],
    poses: tuple[FloatArray, FloatArray, FloatArray] | None = None,
) -> npt.NDArray[np.bool_]:
    """Latch ego contacts with the replayed others at step k ([B, n_o]; copy if changed);
    ``poses``: their [B, n_o] x, y, yaw where the engine moves some of them (reacting
    cars, vei.sim.traffic), else their recording."""
    if hit.shape[1] == 0:
        return hit
    act = np.flatnonzero(arrays.other_active[k])
    if act.size == 0:
        return hit
    reach = 0.5 * (
        np.hypot(arrays.ego_length_m, arrays.ego_width_m)
        + np.hypot(arrays.other_length_m, arrays.other_width_m)
    )
    out = hit
    for j in act:
        if poses is None:
            qx, qy, qyaw = (
                arrays.other_x_m[k, j],
                arrays.other_y_m[k, j],
                arrays.other_yaw_rad[k, j],
            )
        else:
            qx, qy, qyaw = poses[0][:, j], poses[1][:, j], poses[2][:, j]
        dx = qx - ex
        dy = qy - ey
        cand = np.flatnonzero((dx * dx + dy * dy <= reach[j] ** 2) & ~hit[:, j])
        if cand.size == 0:
            continue
        if poses is not None:
            qx, qy, qyaw = qx[cand], qy[cand], qyaw[cand]
        ov = boxes_overlap(
            ex[cand], ey[cand], eyaw[cand], arrays.ego_length_m, arrays.ego_width_m,
            qx, qy, qyaw, arrays.other_length_m[j], arrays.other_width_m[j],
        )  # fmt: skip
        if ov.any():
            if out is hit:
                out = hit.copy()
            out[cand[ov], j] = True
    return out


def initial_contact_state(b: int, n_others: int, n_cars: int) -> dict[str, np.ndarray]:
    """The contact fields at k = 0 (nothing touched yet)."""
    return {
        "rider_hit_other": np.zeros((b, n_others), dtype=bool),
        "car_hit": np.zeros((b, n_cars), dtype=bool),
        "car_hit_with": np.full((b, n_cars), -1, dtype=np.int32),
        "sec_count": np.zeros(b, dtype=np.int32),
        "sec_first_t_s": np.full(b, np.inf),  # none yet (no NaN in the state)
        "sec_striker": np.full(b, -1, dtype=np.int32),
        "sec_struck": np.full(b, -1, dtype=np.int32),
        "sec_max_speed_mps": np.zeros(b),
        "rear_end": np.zeros(b, dtype=bool),
    }


def others_now(
    arrays: Any,
    k: int,
    b: int,
    cars: dict[str, np.ndarray] | None = None,
    peds: dict[str, np.ndarray] | None = None,
) -> tuple[FloatArray, ...]:
    """[B, n_o] x, y, yaw, vx, vy of every replayed other at step k: reacting cars and
    pedestrians where the engine moves them (``cars`` / ``peds``: their SimState fields at
    k where the block moves them, else None: their recording)."""
    ox = np.broadcast_to(arrays.other_x_m[k], (b, arrays.other_x_m.shape[1])).copy()
    oy = np.broadcast_to(arrays.other_y_m[k], ox.shape).copy()
    oyaw = np.broadcast_to(arrays.other_yaw_rad[k], ox.shape).copy()
    osp = np.broadcast_to(arrays.other_speed_mps[k], ox.shape).copy()
    tr = arrays.traffic
    if cars is not None and tr.n:
        ox[:, tr.idx] = cars["car_x_m"]
        oy[:, tr.idx] = cars["car_y_m"]
        oyaw[:, tr.idx] = cars["car_yaw_rad"]
        osp[:, tr.idx] = cars["car_v_mps"]
    if cars is not None and tr.n:  # a replaying car: its recorded speed
        rec = np.broadcast_to(arrays.other_speed_mps[k, tr.idx], osp[:, tr.idx].shape)
        osp[:, tr.idx] = np.where(cars["car_mode"] > traffic_core.REACTING, osp[:, tr.idx], rec)
    ovx, ovy = osp * np.cos(oyaw), osp * np.sin(oyaw)
    pd_ = arrays.peds
    if peds is not None and pd_.n:
        ox[:, pd_.idx], oy[:, pd_.idx] = peds["ped_x_m"], peds["ped_y_m"]
        ovx[:, pd_.idx], ovy[:, pd_.idx] = peds["ped_vx_mps"], peds["ped_vy_mps"]
        walking = np.hypot(ovx[:, pd_.idx], ovy[:, pd_.idx]) > 0.05
        oyaw[:, pd_.idx] = np.where(
            walking, np.arctan2(ovy[:, pd_.idx], ovx[:, pd_.idx]), oyaw[:, pd_.idx]
        )
    return ox, oy, oyaw, ovx, ovy


def _strike(
    pa: tuple[FloatArray, FloatArray], va: tuple[FloatArray, FloatArray],
    pb: tuple[FloatArray, FloatArray], vb: tuple[FloatArray, FloatArray],
) -> tuple[npt.NDArray[np.bool_], FloatArray]:  # fmt: skip
    """(a strikes b [n], impact speed [n] [m/s]) of contacts between a and b."""
    dx, dy = pb[0] - pa[0], pb[1] - pa[1]
    d = np.maximum(np.hypot(dx, dy), 1e-9)
    ca = (va[0] * dx + va[1] * dy) / d
    cb = -(vb[0] * dx + vb[1] * dy) / d
    return ca >= cb, np.hypot(va[0] - vb[0], va[1] - vb[1])


def record(
    out: dict[str, np.ndarray],
    rows: npt.NDArray[np.intp],
    t_s: float,
    a_code: Any,
    b_code: Any,
    a_strikes: npt.NDArray[np.bool_],
    speed: FloatArray,
    rear: npt.NDArray[np.bool_] | None = None,
) -> None:
    """Count new contacts of the variants ``rows`` (one each) into the summaries of ``out``."""
    if rows.size == 0:
        return
    striker = np.where(a_strikes, a_code, b_code)
    struck = np.where(a_strikes, b_code, a_code)
    first = out["sec_count"][rows] == 0
    fr = rows[first]
    out["sec_first_t_s"][fr] = t_s
    out["sec_striker"][fr] = np.broadcast_to(striker, rows.shape)[first]
    out["sec_struck"][fr] = np.broadcast_to(struck, rows.shape)[first]
    out["sec_count"][rows] += 1
    out["sec_max_speed_mps"][rows] = np.fmax(out["sec_max_speed_mps"][rows], speed)
    if rear is not None:
        out["rear_end"][rows] |= rear


def contact_step(
    st: Any, new: dict[str, Any], arrays: Any, on: Any, peds_on: Any = False
) -> dict[str, np.ndarray]:
    """The contact fields at step k + 1 from the new poses.

    Args:
        st: SimState at step k (the latches before). new: the step's new SimState fields
            (ego_*, rider_*, hit_other, extra_*, car_* at k + 1; hit_other already holds the
            ego's contacts with the others at their engine poses).
        arrays: ScenarioArrays. on: the block's cars_react (True / False / [b] mask);
            peds_on: its peds_sfm (the pedestrians' engine poses).
    Returns:
        The new CONTACT_FIELDS (fresh arrays) and, where a reacting car touched something,
        its updated ``car_mode`` / ``car_v_mps`` (stopped) in the same dict.
    """
    k1 = st.k + 1
    t = float(arrays.t_s[min(k1, arrays.t_s.size - 1)])
    out = {f: getattr(st, f).copy() for f in CONTACT_FIELDS}
    b = st.ego_x_m.shape[0]
    n_o = arrays.other_x_m.shape[1]
    tr = arrays.traffic
    cars = new if tr.n and on is not False else None
    peds = new if arrays.peds.n and peds_on is not False else None
    kk = min(k1, arrays.t_s.size - 1)
    ox, oy, oyaw, _, _ = others_now(arrays, kk, b, cars, peds)  # positions at k + 1
    car_f = ("car_x_m", "car_y_m", "car_yaw_rad", "car_v_mps", "car_mode")
    ped_f = ("ped_x_m", "ped_y_m", "ped_vx_mps", "ped_vy_mps")
    cars0 = {f: getattr(st, f) for f in car_f} if cars is not None else None
    peds0 = {f: getattr(st, f) for f in ped_f} if peds is not None else None
    _, _, _, ovx, ovy = others_now(arrays, st.k, b, cars0, peds0)  # velocities at k
    act = np.broadcast_to(arrays.other_active[kk], (b, n_o))
    ex, ey, eyaw = new["ego_x_m"], new["ego_y_m"], new["ego_yaw_rad"]
    evx = st.ego_v_mps * np.cos(st.ego_yaw_rad)
    evy = st.ego_v_mps * np.sin(st.ego_yaw_rad)
    rx, ry, ryaw, ract = (
        new["rider_x_m"],
        new["rider_y_m"],
        new["rider_yaw_rad"],
        new["rider_active"],
    )
    rvx = st.rider_speed_mps * np.cos(st.rider_yaw_rad)
    rvy = st.rider_speed_mps * np.sin(st.rider_yaw_rad)
    cols = np.arange(b)
    # the ego's new contacts with the others (latched by the engine) and extra riders
    fresh = new["hit_other"] & ~st.hit_other
    for j in np.flatnonzero(fresh.any(axis=0)):
        rows = np.flatnonzero(fresh[:, j])
        a_st, sp = _strike((ex[rows], ey[rows]), (evx[rows], evy[rows]),
                           (ox[rows, j], oy[rows, j]), (ovx[rows, j], ovy[rows, j]))  # fmt: skip
        # rear-end: a vehicle strikes the ego from behind (its centre behind the ego's rear
        # bumper), heading its way (within 30 deg)
        along = (ox[rows, j] - ex[rows]) * np.cos(eyaw[rows]) + (oy[rows, j] - ey[rows]) * np.sin(
            eyaw[rows]
        )
        behind = along < -0.5 * arrays.ego_length_m
        same = np.cos(oyaw[rows, j] - eyaw[rows]) > np.cos(np.pi / 6)
        rear = ~a_st & behind & same & (arrays.other_categories[j] == "vehicle")
        record(out, rows, t, 0, 2 + j, a_st, sp, rear)
    if "extra_hit" in new and new["extra_hit"].shape[1]:
        fresh_x = new["extra_hit"] & ~st.extra_hit
        for m in np.flatnonzero(fresh_x.any(axis=0)):
            rows = np.flatnonzero(fresh_x[:, m])
            xs = st.extra_speed_mps[rows, m]
            xy = st.extra_yaw_rad[rows, m]
            a_st, sp = _strike((ex[rows], ey[rows]), (evx[rows], evy[rows]),
                               (new["extra_x_m"][rows, m], new["extra_y_m"][rows, m]),
                               (xs * np.cos(xy), xs * np.sin(xy)))  # fmt: skip
            record(out, rows, t, 0, 2 + n_o + m, a_st, sp)
    # the rider's contacts with the others
    reach = 0.5 * (np.hypot(arrays.rider_length_m, arrays.rider_width_m)
                   + np.hypot(arrays.other_length_m, arrays.other_width_m))  # fmt: skip
    near = act & ract[:, None] & ~out["rider_hit_other"]
    near &= (ox - rx[:, None]) ** 2 + (oy - ry[:, None]) ** 2 <= reach[None, :] ** 2
    for j in np.flatnonzero(near.any(axis=0)):
        rows = np.flatnonzero(near[:, j])
        ov = boxes_overlap(rx[rows], ry[rows], ryaw[rows], arrays.rider_length_m, arrays.rider_width_m,
                           ox[rows, j], oy[rows, j], oyaw[rows, j], arrays.other_length_m[j],
                           arrays.other_width_m[j])  # fmt: skip
        rows = rows[ov]
        if rows.size:
            out["rider_hit_other"][rows, j] = True
            a_st, sp = _strike((rx[rows], ry[rows]), (rvx[rows], rvy[rows]),
                               (ox[rows, j], oy[rows, j]), (ovx[rows, j], ovy[rows, j]))  # fmt: skip
            record(out, rows, t, 1, 2 + j, a_st, sp)
    if tr.n and on is not False:
        _car_contacts(new, arrays, out, (ox, oy, oyaw, ovx, ovy, act), t, cols)
    return out


def _car_contacts(
    new: dict[str, Any], arrays: Any, out: dict[str, np.ndarray], others: tuple, t: float, cols: Any
) -> None:
    """Contacts of the driven reacting cars with any other; a car that touched anything
    (the ego, the rider, another other) stops."""
    tr = arrays.traffic
    ox, oy, oyaw, ovx, ovy, act = others
    mode = new["car_mode"]
    hit_any = new["hit_other"][:, tr.idx] | out["rider_hit_other"][:, tr.idx]
    for j, oj in enumerate(tr.idx):
        driven = (mode[:, j] == traffic_core.IDM) & act[:, oj]
        for q in range(ox.shape[1]):
            if q == oj:
                continue
            rr = 0.5 * (np.hypot(tr.length_m[j], tr.width_m[j])
                        + np.hypot(arrays.other_length_m[q], arrays.other_width_m[q]))  # fmt: skip
            cand = driven & act[:, q] & ~out["car_hit"][:, j]
            cand &= (ox[:, q] - ox[:, oj]) ** 2 + (oy[:, q] - oy[:, oj]) ** 2 <= rr * rr
            rows = np.flatnonzero(cand)
            if rows.size == 0:
                continue
            ov = boxes_overlap(ox[rows, oj], oy[rows, oj], oyaw[rows, oj], tr.length_m[j], tr.width_m[j],
                               ox[rows, q], oy[rows, q], oyaw[rows, q], arrays.other_length_m[q],
                               arrays.other_width_m[q])  # fmt: skip
            rows = rows[ov]
            if rows.size == 0:
                continue
            out["car_hit"][rows, j] = True
            out["car_hit_with"][rows, j] = q
            # a pair of reacting cars is counted once (by the first of the two)
            count = rows[~out["car_hit"][rows, list(tr.idx).index(q)]] if q in tr.idx else rows
            a_st, sp = _strike((ox[count, oj], oy[count, oj]), (ovx[count, oj], ovy[count, oj]),
                               (ox[count, q], oy[count, q]), (ovx[count, q], ovy[count, q]))  # fmt: skip
            record(out, count, t, 2 + oj, 2 + q, a_st, sp)
        stop = (out["car_hit"][:, j] | hit_any[:, j]) & (mode[:, j] == traffic_core.IDM)
        if stop.any():
            mode[stop, j] = traffic_core.STOPPED
            new["car_v_mps"][stop, j] = 0.0
    del cols
