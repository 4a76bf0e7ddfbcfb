"""The social-force rider simulated along many recorded rider tracks at once.

A *window* is a closed-loop rollout of ``H`` engine steps that starts from a recorded state
(smoothed position and velocity) of one rider track; the recorded vehicles move as they
were recorded. Every window runs in one batch ``[B]``: one numpy operation per step for all
windows and all tracks. The step is the engine's (:mod:`vei.sim.engine`, step 3, SFM rider):

- progress along the rider's own recorded path: one local projection step, never backwards;
- goal s_des = the path point ``lookahead_m`` ahead of the progress (clamped at the end);
- ``v_des = v0 (g - p) / sqrt(|g - p|^2 + sigma^2)``; ``f = k_des (v_des - v) + f_veh``;
- ``|f| <= m a_max``; semi-implicit Euler; ``|v| <= v_max``.

One difference from the engine, on purpose: ``f_veh`` sums the repulsion of the ``K``
recorded vehicles nearest to the rider during the window (the instrumented car and any
other moving vehicle, closest point of each oriented box), because the recorded riders
react to every car, not only to the instrumented one. The engine's rider sees one ego.

Baselines over the same windows: constant velocity (CV), constant acceleration (CA, the
smoothed acceleration at the start) and constant speed along the recorded path (CS-path:
knows the route like the SFM does, keeps the start speed).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from vei.boxes import closest_point_on_box
from vei.calibrate.tracks import MOVING_MPS, RiderTrack, SceneTracks
from vei.models.drivable_path import jitter_mask
from vei.models.ego import build_path

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.intp]

#: Path tables: grid step [m], straight extension past both ends [m], and the minimum
#: spacing [m] of the smoothed positions a path is built from (a standing rider's
#: residual jitter must not add arc length or headings).
PATH_DS_M = 0.1
PATH_EXTEND_M = 50.0
PATH_MIN_SPACING_M = 0.2
#: Number of recorded vehicles that act on a window (the nearest during the window).
K_VEHICLES = 3

#: Names of the model parameters of a rollout, each a [B] array.
PARAM_NAMES: tuple[str, ...] = (
    "v0_mps",
    "k_des_nspm",
    "mass_kg",
    "sigma_m",
    "lookahead_m",
    "a_veh_n",
    "b_veh_per_m",
    "max_accel_mps2",
    "max_speed_mps",
)


@dataclass(frozen=True)
class PackedPaths:
    """The arc-length tables of many rider paths, concatenated (one gather per lookup).

    Attributes:
        x_m, y_m, cos, sin: [N_total] table entries. off: [P] first entry of path j.
        n: [P] entries of path j. s_start_m: [P] arc length of its first entry [m].
        length_m: [P] recorded length [m]. ds_m: grid step [m].
        arc_m: per track, [N_j] arc length of every track sample (initial progress).
    """

    x_m: FloatArray
    y_m: FloatArray
    cos: FloatArray
    sin: FloatArray
    off: IntArray
    n: IntArray
    s_start_m: FloatArray
    length_m: FloatArray
    ds_m: float
    arc_m: tuple[FloatArray, ...]

    def __post_init__(self) -> None:
        tab = np.column_stack([self.x_m, self.y_m, self.cos, self.sin])
        dtab = np.zeros_like(tab)
        dtab[:-1] = np.diff(tab, axis=0)
        object.__setattr__(self, "tab", tab)
        object.__setattr__(self, "dtab", dtab)

    def rows(self, j: IntArray) -> tuple[FloatArray, ...]:
        """Per-rider constants of :meth:`index_rows` for path indices j [B] (gather once)."""
        nj = self.n[j]
        return (
            self.s_start_m[j],
            (nj - 1.0).astype(np.float64),
            np.maximum(nj - 2, 0),
            self.off[j],
            self.length_m[j],
        )

    def index_rows(
        self, rows: tuple[FloatArray, ...], s_m: FloatArray
    ) -> tuple[IntArray, FloatArray]:
        """Global entry index and weight of arc lengths s [B] (clamped) given :meth:`rows`."""
        s0, nm1, imax, off, _ = rows
        f = np.clip((s_m - s0) * (1.0 / self.ds_m), 0.0, nm1)
        i = np.minimum(f.astype(np.intp), imax)
        return i + off, f - i

    def index(self, j: IntArray, s_m: FloatArray) -> tuple[IntArray, FloatArray]:
        """Global entry index and weight of arc lengths s [B] on paths j [B] (clamped)."""
        return self.index_rows(self.rows(j), s_m)

    def at(self, gi: IntArray, w: FloatArray, table: FloatArray) -> FloatArray:
        """Linear interpolation of one table (x_m, y_m, cos, sin) at (gi, w)."""
        return table[gi] + w * (table[gi + 1] - table[gi])

    def at4(self, gi: IntArray, w: FloatArray) -> FloatArray:
        """[..., 4] interpolated x_m, y_m, cos, sin at (gi, w) (one gather)."""
        return self.tab[gi] + w[..., None] * self.dtab[gi]


def decimated(x: FloatArray, y: FloatArray, spacing_m: float) -> IntArray:
    """Indices of the points kept when each must be >= spacing_m from the last kept one."""
    keep = [0]
    lx, ly = x[0], y[0]
    for i in range(1, x.size):
        if (x[i] - lx) ** 2 + (y[i] - ly) ** 2 >= spacing_m * spacing_m:
            keep.append(i)
            lx, ly = x[i], y[i]
    return np.asarray(keep, dtype=np.intp)


def pack_paths(tracks: list[RiderTrack], collapse_waits: bool = False) -> PackedPaths:
    """Arc-length tables (:func:`vei.models.ego.build_path`) of the tracks' smoothed paths.

    Each path is built from the positions spaced >= PATH_MIN_SPACING_M apart; a sample's
    arc length is that of the last kept point before it plus its distance from it.
    ``collapse_waits``: a wait whose positions jitter contributes its first point only
    (:func:`vei.models.drivable_path.jitter_mask`, as the engine's rider paths; the
    whole-track rollouts of vei.calibrate.decision_validate, which start standing riders).
    """
    xs, ys, cs, ss, offs, ns, s0, lens, arcs = [], [], [], [], [], [], [], [], []
    total = 0
    for tr in tracks:
        base = np.arange(tr.t_s.size)
        if collapse_waits:
            wait = jitter_mask(tr.x_m, tr.y_m, tr.t_s)
            base = np.flatnonzero(~wait | np.concatenate([[True], ~wait[:-1]]))
        k = base[decimated(tr.x_m[base], tr.y_m[base], PATH_MIN_SPACING_M)]
        yaw0 = float(np.arctan2(tr.vy_mps[0], tr.vx_mps[0]))
        p = build_path(
            tr.x_m[k], tr.y_m[k], yaw_hint_rad=yaw0, ds_m=PATH_DS_M, extend_m=PATH_EXTEND_M
        )
        xs.append(p.x_m)
        ys.append(p.y_m)
        cs.append(p.cos_yaw)  # type: ignore[attr-defined]
        ss.append(p.sin_yaw)  # type: ignore[attr-defined]
        offs.append(total)
        ns.append(p.x_m.size)
        total += p.x_m.size
        s0.append(p.s_start_m)
        lens.append(p.length_m)
        karc = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(tr.x_m[k]), np.diff(tr.y_m[k])))])
        last = np.searchsorted(k, np.arange(tr.t_s.size), side="right") - 1
        arcs.append(karc[last] + np.hypot(tr.x_m - tr.x_m[k][last], tr.y_m - tr.y_m[k][last]))
    return PackedPaths(
        x_m=np.concatenate(xs),
        y_m=np.concatenate(ys),
        cos=np.concatenate(cs),
        sin=np.concatenate(ss),
        off=np.asarray(offs, dtype=np.intp),
        n=np.asarray(ns, dtype=np.intp),
        s_start_m=np.asarray(s0),
        length_m=np.asarray(lens),
        ds_m=PATH_DS_M,
        arc_m=tuple(arcs),
    )


@dataclass(frozen=True)
class Windows:
    """B rollout windows of H steps over a list of tracks.

    Attributes:
        track: [B] index into the track list. start: [B] start sample in the track.
        horizon_steps: H. dt_s: step [s].
        x0_m, y0_m, vx0_mps, vy0_mps, ax0_mps2, ay0_mps2, prog0_m: [B] recorded start state.
        truth_x_m, truth_y_m: [B, H + 1] the recorded (smoothed) positions.
        veh_x_m, veh_y_m, veh_yaw_rad, veh_length_m, veh_width_m: [B, H + 1, K] the K
            nearest recorded vehicles (length 0 = no vehicle); veh_active: [B, H + 1, K].
        veh_min_gap_m: [B] smallest distance rider (recorded) to a vehicle box in the window.
    """

    track: IntArray
    start: IntArray
    horizon_steps: int
    dt_s: float
    x0_m: FloatArray
    y0_m: FloatArray
    vx0_mps: FloatArray
    vy0_mps: FloatArray
    ax0_mps2: FloatArray
    ay0_mps2: FloatArray
    prog0_m: FloatArray
    truth_x_m: FloatArray
    truth_y_m: FloatArray
    veh_x_m: FloatArray
    veh_y_m: FloatArray
    veh_yaw_rad: FloatArray
    veh_length_m: FloatArray
    veh_width_m: FloatArray
    veh_active: npt.NDArray[np.bool_]
    veh_min_gap_m: FloatArray

    @property
    def size(self) -> int:
        """B."""
        return int(self.track.size)

    def take(self, idx: npt.ArrayLike) -> Windows:
        """The windows at idx (int array or bool mask)."""
        ix = np.asarray(idx)
        vals = {}
        for name in self.__dataclass_fields__:
            v = getattr(self, name)
            vals[name] = v[ix] if isinstance(v, np.ndarray) else v
        return Windows(**vals)


def make_windows(
    tracks: list[RiderTrack],
    scenes: dict[str, SceneTracks],
    paths: PackedPaths,
    horizon_s: float,
    stride_s: float = 0.5,
    dt_s: float = 0.05,
    starts: list[tuple[int, int]] | None = None,
) -> Windows:
    """Every window of ``horizon_s`` starting every ``stride_s`` at a moving sample.

    A window starts at a sample whose smoothed speed exceeds MOVING_MPS (a standing rider
    waits for a signal the model does not see) and needs the full horizon inside the track.

    Args:
        tracks: the rider tracks (index = ``Windows.track``). scenes: scenario -> its
            SceneTracks (for the vehicles). paths: :func:`pack_paths` of ``tracks``.
        horizon_s: rollout length [s]. stride_s: spacing of the starts [s]. dt_s: step [s].
        starts: the windows' (track index, start sample) given (whole-track rollouts of
            vei.calibrate.decision_validate; standing starts allowed) instead of found.
    Returns:
        The Windows (B may be 0).
    """
    h = int(round(horizon_s / dt_s))
    stride = max(1, int(round(stride_s / dt_s)))
    rows: list[tuple[int, int]] = [] if starts is None else list(starts)
    for j, tr in enumerate(tracks if starts is None else ()):
        sp = tr.speed_mps
        for s in range(0, tr.t_s.size - h, stride):
            if sp[s] > MOVING_MPS:
                rows.append((j, s))
    b = len(rows)
    tj = np.array([r[0] for r in rows], dtype=np.intp)
    st = np.array([r[1] for r in rows], dtype=np.intp)
    steps = np.arange(h + 1)
    tx, ty = np.zeros((b, h + 1)), np.zeros((b, h + 1))
    vx_, vy_, vyaw, vl, vw = (np.zeros((b, h + 1, K_VEHICLES)) for _ in range(5))
    vact = np.zeros((b, h + 1, K_VEHICLES), dtype=bool)
    gap = np.full(b, np.inf)
    for i, (j, s) in enumerate(rows):
        tr = tracks[j]
        tx[i] = tr.x_m[s : s + h + 1]
        ty[i] = tr.y_m[s : s + h + 1]
        veh = scenes[tr.scenario].vehicles
        if not veh.ids:
            continue
        k = np.rint(tr.t_s[s] / dt_s).astype(np.intp) + steps
        k = np.minimum(k, veh.x_m.shape[0] - 1)
        act = veh.active[k]
        qx, qy = closest_point_on_box(
            tx[i][:, None],
            ty[i][:, None],
            veh.x_m[k],
            veh.y_m[k],
            veh.yaw_rad[k],
            veh.length_m[None, :],
            veh.width_m[None, :],
        )
        d = np.where(act, np.hypot(tx[i][:, None] - qx, ty[i][:, None] - qy), np.inf)
        dmin = d.min(axis=0)
        order = np.argsort(dmin)[:K_VEHICLES]
        order = order[np.isfinite(dmin[order])]
        if order.size == 0:
            continue
        gap[i] = float(dmin[order[0]])
        m = order.size
        vx_[i, :, :m] = veh.x_m[k][:, order]
        vy_[i, :, :m] = veh.y_m[k][:, order]
        vyaw[i, :, :m] = veh.yaw_rad[k][:, order]
        vl[i, :, :m] = veh.length_m[order]
        vw[i, :, :m] = veh.width_m[order]
        vact[i, :, :m] = act[:, order]
    return Windows(
        track=tj,
        start=st,
        horizon_steps=h,
        dt_s=dt_s,
        x0_m=tx[:, 0].copy(),
        y0_m=ty[:, 0].copy(),
        vx0_mps=np.array([tracks[j].vx_mps[s] for j, s in rows]),
        vy0_mps=np.array([tracks[j].vy_mps[s] for j, s in rows]),
        ax0_mps2=np.array([tracks[j].ax_mps2[s] for j, s in rows]),
        ay0_mps2=np.array([tracks[j].ay_mps2[s] for j, s in rows]),
        prog0_m=np.array([paths.arc_m[j][s] for j, s in rows]),
        truth_x_m=tx,
        truth_y_m=ty,
        veh_x_m=vx_,
        veh_y_m=vy_,
        veh_yaw_rad=vyaw,
        veh_length_m=vl,
        veh_width_m=vw,
        veh_active=vact,
        veh_min_gap_m=gap,
    )


def sfm_force(
    paths: PackedPaths,
    j: IntArray | tuple[FloatArray, ...],
    x: FloatArray,
    y: FloatArray,
    vx: FloatArray,
    vy: FloatArray,
    prog0: FloatArray,
    p: dict[str, FloatArray],
    veh: tuple[FloatArray, ...] | None,
    speed_cap: FloatArray | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Social force on riders [B] (capped at m a_max) and their updated progress.

    Args:
        paths, j: the packed paths and each rider's path index [B] (or its
            ``paths.rows(j)``, gathered once per rollout).
        x, y, vx, vy: rider state [B] (m, m/s). prog0: progress before the step [B] (m).
        p: parameters (PARAM_NAMES) [B]. veh: (x, y, yaw, length, width, active) [B, K]
            of the vehicles at this step, or None.
        speed_cap: [B] a cap on the desired speed [m/s] (the yield decision's,
            vei.calibrate.decision_validate; +inf = none), or None.
    Returns:
        (fx_n, fy_n, prog_m) [B].
    """
    rows = paths.rows(j) if isinstance(j, np.ndarray) else j
    gi, w = paths.index_rows(rows, prog0)
    q = paths.at4(gi, w)
    prog = np.maximum(prog0 + (x - q[:, 0]) * q[:, 2] + (y - q[:, 1]) * q[:, 3], prog0)
    gi, w = paths.index_rows(rows, np.minimum(prog + p["lookahead_m"], rows[4]))
    g = paths.at4(gi, w)
    dx = g[:, 0] - x
    dy = g[:, 1] - y
    f = p["v0_mps"] / np.sqrt(dx * dx + dy * dy + p["sigma_m"] ** 2)
    if speed_cap is not None:
        f = f * np.minimum(1.0, speed_cap / np.maximum(f * np.sqrt(dx * dx + dy * dy), 1e-9))
    k = p["k_des_nspm"]
    fx = k * (f * dx - vx)
    fy = k * (f * dy - vy)
    if veh is not None:
        ox, oy, oyaw, ol, ow, oa = veh
        qx, qy = closest_point_on_box(x[:, None], y[:, None], ox, oy, oyaw, ol, ow)
        ex, ey = x[:, None] - qx, y[:, None] - qy
        d = np.sqrt(ex * ex + ey * ey)
        inside = d < 1e-9
        cx, cy = x[:, None] - ox, y[:, None] - oy
        ux = np.where(inside, cx, ex)
        uy = np.where(inside, cy, ey)
        un = np.maximum(np.sqrt(ux * ux + uy * uy), 1e-9)
        mag = np.where(oa, p["a_veh_n"][:, None] * np.exp(-p["b_veh_per_m"][:, None] * d), 0.0)
        fx = fx + np.sum(mag * ux / un, axis=1)
        fy = fy + np.sum(mag * uy / un, axis=1)
    fmax = p["max_accel_mps2"] * p["mass_kg"]
    fmag = np.sqrt(fx * fx + fy * fy)
    over = fmag > fmax
    if not over.any():
        return fx, fy, prog
    sc = np.where(over, fmax / np.maximum(fmag, 1e-12), 1.0)
    return fx * sc, fy * sc, prog


def rollout_sfm(
    paths: PackedPaths, win: Windows, params: dict[str, FloatArray], *, vehicles: bool = True
) -> tuple[FloatArray, FloatArray]:
    """Closed-loop social-force rollouts of every window.

    Args:
        paths: packed paths of the windows' tracks. win: the windows (B, H).
        params: every name of PARAM_NAMES, [B] (or scalars, broadcast).
        vehicles: include the recorded vehicles' repulsion.
    Returns:
        (x_m, y_m) [B, H + 1], column 0 the recorded start.
    """
    b, h, dt = win.size, win.horizon_steps, win.dt_s
    p = {n: np.broadcast_to(np.asarray(params[n], dtype=np.float64), (b,)) for n in PARAM_NAMES}
    use_veh = vehicles and bool(np.any(p["a_veh_n"] > 0)) and bool(win.veh_active.any())
    x, y = win.x0_m.copy(), win.y0_m.copy()
    vx, vy = win.vx0_mps.copy(), win.vy0_mps.copy()
    prog = win.prog0_m.copy()
    outx, outy = np.empty((b, h + 1)), np.empty((b, h + 1))
    outx[:, 0], outy[:, 0] = x, y
    inv_m = 1.0 / p["mass_kg"]
    vmax = p["max_speed_mps"]
    rows = paths.rows(win.track)
    for k in range(h):
        veh = None
        if use_veh:
            veh = (
                win.veh_x_m[:, k],
                win.veh_y_m[:, k],
                win.veh_yaw_rad[:, k],
                win.veh_length_m[:, k],
                win.veh_width_m[:, k],
                win.veh_active[:, k],
            )
        fx, fy, prog = sfm_force(paths, rows, x, y, vx, vy, prog, p, veh)
        vx = vx + fx * inv_m * dt
        vy = vy + fy * inv_m * dt
        sp = np.sqrt(vx * vx + vy * vy)
        fast = sp > vmax
        if fast.any():
            sc = np.where(fast, vmax / np.maximum(sp, 1e-12), 1.0)
            vx, vy = vx * sc, vy * sc
        x = x + vx * dt
        y = y + vy * dt
        outx[:, k + 1], outy[:, k + 1] = x, y
    return outx, outy


def rollout_cv(win: Windows) -> tuple[FloatArray, FloatArray]:
    """Constant velocity from the recorded start: (x_m, y_m) [B, H + 1]."""
    t = np.arange(win.horizon_steps + 1) * win.dt_s
    return win.x0_m[:, None] + win.vx0_mps[:, None] * t, win.y0_m[:, None] + win.vy0_mps[
        :, None
    ] * t


def rollout_ca(win: Windows) -> tuple[FloatArray, FloatArray]:
    """Constant acceleration (smoothed, at the start): (x_m, y_m) [B, H + 1]."""
    t = np.arange(win.horizon_steps + 1) * win.dt_s
    x = win.x0_m[:, None] + win.vx0_mps[:, None] * t + 0.5 * win.ax0_mps2[:, None] * t * t
    y = win.y0_m[:, None] + win.vy0_mps[:, None] * t + 0.5 * win.ay0_mps2[:, None] * t * t
    return x, y


def rollout_path_cs(paths: PackedPaths, win: Windows) -> tuple[FloatArray, FloatArray]:
    """Constant start speed along the recorded path (the route known, the timing not)."""
    t = np.arange(win.horizon_steps + 1) * win.dt_s
    sp = np.hypot(win.vx0_mps, win.vy0_mps)
    s = win.prog0_m[:, None] + sp[:, None] * t
    j = np.broadcast_to(win.track[:, None], s.shape)
    gi, w = paths.index(j, s)
    x = paths.at(gi, w, paths.x_m)
    y = paths.at(gi, w, paths.y_m)
    # Anchor at the recorded start (the path point may lie a few cm off it).
    return x - x[:, :1] + win.x0_m[:, None], y - y[:, :1] + win.y0_m[:, None]


def displacement_errors(
    win: Windows, x: FloatArray, y: FloatArray, horizon_steps: int | None = None
) -> tuple[FloatArray, FloatArray]:
    """ADE and FDE [B] [m] of predicted positions over the first ``horizon_steps`` steps.

    ADE = mean over steps 1..h of the Euclidean error; FDE = the error at step h.
    """
    h = win.horizon_steps if horizon_steps is None else horizon_steps
    e = np.hypot(
        x[:, 1 : h + 1] - win.truth_x_m[:, 1 : h + 1], y[:, 1 : h + 1] - win.truth_y_m[:, 1 : h + 1]
    )
    return e.mean(axis=1), e[:, -1]
