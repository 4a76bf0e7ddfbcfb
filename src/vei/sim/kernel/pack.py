"""Pack a prepared scenario, its variants and their start state into the compiled kernel's
argument groups, and unpack what it wrote (importable without numba).

The kernel (:mod:`vei.sim.kernel.loop`) takes one tuple per part of the world; a part the
run does not use is passed as ``None`` and is then not compiled (:class:`Features` says
which parts a run uses). Shapes: B variants, T steps, ``no`` other road users, R extra
riders, C reacting cars, K conflicts; tables are values then slopes per grid cell.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

from vei.sim.kernel.layout import BOOL_FIELDS, FLOAT_FIELDS, N_OUT
from vei.sim.riders import EXTRA_BOOL_FIELDS, EXTRA_FLOAT_FIELDS, RIDER_COLUMNS

_F = np.float64


class Features(NamedTuple):
    """The optional parts of the world a kernel run uses; one compiled specialisation per
    combination (:func:`vei.sim.kernel.run`).

    Attributes:
        others: replayed other road users (contacts, the ego's hits of them).
        riders: extra social-force riders, or the several-rider repulsion mode.
        decisions: a social-force rider that decides to yield or go at its conflicts.
        traffic: recorded cars that react (IDM).
        metrics: the fused metrics scored inside the kernel (simulate_metrics).
        policy: ego policies run in the kernel (``aeb``, ``idm``, users' compiled ones:
            vei.sim.kernel.policy).
        user: one of them is a user's compiled function (vei.policy.compiled): the run
            takes it as a function value and goes through the serial shell on threads.
    """

    others: bool = False
    riders: bool = False
    decisions: bool = False
    traffic: bool = False
    metrics: bool = False
    policy: bool = False
    user: bool = False

    @property
    def name(self) -> str:
        """'base' or the parts joined by '+', e.g. 'others+metrics' (stamps, messages)."""
        on = [f for f in self._fields if getattr(self, f)]
        return "+".join(on) if on else "base"


#: Every part on (the warm-up of a machine that will run anything; benchmarks).
ALL_FEATURES = Features(True, True, True, True, True, True, True)


def features_of(arrays: Any, params: Any, scored: bool) -> Features:
    """The parts of the world a run of ``params`` [B] on ``arrays`` uses (scored: the
    fused metrics are computed in the kernel)."""
    others = len(arrays.other_ids) > 0
    riders = arrays.riders.n > 0 or bool(arrays.riders.enabled)
    decide = np.asarray(params.decide, dtype=bool) & np.asarray(params.rider_sfm, dtype=bool)
    any_conflict = arrays.conflicts.n > 0 or any(c.n for c in arrays.riders.conflicts)
    decisions = any_conflict and bool(decide.any())
    react = np.asarray(params.cars_react, dtype=bool)
    traffic = others and arrays.traffic.n > 0 and bool(react.any())
    policy = bool((np.asarray(params.ego_mode) == 3).any())  # vei.sim.state.EGO_POLICY
    user = False
    if policy:
        from vei.sim.kernel.policy_pack import kernel_kinds

        user = kernel_kinds(params)[1] is not None
    return Features(others, riders, decisions, traffic, bool(scored), policy, user)


def path_rows(path: Any) -> np.ndarray:
    """[10, N] x, y, yaw, cos, sin of a path on its arc grid, then their slopes."""
    vals = path._values  # type: ignore[attr-defined]
    slopes = path._slopes  # type: ignore[attr-defined]
    names = ("x", "y", "yaw", "cos", "sin")
    return np.ascontiguousarray(np.stack([vals[n] for n in names] + [slopes[n] for n in names]))


def table_rows(table: Any, names: tuple[str, ...]) -> np.ndarray:
    """[2 len(names), M] the columns ``names`` of a time table, then their slopes."""
    cols = table._cols  # type: ignore[attr-defined]
    slopes = table._slopes  # type: ignore[attr-defined]
    return np.ascontiguousarray(np.stack([cols[n] for n in names] + [slopes[n] for n in names]))


def ego_group(arrays: Any) -> tuple[Any, ...]:
    """(path [10, N], s0, ds, recorded s / speed table [4, M], t0, dt, length, width)."""
    p, et = arrays.ego_path, arrays.ego_track
    return (
        path_rows(p), float(p.s_start_m), float(p.ds_m),
        table_rows(et, ("s_m", "speed_mps")), float(et.t0_s), float(et.dt_s),
        float(arrays.ego_length_m), float(arrays.ego_width_m),
    )  # fmt: skip


def rider_group(arrays: Any) -> tuple[Any, ...]:
    """The primary rider: (track [14, M], t0, dt, t_end, SFM entry time [s], path [10, N],
    s0, ds, length, end x, end y, rider length, width)."""
    tr, rp = arrays.rider_track, arrays.rider_path
    cols = ("x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps", "arc_m")
    return (
        table_rows(tr, cols), float(tr.t0_s), float(tr.dt_s), float(tr.t_end_s),
        float(arrays.rider_sfm_entry_s),
        path_rows(rp), float(rp.s_start_m), float(rp.ds_m), float(rp.length_m),
        float(rp.end_x_m), float(rp.end_y_m),
        float(arrays.rider_length_m), float(arrays.rider_width_m),
    )  # fmt: skip


def others_group(arrays: Any, state0: Any, b: int, tt: int) -> tuple[Any, ...]:
    """The replayed others: (x, y, yaw, speed [T, no], active [T, no], lengths, widths
    [no], vehicle [no], the ego's hit latches [B, no] (in and out), their series buffer
    [B, tt, no], the rider's hit latches in [B, no], out [B, no])."""
    no = len(arrays.other_ids)
    veh = np.array([cat == "vehicle" for cat in arrays.other_categories], dtype=np.bool_)
    h0 = np.ascontiguousarray(state0.hit_other.astype(np.uint8))
    oh = np.zeros((b, tt, no), dtype=np.uint8)
    oh[:, 0] = h0
    return (
        np.ascontiguousarray(arrays.other_x_m), np.ascontiguousarray(arrays.other_y_m),
        np.ascontiguousarray(arrays.other_yaw_rad), np.ascontiguousarray(arrays.other_speed_mps, _F),
        np.ascontiguousarray(arrays.other_active),
        np.ascontiguousarray(arrays.other_length_m, dtype=_F),
        np.ascontiguousarray(arrays.other_width_m, dtype=_F), veh,
        h0, oh, np.ascontiguousarray(state0.rider_hit_other.astype(np.uint8)),
        np.empty((b, no), dtype=np.uint8),
    )  # fmt: skip


def riders_group(arrays: Any, state0: Any, b: int, tt: int, record: bool) -> tuple[Any, ...]:
    """The extra riders (vei.sim.riders): R, tables padded to the longest [R, 14, M], their
    times, paths [R, 10, N], footprints, radii, recorded speeds, the primary's radius,
    the repulsion mode, the pedestrians' indices and radii, the state in [9, B, R] /
    [4, B, R], the series buffers [B, 5, tt, R] / [B, 2, tt, R] and the finals."""
    xr = arrays.riders
    n_x = xr.n
    m_max = max([t.data.shape[0] for t in xr.tracks], default=1)
    n_max = max([p.x_m.shape[0] for p in xr.paths], default=1)
    xtab = np.zeros((n_x, 14, m_max))
    xpath = np.zeros((n_x, 10, n_max))
    for j in range(n_x):
        rows = table_rows(xr.tracks[j], RIDER_COLUMNS)
        xtab[j, :, : rows.shape[1]] = rows
        prow = path_rows(xr.paths[j])
        xpath[j, :, : prow.shape[1]] = prow
    nf = len(EXTRA_FLOAT_FIELDS)
    xs0 = np.ascontiguousarray(
        np.stack([getattr(state0, f) for f in EXTRA_FLOAT_FIELDS]).astype(_F)
    ).reshape(nf, b, n_x)
    xb0 = np.ascontiguousarray(
        np.stack([getattr(state0, f) for f in EXTRA_BOOL_FIELDS]).astype(np.uint8)
    ).reshape(4, b, n_x)
    outx = np.zeros((b, 5, tt, n_x))
    outxb = np.zeros((b, 2, tt, n_x), dtype=np.uint8)
    if record and n_x:
        for j, f in enumerate(
            ("extra_x_m", "extra_y_m", "extra_yaw_rad", "extra_speed_mps", "extra_a_mps2")
        ):
            outx[:, j, 0, :] = getattr(state0, f)
        outxb[:, 0, 0, :] = state0.extra_active
        outxb[:, 1, 0, :] = state0.extra_hit
    return (
        n_x, xtab,
        np.array([t.t0_s for t in xr.tracks], _F), np.array([t.dt_s for t in xr.tracks], _F),
        np.array([t.t_end_s for t in xr.tracks], _F),
        np.array([t.data.shape[0] for t in xr.tracks], np.int64),
        np.array(xr.sfm_entry_s if xr.sfm_entry_s.size == n_x else [-np.inf] * n_x, _F),
        xpath,
        np.array([p.s_start_m for p in xr.paths], _F), np.array([p.ds_m for p in xr.paths], _F),
        np.array([p.x_m.shape[0] for p in xr.paths], np.int64),
        np.array([p.length_m for p in xr.paths], _F),
        np.array([p.end_x_m for p in xr.paths], _F), np.array([p.end_y_m for p in xr.paths], _F),
        np.ascontiguousarray(xr.length_m, _F), np.ascontiguousarray(xr.width_m, _F),
        np.ascontiguousarray(xr.radius_m, _F), np.ascontiguousarray(xr.median_speed_mps, _F),
        np.ascontiguousarray(xr.p99_speed_mps, _F), float(xr.primary_radius_m), bool(xr.enabled),
        np.ascontiguousarray(xr.ped_idx, np.int64), np.ascontiguousarray(xr.ped_radius_m, _F),
        xs0, xb0, outx, outxb, np.empty((nf, b, n_x)), np.empty((4, b, n_x), dtype=np.uint8),
    )  # fmt: skip


def decisions_group(arrays: Any) -> tuple[Any, ...]:
    """The conflicts of the decisions (vei.sim.decisions.Conflicts): the primary rider's K
    and its [K] arrays (zone exit, crossing along the rider's and the ego's path,
    half-lengths) [m], then the extra riders' the same way: their K [R] and [R, K_max]
    arrays padded with zeros (rows 6-11)."""
    c = arrays.conflicts
    xc = arrays.riders.conflicts or ()
    r = len(xc)
    km = max([x.n for x in xc], default=1) or 1
    pad = [np.zeros((r, km)) for _ in range(5)]
    for j, x in enumerate(xc):
        for a, src in zip(pad, (x.exit_m, x.s_rider_m, x.s_ego_m, x.hz_rider_m, x.hz_ego_m),
                          strict=True):  # fmt: skip
            a[j, : x.n] = src
    return (
        int(c.n), np.ascontiguousarray(c.exit_m, _F), np.ascontiguousarray(c.s_rider_m, _F),
        np.ascontiguousarray(c.s_ego_m, _F), np.ascontiguousarray(c.hz_rider_m, _F),
        np.ascontiguousarray(c.hz_ego_m, _F),
        np.array([x.n for x in xc], dtype=np.int64), *pad,
    )  # fmt: skip


def traffic_group(arrays: Any, state0: Any, b: int, tt: int) -> tuple[Any, ...]:
    """The reacting cars (vei.sim.traffic.Traffic): the scene, their state at k = 0, the
    series buffers [B, 4, tt, C], [B, tt, C] and the finals [6, B, C], [B, C] x 3."""
    from vei.sim.traffic import CAR_FLOAT_FIELDS

    tr = arrays.traffic
    c, no = tr.n, len(arrays.other_ids)
    tci = np.full(no, -1, dtype=np.int64)
    tci[tr.idx] = np.arange(c)
    cs0 = np.ascontiguousarray(
        np.stack([getattr(state0, n) for n in CAR_FLOAT_FIELDS]).astype(_F).reshape(6, b, c)
    )
    return (
        int(c), np.ascontiguousarray(tr.idx, np.int64), np.ascontiguousarray(tr.length_m, _F),
        np.ascontiguousarray(tr.width_m, _F), tci, np.ascontiguousarray(tr.ptab, _F),
        np.ascontiguousarray(tr.ps0, _F), np.ascontiguousarray(tr.pds, _F),
        np.ascontiguousarray(tr.pn, np.int64), np.ascontiguousarray(tr.s_rec_m, _F),
        np.ascontiguousarray(tr.v_rec_mps, _F), np.ascontiguousarray(tr.a_rec_mps2, _F),
        np.ascontiguousarray(tr.active), np.ascontiguousarray(tr.ego_s_rec_m, _F),
        np.ascontiguousarray(tr.ego_v_rec_mps, _F), np.ascontiguousarray(tr.mtab, _F),
        np.ascontiguousarray(tr.m0, _F), np.ascontiguousarray(tr.mn, np.int64),
        np.ascontiguousarray(tr.pair),
        cs0, np.ascontiguousarray(state0.car_mode, np.int64),
        np.ascontiguousarray(state0.car_hit.astype(np.uint8)),
        np.ascontiguousarray(state0.car_hit_with, np.int64),
        np.zeros((b, 4, tt, c)), np.zeros((b, tt, c), dtype=np.uint8),
        np.empty((6, b, c)), np.empty((b, c), dtype=np.int64), np.empty((b, c), dtype=np.uint8),
        np.empty((b, c), dtype=np.int64),
    )  # fmt: skip


def cars_final(
    state0: Any, group: tuple[Any, ...] | None, final: dict[str, Any], record: bool, tt: int
) -> dict | None:
    """Put the reacting cars' finals into ``final`` and return their series (record) as a
    dict of [B, T, C] arrays. Without a traffic group (no car reacts in this batch) the
    cars keep their start state, as the NumPy step keeps it."""
    from vei.sim.traffic import CAR_FLOAT_FIELDS

    if group is None:
        for n in (*CAR_FLOAT_FIELDS, "car_mode", "car_hit", "car_hit_with"):
            final[n] = np.array(getattr(state0, n), copy=True)
        if not record:
            return None
        rep = {
            "car_x_m": state0.car_x_m, "car_y_m": state0.car_y_m,
            "car_yaw_rad": state0.car_yaw_rad, "car_speed_mps": state0.car_v_mps,
        }  # fmt: skip
        series = {n: np.repeat(np.asarray(v, _F)[:, None, :], tt, axis=1) for n, v in rep.items()}
        series["car_mode"] = np.repeat(np.asarray(state0.car_mode, np.int8)[:, None, :], tt, axis=1)
        return series
    oc, ocm, cfs, cfm, cfh, cfw = group[-6:]
    for j, n in enumerate(CAR_FLOAT_FIELDS):
        final[n] = cfs[j].copy()
    final["car_mode"] = cfm.astype(np.int8)
    final["car_hit"] = cfh.astype(bool)
    final["car_hit_with"] = cfw.astype(np.int32)
    if not record:
        return None
    for j, src in enumerate(("car_x_m", "car_y_m", "car_yaw_rad", "car_v_mps")):
        oc[:, j, 0, :] = getattr(state0, src)
    ocm[:, 0, :] = state0.car_mode
    return {
        "car_x_m": oc[:, 0], "car_y_m": oc[:, 1], "car_yaw_rad": oc[:, 2],
        "car_speed_mps": oc[:, 3], "car_mode": ocm.astype(np.int8),
    }  # fmt: skip


def state_group(state0: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(S0 [20, B] floats, B0 [4, B] uint8, SEC0 [6, B] the secondary summaries)."""
    s0 = np.ascontiguousarray(
        np.stack([np.asarray(getattr(state0, f), dtype=_F) for f in FLOAT_FIELDS])
    )
    b0 = np.ascontiguousarray(
        np.stack([np.asarray(getattr(state0, f)).astype(np.uint8) for f in BOOL_FIELDS])
    )
    sec0 = np.stack(
        [state0.sec_count.astype(_F), state0.sec_first_t_s, state0.sec_striker.astype(_F),
         state0.sec_struck.astype(_F), state0.sec_max_speed_mps, state0.rear_end.astype(_F)]
    )  # fmt: skip
    return s0, b0, np.ascontiguousarray(sec0, dtype=_F)


def out_group(state0: Any, b: int, tt: int, hist_len: int, record: bool) -> tuple[Any, ...]:
    """(OUT [B, N_OUT, tt], OB [B, 4, tt] uint8, FS [20, B], FB [4, B], FH [4, H, B],
    collision time [B], least centre distance [B], SECF [6, B]); the first step of the
    series filled from ``state0`` when recording."""
    out = np.empty((b, N_OUT, tt))
    outb = np.zeros((b, 4, tt), dtype=np.uint8)  # cap, rider active, collided, decision
    if record:
        first = (
            state0.ego_s_m, state0.ego_x_m, state0.ego_y_m, state0.ego_yaw_rad, state0.ego_v_mps,
            state0.ego_a_mps2, state0.ego_cmd, state0.rider_x_m, state0.rider_y_m,
            state0.rider_yaw_rad, state0.rider_speed_mps, state0.rider_vx_mps,
            state0.rider_vy_mps, state0.rider_a_mps2,
        )  # fmt: skip
        for j, val in enumerate(first):
            out[:, j, 0] = val
        outb[:, 0, 0] = state0.cap_state
        outb[:, 1, 0] = state0.rider_active
        outb[:, 2, 0] = state0.collided
        outb[:, 3, 0] = state0.rider_decision
    return (
        out, outb, np.empty((len(FLOAT_FIELDS), b)), np.empty((len(BOOL_FIELDS), b), np.uint8),
        np.empty((4, hist_len, b)), np.empty(b), np.empty(b), np.empty((6, b)),
    )  # fmt: skip


def secondary_final(secf: np.ndarray, final: dict[str, Any]) -> None:
    """The secondary-collision summaries [6, B] into ``final`` (SimState fields)."""
    final["sec_count"] = secf[0].astype(np.int32)
    final["sec_first_t_s"] = secf[1].copy()
    final["sec_striker"] = secf[2].astype(np.int32)
    final["sec_struck"] = secf[3].astype(np.int32)
    final["sec_max_speed_mps"] = secf[4].copy()
    final["rear_end"] = secf[5] > 0.5
