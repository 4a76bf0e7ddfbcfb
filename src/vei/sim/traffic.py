"""Recorded cars that react to the ego: their tables (once per scenario) and their NumPy step.

:func:`prepare_traffic` picks the *reacting cars*: the recorded vehicles among the replayed
others whose path shares or crosses the ego's (comes within half their widths plus
:data:`NEAR_M` of it). For each: its path (through its recorded positions, a wait by its
first point), its recorded arc length, speed and acceleration at every engine step, and
where every possible leader lies on that path (the ego along the ego's path, every other
reacting car along its own: a table on the leader's arc length of the nearest point on the
car's path, the lateral offset, the heading difference's cosine and the leader's
half-extent along the car's path, :func:`leader_maps`).

:func:`traffic_step` advances them by one step for B variants with the laws of
:mod:`vei.models.traffic_core` (the compiled kernel runs the same on scalars,
:mod:`vei.sim.kernel.traffic`): a car replays its recording until the IDM towards its
actual leader (the nearest road user on its path ahead) asks ``trigger`` more braking
than towards its recorded leader; after its reaction time it drives along its path by
``min(intent, IDM)``; a contact stops it.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.models import traffic_core as core
from vei.models.drivable_path import dwell_mask, recorded_arc_length
from vei.models.ego import PathTable, build_path

FloatArray = npt.NDArray[np.float64]
#: A vehicle reacts when its recorded path comes within half the two widths plus this [m]
#: of the ego's recorded path (its lane, or crossing it).
NEAR_M = 1.0
#: Grid step [m] of the leader maps.
MAP_DS_M = 0.5
#: Straight extension [m] of a car's path beyond its recorded ends.
CAR_PATH_EXTEND_M = 100.0
#: Lateral tolerance [m] beyond half the two widths within which a leader is on the path.
LAT_MARGIN_M = 0.0


@dataclass(frozen=True)
class Traffic:
    """The reacting cars of a scenario (C of them; C = 0: none).

    Attributes:
        idx: [C] their indices among the replayed others. length_m, width_m: [C].
        paths: their PathTables. ptab: [C, 10, N] the paths' rows (x y yaw cos sin and
            slopes, padded), ps0, pds: [C] grid start and step [m], pn: [C] entries.
        s_rec_m, v_rec_mps, a_rec_mps2: [T, C] recorded arc length along the path [m],
            speed [m/s] and acceleration [m/s^2] at the engine steps (held outside the span).
        active: [T, C] present (the replayed others' span).
        ego_s_rec_m, ego_v_rec_mps: [T] the recorded ego's arc length along the ego's
            path [m] and speed [m/s] (its recording, held after its end).
        mtab: [C + 1, C, 4, M] leader maps: leader l (0 = the ego, 1 + k = car k) onto car
            j, on the leader's arc grid m0[l] + i MAP_DS_M (i < mn[l]): the nearest arc on
            j's path [m], lateral offset [m], cosine of the heading difference, the
            leader's half-extent along j's path [m]. pair: [C + 1, C] leader l ever comes
            onto j's path.
    """

    idx: npt.NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    length_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    width_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    paths: tuple[PathTable, ...] = ()
    ptab: FloatArray = field(default_factory=lambda: np.zeros((0, 10, 1)))
    ps0: FloatArray = field(default_factory=lambda: np.zeros(0))
    pds: FloatArray = field(default_factory=lambda: np.zeros(0))
    pn: npt.NDArray[np.int64] = field(default_factory=lambda: np.zeros(0, dtype=np.int64))
    s_rec_m: FloatArray = field(default_factory=lambda: np.zeros((1, 0)))
    v_rec_mps: FloatArray = field(default_factory=lambda: np.zeros((1, 0)))
    a_rec_mps2: FloatArray = field(default_factory=lambda: np.zeros((1, 0)))
    active: npt.NDArray[np.bool_] = field(default_factory=lambda: np.zeros((1, 0), dtype=bool))
    ego_s_rec_m: FloatArray = field(default_factory=lambda: np.zeros(1))
    ego_v_rec_mps: FloatArray = field(default_factory=lambda: np.zeros(1))
    mtab: FloatArray = field(default_factory=lambda: np.zeros((1, 0, 4, 1)))
    m0: FloatArray = field(default_factory=lambda: np.zeros(1))
    mn: npt.NDArray[np.int64] = field(default_factory=lambda: np.zeros(1, dtype=np.int64))
    pair: npt.NDArray[np.bool_] = field(default_factory=lambda: np.zeros((1, 0), dtype=bool))

    @property
    def n(self) -> int:
        """C, the number of reacting cars."""
        return int(self.idx.shape[0])


def car_path(x: FloatArray, y: FloatArray, t: FloatArray, yaw0: float, where: str) -> PathTable:
    """The path of a recorded car: through its positions (a wait by its first point, points
    at least 0.2 m apart), extended straight by CAR_PATH_EXTEND_M at both ends."""
    dwell = dwell_mask(x, y, t)
    keep = ~dwell | np.concatenate([[True], ~dwell[:-1]])
    xs, ys = x[keep], y[keep]
    k = [0]
    for i in range(1, xs.size):
        if (xs[i] - xs[k[-1]]) ** 2 + (ys[i] - ys[k[-1]]) ** 2 >= 0.04:
            k.append(i)
    return build_path(xs[k], ys[k], yaw_hint_rad=yaw0, extend_m=CAR_PATH_EXTEND_M, where=where)


def leader_map(
    leader: PathTable, car: PathTable, l_len: float, l_wid: float, tree: Any = None
) -> tuple[FloatArray, float, int]:
    """[4, M] where the leader's path lies on the car's (see :class:`Traffic` mtab), its
    grid start [m] and size M (``tree``: a cKDTree of the car's grid points, or None)."""
    from scipy.spatial import cKDTree

    s = np.arange(
        leader.s_start_m, leader.s_start_m + leader.ds_m * (leader.x_m.size - 1), MAP_DS_M
    )
    lx, ly, lyaw = leader.lookup(s)
    tree = tree if tree is not None else cKDTree(np.column_stack([car.x_m, car.y_m]))
    _, i = tree.query(np.column_stack([lx, ly]))
    sig = car.s_start_m + i * car.ds_m
    ci, cw = car.index(sig)
    px, py, pc, ps, pyaw = car.values_at(ci, cw, "x", "y", "cos", "sin", "yaw")
    along = (lx - px) * pc + (ly - py) * ps
    sig = sig + along
    lat = -(lx - px) * ps + (ly - py) * pc
    d = lyaw - pyaw
    cos_d = np.cos(d)
    ext = 0.5 * (l_len * np.abs(cos_d) + l_wid * np.abs(np.sin(d)))
    return np.stack([sig, lat, cos_d, ext]), float(s[0]), int(s.size)


def _near(a: PathTable, bx: FloatArray, by: FloatArray) -> float:
    """Smallest distance [m] of the points (bx, by) to the recorded part of path a."""
    from scipy.spatial import cKDTree

    i0 = int(round(-a.s_start_m / a.ds_m))
    i1 = i0 + int(round(a.length_m / a.ds_m)) + 1
    d, _ = cKDTree(np.column_stack([a.x_m[i0:i1], a.y_m[i0:i1]])).query(np.column_stack([bx, by]))
    return float(d.min()) if d.size else np.inf


def prepare_traffic(
    scenario: Any,
    others: list[Any],
    t_s: FloatArray,
    ego_path: PathTable,
    ego_track: Any,
    ego_length_m: float,
    ego_width_m: float,
    where: str,
) -> Traffic:
    """The reacting cars of a scenario (see the module): the vehicles among ``others`` (the
    replayed others' AgentInfo, engine order) near the ego's path."""
    cars, paths, srec, vrec, arec, act = [], [], [], [], [], []
    for j, a in enumerate(others):
        if a.category != "vehicle":
            continue
        tr = scenario.track(a.agent_id)
        x = tr["x_m"].to_numpy(dtype=np.float64)
        y = tr["y_m"].to_numpy(dtype=np.float64)
        tt = tr["t_s"].to_numpy(dtype=np.float64)
        if x.size < 2 or _near(ego_path, x, y) > 0.5 * (ego_width_m + a.width_m) + NEAR_M:
            continue
        path = car_path(x, y, tt, float(tr["yaw_rad"].iloc[0]), f"{where}: {a.agent_id}")
        s = recorded_arc_length(path, x, y)
        on = (t_s >= tt[0] - 1e-9) & (t_s <= tt[-1] + 1e-9)
        sk = np.interp(t_s, tt, s)
        vk = np.gradient(sk, t_s) if t_s.size > 1 else np.zeros_like(sk)
        ak = np.gradient(vk, t_s) if t_s.size > 1 else np.zeros_like(sk)
        cars.append(j)
        paths.append(path)
        srec.append(sk)
        vrec.append(np.where(on, vk, 0.0))
        arec.append(np.where(on, ak, 0.0))
        act.append(on)
    c = len(cars)
    if c == 0:
        return Traffic()
    length = np.array([others[j].length_m for j in cars], dtype=np.float64)
    width = np.array([others[j].width_m for j in cars], dtype=np.float64)
    n_max = max(p.x_m.size for p in paths)
    ptab = np.zeros((c, 10, n_max))
    for j, p in enumerate(paths):
        vals, slopes = p._values, p._slopes  # type: ignore[attr-defined]
        names = ("x", "y", "yaw", "cos", "sin")
        ptab[j, :, : p.x_m.size] = np.stack(
            [vals[nm] for nm in names] + [slopes[nm] for nm in names]
        )
    ti, tw = ego_track.index(t_s)
    es, ev = ego_track.values_at(ti, tw, "s_m", "speed_mps")
    leaders = [(ego_path, ego_length_m, ego_width_m)] + [
        (p, float(length[k]), float(width[k])) for k, p in enumerate(paths)
    ]
    from scipy.spatial import cKDTree

    trees = [cKDTree(np.column_stack([p.x_m, p.y_m])) for p in paths]
    maps = [
        [leader_map(lp, paths[j], ll, lw, trees[j]) for j in range(c)] for lp, ll, lw in leaders
    ]
    m_max = max(m[0].shape[1] for row in maps for m in row)
    mtab = np.zeros((c + 1, c, 4, m_max))
    mtab[:, :, 1, :] = np.inf  # padding: off the path
    pair = np.zeros((c + 1, c), dtype=bool)
    m0 = np.zeros(c + 1)
    mn = np.zeros(c + 1, dtype=np.int64)
    for li, row in enumerate(maps):
        for j, (tab, s0, n) in enumerate(row):
            mtab[li, j, :, :n] = tab
            m0[li], mn[li] = s0, n
            lw = leaders[li][2]
            pair[li, j] = (li != j + 1) and bool((np.abs(tab[1]) <= 0.5 * (width[j] + lw)).any())
    return Traffic(
        idx=np.asarray(cars, dtype=np.intp), length_m=length, width_m=width, paths=tuple(paths),
        ptab=ptab, ps0=np.array([p.s_start_m for p in paths]), pds=np.array([p.ds_m for p in paths]),
        pn=np.array([p.x_m.size for p in paths], dtype=np.int64),
        s_rec_m=np.column_stack(srec), v_rec_mps=np.column_stack(vrec),
        a_rec_mps2=np.column_stack(arec), active=np.column_stack(act),
        ego_s_rec_m=np.asarray(es, dtype=np.float64), ego_v_rec_mps=np.asarray(ev, dtype=np.float64),
        mtab=mtab, m0=m0, mn=mn, pair=pair,
    )  # fmt: skip


# --------------------------------------------------------------------------------------
# NumPy step
# --------------------------------------------------------------------------------------
#: SimState fields of the reacting cars ([B, C]): floats, then the int8 mode.
CAR_FLOAT_FIELDS = ("car_s_m", "car_v_mps", "car_timer_s", "car_x_m", "car_y_m", "car_yaw_rad")


def initial_traffic_state(arrays: Any, b: int) -> dict[str, np.ndarray]:
    """The reacting cars' SimState fields at k = 0 ([B, C]): replaying, at their recorded
    arc length, speed and pose."""
    tr: Traffic = arrays.traffic
    c = tr.n
    out: dict[str, np.ndarray] = {f: np.zeros((b, c)) for f in CAR_FLOAT_FIELDS}
    out["car_mode"] = np.zeros((b, c), dtype=np.int8)
    if c:
        out["car_s_m"][:] = tr.s_rec_m[0]
        out["car_v_mps"][:] = tr.v_rec_mps[0]
        out["car_x_m"][:] = arrays.other_x_m[0, tr.idx]
        out["car_y_m"][:] = arrays.other_y_m[0, tr.idx]
        out["car_yaw_rad"][:] = arrays.other_yaw_rad[0, tr.idx]
    return out


def map_at(tr: Traffic, leader: int, car: int, s_m: FloatArray) -> FloatArray:
    """[4, B] the leader map (leader 0 = ego, 1 + k = car k) onto ``car`` at the leader's
    arc lengths ``s_m`` [B] (linear interpolation, clamped)."""
    n = int(tr.mn[leader])
    f = np.clip((np.asarray(s_m, dtype=np.float64) - tr.m0[leader]) / MAP_DS_M, 0.0, n - 1.0)
    i = np.minimum(f.astype(np.intp), max(n - 2, 0))
    w = f - i
    row = tr.mtab[leader, car]
    return row[:, i] + w * (row[:, np.minimum(i + 1, n - 1)] - row[:, i])


def _nearest_leader(
    tr: Traffic,
    j: int,
    own_s: FloatArray,
    ls: npt.NDArray[np.intp],
    lead: tuple[FloatArray, FloatArray, FloatArray],
    widths: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """(gap [B] [m], the leader's speed along j's path [B] [m/s]) of the nearest road user
    on car j's path ahead (+inf, 0: none) among the leaders ``ls`` [L] (0 = the ego, 1 + m
    = car m): ``lead`` = their arcs, speeds and presence [L, B], ``widths`` [L] [m]."""
    sl, v, present = lead
    if ls.size == 0:
        return np.full(own_s.shape, np.inf), np.zeros(own_s.shape)
    n = tr.mn[ls][:, None]
    f = np.clip((sl - tr.m0[ls][:, None]) / MAP_DS_M, 0.0, n - 1.0)
    i = np.minimum(f.astype(np.intp), np.maximum(n - 2, 0))
    w = f - i
    i1 = np.minimum(i + 1, n - 1)
    rows = tr.mtab[ls, j]  # [L, 4, M]
    li = np.arange(ls.size)[:, None]
    r0, r1 = rows[li, :, i], rows[li, :, i1]  # [L, B, 4]
    val = r0 + w[..., None] * (r1 - r0)
    sig, lat, cosd, ext = val[..., 0], val[..., 1], val[..., 2], val[..., 3]
    g = core.leader_gap_core(
        sig, lat, ext, own_s[None, :], 0.5 * tr.length_m[j], 0.5 * (tr.width_m[j] + widths[:, None])
    )
    g = np.where(present, g, np.inf)
    best = np.argmin(g, axis=0)
    cols = np.arange(own_s.shape[0])
    gap = g[best, cols]
    return gap, np.where(np.isfinite(gap), (v * cosd)[best, cols], 0.0)


def traffic_step(st: Any, arrays: Any, p: Any, on: Any, dt: float) -> dict[str, np.ndarray]:
    """Advance the reacting cars of one block by one step (leaders from the state at step k).

    Args:
        st: SimState at step k. arrays: ScenarioArrays (``traffic``, the others' replay).
        p: the block's VariantParams (car_* fields [b]). on: cars_react, True / mask [b].
        dt: step [s].
    Returns:
        The new car_* SimState fields ([b, C], fresh arrays).
    """
    tr: Traffic = arrays.traffic
    k = st.k
    mode = st.car_mode.copy()
    s, v, timer = st.car_s_m.copy(), st.car_v_mps.copy(), st.car_timer_s.copy()
    own_s = np.where(mode >= core.IDM, s, tr.s_rec_m[k])
    own_v = np.where(mode >= core.IDM, v, tr.v_rec_mps[k])
    b = mode.shape[0]
    c = tr.n
    pres = np.broadcast_to(tr.active[k][:, None], (c, b))
    act_s = np.vstack([st.ego_s_m[None, :], own_s.T])  # [C + 1, B] the leaders now
    act_v = np.vstack([st.ego_v_mps[None, :], own_v.T])
    rec_s = np.broadcast_to(
        np.concatenate([[tr.ego_s_rec_m[k]], tr.s_rec_m[k]])[:, None], (c + 1, b)
    )
    rec_v = np.broadcast_to(
        np.concatenate([[tr.ego_v_rec_mps[k]], tr.v_rec_mps[k]])[:, None], (c + 1, b)
    )
    present = np.vstack([np.ones((1, b), dtype=bool), pres])
    widths = np.concatenate([[arrays.ego_width_m], tr.width_m])
    idm = (
        p.car_v0_mps,
        p.car_headway_s,
        p.car_min_gap_m,
        p.car_accel_mps2,
        p.car_decel_mps2,
        p.car_delta,
    )
    new_mode = mode.copy()
    for j in range(c):
        if not tr.active[k, j]:
            continue
        ls = np.flatnonzero(tr.pair[:, j])
        ls = ls[ls != j + 1]
        gap_a, vl_a = _nearest_leader(
            tr, j, own_s[:, j], ls, (act_s[ls], act_v[ls], present[ls]), widths[ls]
        )
        own_r = np.full(b, tr.s_rec_m[k, j])
        gap_r, vl_r = _nearest_leader(
            tr, j, own_r, ls, (rec_s[ls], rec_v[ls], present[ls]), widths[ls]
        )
        a_act = core.idm_accel_core(own_v[:, j], vl_a, gap_a, *idm)
        a_rec = core.idm_accel_core(np.full(b, tr.v_rec_mps[k, j]), vl_r, gap_r, *idm)
        m = mode[:, j]
        notice = (m == core.REPLAY) & core.notices_core(a_act, a_rec, p.car_trigger_mps2) & on
        m = np.where(notice, core.REACTING, m)
        tm = np.where(notice, p.car_reaction_s, timer[:, j])
        react = m == core.REACTING
        tm = np.where(react, tm - dt, tm)
        go = react & (tm <= 1e-9)
        m = np.where(go, core.IDM, m)
        sj = np.where(go, tr.s_rec_m[k, j], s[:, j])
        vj = np.where(go, tr.v_rec_mps[k, j], v[:, j])
        acc = core.car_accel_core(
            tr.a_rec_mps2[k, j], tr.v_rec_mps[k, j], vj, a_act, p.car_headway_s,
            p.car_accel_mps2, p.car_max_decel_mps2,
        )  # fmt: skip
        drive = m == core.IDM
        v_new = np.where(drive, np.maximum(vj + acc * dt, 0.0), vj)
        s_new = np.where(drive, sj + v_new * dt, sj)
        stopped = m == core.STOPPED
        v_new = np.where(stopped, 0.0, v_new)
        new_mode[:, j] = m
        timer[:, j] = tm
        s[:, j], v[:, j] = s_new, v_new
    # replaying (or reacting) cars are their recording at k + 1
    rep = new_mode <= core.REACTING
    kn = min(k + 1, tr.s_rec_m.shape[0] - 1)
    s = np.where(rep, tr.s_rec_m[kn], s)
    v = np.where(rep, tr.v_rec_mps[kn], v)
    x = np.where(rep, arrays.other_x_m[kn, tr.idx], 0.0)
    y = np.where(rep, arrays.other_y_m[kn, tr.idx], 0.0)
    yaw = np.where(rep, arrays.other_yaw_rad[kn, tr.idx], 0.0)
    for j in range(tr.n):
        sim = ~rep[:, j]
        if sim.any():
            px, py, pyaw = tr.paths[j].lookup(s[sim, j])
            x[sim, j], y[sim, j], yaw[sim, j] = px, py, pyaw
    return {
        "car_s_m": s, "car_v_mps": v, "car_timer_s": timer, "car_x_m": x, "car_y_m": y,
        "car_yaw_rad": yaw, "car_mode": new_mode,
    }  # fmt: skip
