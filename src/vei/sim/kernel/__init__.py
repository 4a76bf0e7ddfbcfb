"""Compiled kernel of the built-in engine (optional; needs numba).

The same model, the same order of operations and the same formulas as
:func:`vei.sim.engine.step` (the NumPy reference, which stays the pure step API), written
as one loop per variant over all steps and compiled with numba. Each variant is computed
independently of the others (``prange`` over variants, no reductions across them), so B
single runs equal one batch of B bit for bit, and two runs are bit-identical. Against the
NumPy path results agree to rounding (libm vs NumPy's vectorised exp/cos/atan2): a test
bounds the difference.

:func:`available` tells whether numba can be imported; :func:`run` is called by
:func:`vei.sim.engine.simulate` with ``kernel='numba'`` (or 'auto' when available).

Compilation is paid once per machine and installation: numba caches the machine code beside
this package, or in a user cache directory when the package's folder is not writable
(``$NUMBA_CACHE_DIR``, else the platform's user cache, e.g. ``~/.cache/numba``). The
first call that has to compile says so (:data:`COMPILE_MESSAGE`, with a line every 10 s
when the output is not a terminal: :func:`vei.io.progress.activity`); :func:`is_cold`
tells beforehand, so that a command with workers compiles once in its own process before
it starts them (:func:`vei.sim.warmup.ensure_compiled`).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

from vei.errors import DependencyError
from vei.sim.kernel.layout import BOOL_FIELDS, FLOAT_FIELDS, N_OUT, P_DELAY, PARAM_FIELDS
from vei.sim.riders import EXTRA_BOOL_FIELDS, EXTRA_FLOAT_FIELDS, RIDER_COLUMNS

_KERNEL: Any = None
_KEY: str | None = None  # _compile_key(), computed once per process
_WARM = False  # this process has run the kernel (its machine code is loaded)
#: Variants per chunk handed to a thread of the compiled kernel's parallel loop (each
#: variant is ~50-100 us of work: a chunk is ~1 ms, far above the scheduling cost).
_CHUNK = 16


def available() -> bool:
    """True when numba can be imported (the compiled kernel can run)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return False
    return True


#: What the first call on a machine (and installation) prints while numba compiles.
COMPILE_MESSAGE = (
    "compiling vei's engine kernel for this machine (once per installation; 1-3 minutes, "
    "later runs load it in about a second)"
)
_STAMP = "loop.compiled"


def _build() -> Any:
    """The compiled kernel (imports numba and compiles or loads it from the cache once)."""
    global _KERNEL
    if _KERNEL is not None:
        return _KERNEL
    if not available():
        raise DependencyError("the compiled engine kernel needs numba (pip install numba)")
    from vei.sim.kernel.loop import kernel

    _drop_stale_cache(kernel)
    _KERNEL = kernel
    return kernel


#: Modules compiled into the kernel (numba's cache checks only the kernel's own file);
#: vei.boxes gives it the box-overlap test, vei.config.settings the order of P's rows
#: (layout's P_* constants). Paths relative to this package.
_KERNEL_SOURCES = (
    "loop.py", "scalar.py", "ego.py", "sfm.py", "riders.py", "layout.py", "decision.py",
    "traffic.py", "../../models/traffic_core.py",
    "../../boxes.py", "../../config/settings.py", "../../metrics/fused.py",
    "../../metrics/fused_layout.py", "../../metrics/fused_ops.py",
    "../../models/ego_core.py", "../../models/sfm_core.py", "../../models/decision_core.py",
)  # fmt: skip


def _drop_stale_cache(kernel: Any) -> None:
    """Flush the kernel's on-disk numba cache when any module compiled into it changed.

    numba keys a cached function by its own source file only, so an edit of a helper module
    (inlined into the kernel) would otherwise keep serving the old machine code. A SHA-256
    of all :data:`_KERNEL_SOURCES` is kept next to the cache; on a mismatch the cache is
    flushed (recompiled on the first call) and the new digest written atomically.
    """
    cache = getattr(kernel, "_cache", None)
    cache_dir = getattr(cache, "cache_path", None)
    if not cache_dir:
        return
    digest = _sources_digest()
    stamp = Path(cache_dir) / "loop.sources.sha256"
    try:
        if stamp.is_file() and stamp.read_text().strip() == digest:
            return
        cache.flush()
        stamp.parent.mkdir(parents=True, exist_ok=True)
        tmp = stamp.with_name(f"{stamp.name}.{os.getpid()}.tmp")
        tmp.write_text(digest + "\n")
        os.replace(tmp, stamp)
    except OSError:  # read-only install: nothing cached by us can be stale
        return


def _compile_key() -> str:
    """What the cached machine code depends on (sources, numba, CPU), kept in the stamp."""
    global _KEY
    if _KEY is None:
        import llvmlite.binding as llvm
        import numba

        cpu = llvm.get_host_cpu_name()
        _KEY = f"{_sources_digest()} numba {numba.__version__} {platform.machine()} {cpu}"
    return _KEY


def _sources_digest() -> str:
    here = Path(__file__).resolve().parent
    return hashlib.sha256(b"".join((here / n).read_bytes() for n in _KERNEL_SOURCES)).hexdigest()


def _compiled_stamp(kernel: Any) -> Path | None:
    cache_dir = getattr(getattr(kernel, "_cache", None), "cache_path", None)
    return Path(cache_dir) / _STAMP if cache_dir else None


def is_cold() -> bool:
    """True when the compiled kernel has no machine code cached for this machine and
    installation yet (its first call compiles: 1-3 minutes); False when it loads from the
    cache, or when numba is not installed."""
    if _WARM or not available():
        return False
    stamp = _compiled_stamp(_build())
    if stamp is None:
        return True
    # the stamp says who compiled; numba's index file that the machine code is still there
    # (a cleared __pycache__ can leave the one without the other)
    if not any(stamp.parent.glob("loop.*.nbi")):
        return True
    try:
        return stamp.read_text().strip() != _compile_key()
    except OSError:
        return True


def _loaded(kernel: Any, compiled: bool) -> None:
    """After a call: the process has the machine code; after a compile, say so on disk."""
    global _WARM
    _WARM = True
    if compiled:
        _mark_compiled(kernel)


def _mark_compiled(kernel: Any) -> None:
    stamp = _compiled_stamp(kernel)
    if stamp is None:
        return
    try:
        tmp = stamp.with_name(f"{stamp.name}.{os.getpid()}.tmp")
        tmp.write_text(_compile_key() + "\n")
        os.replace(tmp, stamp)
    except OSError:  # a cache we cannot write: numba compiles again next time anyway
        return


def _path_rows(path: Any) -> np.ndarray:
    vals = path._values  # type: ignore[attr-defined]
    slopes = path._slopes  # type: ignore[attr-defined]
    names = ("x", "y", "yaw", "cos", "sin")
    return np.ascontiguousarray(np.stack([vals[n] for n in names] + [slopes[n] for n in names]))


def _table_rows(table: Any, names: tuple[str, ...]) -> np.ndarray:
    cols = table._cols  # type: ignore[attr-defined]
    slopes = table._slopes  # type: ignore[attr-defined]
    return np.ascontiguousarray(np.stack([cols[n] for n in names] + [slopes[n] for n in names]))


def _extra_args(arrays: Any) -> tuple[Any, ...]:
    """The kernel's extra-rider arguments (R, padded tables, radii, pedestrians, mode)."""
    xr = arrays.riders
    n_x = xr.n
    m_max = max([t.data.shape[0] for t in xr.tracks], default=1)
    n_max = max([p.x_m.shape[0] for p in xr.paths], default=1)
    xtab = np.zeros((n_x, 14, m_max))
    xpath = np.zeros((n_x, 10, n_max))
    for j in range(n_x):
        rows = _table_rows(xr.tracks[j], RIDER_COLUMNS)
        xtab[j, :, : rows.shape[1]] = rows
        prow = _path_rows(xr.paths[j])
        xpath[j, :, : prow.shape[1]] = prow
    f = np.float64
    return (
        n_x, xtab,
        np.array([t.t0_s for t in xr.tracks], f), np.array([t.dt_s for t in xr.tracks], f),
        np.array([t.t_end_s for t in xr.tracks], f),
        np.array([t.data.shape[0] for t in xr.tracks], np.int64),
        np.array(xr.sfm_entry_s if xr.sfm_entry_s.size == n_x else [-np.inf] * n_x, f),
        xpath,
        np.array([p.s_start_m for p in xr.paths], f), np.array([p.ds_m for p in xr.paths], f),
        np.array([p.x_m.shape[0] for p in xr.paths], np.int64),
        np.array([p.length_m for p in xr.paths], f),
        np.array([p.end_x_m for p in xr.paths], f), np.array([p.end_y_m for p in xr.paths], f),
        np.ascontiguousarray(xr.length_m, f), np.ascontiguousarray(xr.width_m, f),
        np.ascontiguousarray(xr.radius_m, f), np.ascontiguousarray(xr.median_speed_mps, f),
        np.ascontiguousarray(xr.p99_speed_mps, f), float(xr.primary_radius_m), bool(xr.enabled),
        np.ascontiguousarray(xr.ped_idx, np.int64), np.ascontiguousarray(xr.ped_radius_m, f),
    )  # fmt: skip


def _conflict_args(arrays: Any) -> tuple[Any, ...]:
    """The kernel's conflict arguments (vei.sim.decisions.Conflicts): K and its [K]
    arrays (zone exit, crossing along the rider's and the ego's path, half-lengths)."""
    c = arrays.conflicts
    f = np.float64
    return (
        int(c.n), np.ascontiguousarray(c.exit_m, f), np.ascontiguousarray(c.s_rider_m, f),
        np.ascontiguousarray(c.s_ego_m, f), np.ascontiguousarray(c.hz_rider_m, f),
        np.ascontiguousarray(c.hz_ego_m, f),
    )  # fmt: skip


def _traffic_args(arrays: Any, state0: Any, b: int, tt: int) -> tuple[tuple, tuple, tuple]:
    """The kernel's reacting-car arguments (vei.sim.traffic.Traffic), their initial state,
    and the output / final buffers (see the kernel's signature)."""
    tr = arrays.traffic
    c, no = tr.n, len(arrays.other_ids)
    f = np.float64
    tci = np.full(no, -1, dtype=np.int64)
    tci[tr.idx] = np.arange(c)
    veh = np.array([cat == "vehicle" for cat in arrays.other_categories], dtype=np.bool_)
    scene = (
        int(c), np.ascontiguousarray(tr.idx, np.int64), np.ascontiguousarray(tr.length_m, f),
        np.ascontiguousarray(tr.width_m, f), tci, np.ascontiguousarray(tr.ptab, f),
        np.ascontiguousarray(tr.ps0, f), np.ascontiguousarray(tr.pds, f),
        np.ascontiguousarray(tr.pn, np.int64), np.ascontiguousarray(tr.s_rec_m, f),
        np.ascontiguousarray(tr.v_rec_mps, f), np.ascontiguousarray(tr.a_rec_mps2, f),
        np.ascontiguousarray(tr.active), np.ascontiguousarray(tr.ego_s_rec_m, f),
        np.ascontiguousarray(tr.ego_v_rec_mps, f), np.ascontiguousarray(tr.mtab, f),
        np.ascontiguousarray(tr.m0, f), np.ascontiguousarray(tr.mn, np.int64),
        np.ascontiguousarray(tr.pair), np.ascontiguousarray(arrays.other_speed_mps, f), veh,
    )  # fmt: skip
    from vei.sim.traffic import CAR_FLOAT_FIELDS

    cs0 = np.ascontiguousarray(
        np.stack([getattr(state0, n) for n in CAR_FLOAT_FIELDS]).astype(f).reshape(6, b, c)
    )
    sec0 = np.stack(
        [state0.sec_count.astype(f), state0.sec_first_t_s, state0.sec_striker.astype(f),
         state0.sec_struck.astype(f), state0.sec_max_speed_mps, state0.rear_end.astype(f)]
    )  # fmt: skip
    init = (
        cs0, np.ascontiguousarray(state0.car_mode, np.int64),
        np.ascontiguousarray(state0.car_hit.astype(np.uint8)),
        np.ascontiguousarray(state0.car_hit_with, np.int64),
        np.ascontiguousarray(state0.rider_hit_other.astype(np.uint8)), np.ascontiguousarray(sec0),
    )  # fmt: skip
    bufs = (
        np.zeros((b, 4, tt, c)), np.zeros((b, tt, c), dtype=np.uint8),
        np.empty((6, b, c)), np.empty((b, c), dtype=np.int64), np.empty((b, c), dtype=np.uint8),
        np.empty((b, c), dtype=np.int64), np.empty((b, no), dtype=np.uint8), np.empty((6, b)),
    )  # fmt: skip
    return scene, init, bufs


def _traffic_final(state0: Any, bufs: tuple, final: dict[str, Any], record: bool) -> dict | None:
    """Put the kernel's reacting-car and contact finals into ``final``; the car series
    (record) as a dict of [B, T, C] arrays."""
    from vei.sim.traffic import CAR_FLOAT_FIELDS

    oc, ocm, cfs, cfm, cfh, cfw, rfh, secf = bufs
    for j, n in enumerate(CAR_FLOAT_FIELDS):
        final[n] = cfs[j].copy()
    final["car_mode"] = cfm.astype(np.int8)
    final["car_hit"] = cfh.astype(bool)
    final["car_hit_with"] = cfw.astype(np.int32)
    final["rider_hit_other"] = rfh.astype(bool)
    final["sec_count"] = secf[0].astype(np.int32)
    final["sec_first_t_s"] = secf[1].copy()
    final["sec_striker"] = secf[2].astype(np.int32)
    final["sec_struck"] = secf[3].astype(np.int32)
    final["sec_max_speed_mps"] = secf[4].copy()
    final["rear_end"] = secf[5] > 0.5
    if not record:
        return None
    for j, src in enumerate(("car_x_m", "car_y_m", "car_yaw_rad", "car_v_mps")):
        oc[:, j, 0, :] = getattr(state0, src)
    ocm[:, 0, :] = state0.car_mode
    return {
        "car_x_m": oc[:, 0], "car_y_m": oc[:, 1], "car_yaw_rad": oc[:, 2],
        "car_speed_mps": oc[:, 3], "car_mode": ocm.astype(np.int8),
    }  # fmt: skip


def run(
    arrays: Any,
    params: Any,
    state0: Any,
    hist_len: int,
    record: bool,
    metrics_cfg: np.ndarray | None = None,
) -> dict[str, Any]:
    """Run the compiled kernel from ``state0`` over all steps of ``arrays``.

    Args:
        arrays: ScenarioArrays. params: VariantParams [B]. state0: SimState at k = 0 (from
        :func:`vei.sim.engine.initial_state`). hist_len: perception ring length H.
        record: keep the time series.
        metrics_cfg: [N_CFG] :func:`vei.metrics.fused.config_vector`: also score every
            variant with the fused metrics (per-variant [T] scratch channels inside the
            kernel, no [B, T] buffer); None: no metrics.
    Returns:
        dict with 'series' (name -> [B, T] arrays of vei.sim.result._RECORDED (views of a
        variant-major buffer), or None), 'hit' ([B, T, n_o] or None), 'final' (SimState
        fields), 'collision_time_s', 'min_center_distance_m', 'metrics' ([B, N_FUSED]
        rows of vei.metrics.fused.FUSED_METRICS, or None).
    """
    from vei.metrics.fused_layout import N_CFG, N_FUSED

    kernel = _build()
    cold = is_cold()
    t_n = arrays.n_steps
    b = params.batch_size
    no = len(arrays.other_ids)
    p_mat = np.ascontiguousarray(
        np.stack([np.asarray(getattr(params, f), dtype=np.float64) for f in PARAM_FIELDS])
    )
    p_mat[P_DELAY] = params.delay_steps(arrays.dt_s)
    s0 = np.ascontiguousarray(
        np.stack([np.asarray(getattr(state0, f), dtype=np.float64) for f in FLOAT_FIELDS])
    )
    b0 = np.ascontiguousarray(
        np.stack([np.asarray(getattr(state0, f)).astype(np.uint8) for f in BOOL_FIELDS])
    )
    tt = t_n if record else 1
    out = np.empty((b, N_OUT, tt))
    outb = np.zeros((b, 4, tt), dtype=np.uint8)  # cap, rider active, collided, decision
    outh = np.zeros((b, tt, no), dtype=np.uint8)
    h0 = np.ascontiguousarray(state0.hit_other.astype(np.uint8))
    if record:
        first = (
            state0.ego_s_m, state0.ego_x_m, state0.ego_y_m, state0.ego_yaw_rad, state0.ego_v_mps,
            state0.ego_a_mps2, state0.ego_cmd, state0.rider_x_m, state0.rider_y_m, state0.rider_yaw_rad,
            state0.rider_speed_mps, state0.rider_vx_mps, state0.rider_vy_mps, state0.rider_a_mps2,
        )  # fmt: skip
        for j, val in enumerate(first):
            out[:, j, 0] = val
        outb[:, 0, 0] = state0.cap_state
        outb[:, 1, 0] = state0.rider_active
        outb[:, 2, 0] = state0.collided
        outb[:, 3, 0] = state0.rider_decision
        outh[:, 0] = h0
    fs = np.empty((len(FLOAT_FIELDS), b))
    fb = np.empty((len(BOOL_FIELDS), b), dtype=np.uint8)
    fh = np.empty((4, hist_len, b))
    coll_t = np.empty(b)
    min_d = np.empty(b)
    tr, rp, et = arrays.rider_track, arrays.rider_path, arrays.ego_track
    # Extra riders (vei.sim.riders): tables padded to the longest, state [F, B, R].
    xr = arrays.riders
    n_x = xr.n
    xa = _extra_args(arrays)
    xs0 = np.ascontiguousarray(
        np.stack([getattr(state0, f) for f in EXTRA_FLOAT_FIELDS]).astype(np.float64)
    ).reshape(8, b, n_x)
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
    xfs = np.empty((8, b, n_x))
    xfb = np.empty((4, b, n_x), dtype=np.uint8)
    scored = metrics_cfg is not None
    mcfg = np.ascontiguousarray(metrics_cfg if scored else np.zeros(N_CFG), dtype=np.float64)
    m_out = np.empty((b if scored else 1, N_FUSED))
    t_m = np.ascontiguousarray(arrays.t_s, dtype=np.float64)
    dt_m = float(t_m[1] - t_m[0]) if t_m.size > 1 else 0.0  # as vei.types.Trace.dt_s
    # Variants differ in cost (a collided one stops its rider's social force): the threads
    # take them in chunks of _CHUNK on demand, not one equal block each (which left a core
    # idle for ~20 % of the run of a batch sorted by time shift); results do not change.
    import numba

    from vei.io.progress import activity

    t_scene, t_init, t_bufs = _traffic_args(arrays, state0, b, tt)
    prev_chunk = numba.set_parallel_chunksize(_CHUNK)
    announce = activity(COMPILE_MESSAGE) if cold else contextlib.nullcontext()
    try:
        with announce:
            kernel(
                t_n, float(arrays.dt_s), int(hist_len), bool(record),
                _path_rows(arrays.ego_path), float(arrays.ego_path.s_start_m), float(arrays.ego_path.ds_m),
                _table_rows(et, ("s_m", "speed_mps")), float(et.t0_s), float(et.dt_s),
                _table_rows(tr, ("x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps", "arc_m")),
                float(tr.t0_s), float(tr.dt_s), float(tr.t_end_s), float(arrays.rider_sfm_entry_s),
                _path_rows(rp), float(rp.s_start_m), float(rp.ds_m), float(rp.length_m), float(rp.end_x_m), float(rp.end_y_m),
                float(arrays.ego_length_m), float(arrays.ego_width_m), float(arrays.rider_length_m), float(arrays.rider_width_m),
                np.ascontiguousarray(arrays.other_x_m), np.ascontiguousarray(arrays.other_y_m),
                np.ascontiguousarray(arrays.other_yaw_rad), np.ascontiguousarray(arrays.other_active),
                np.ascontiguousarray(arrays.other_length_m, dtype=np.float64),
                np.ascontiguousarray(arrays.other_width_m, dtype=np.float64),
                p_mat, s0, b0, out, outb, outh, h0, fs, fb, fh, coll_t, min_d,
                *xa, xs0, xb0, outx, outxb, xfs, xfb,
                scored, t_m, dt_m, mcfg, m_out,
                *_conflict_args(arrays), *t_scene, *t_init, *t_bufs,
            )  # fmt: skip
    finally:
        numba.set_parallel_chunksize(prev_chunk)
    _loaded(kernel, cold)
    final = {f: fs[j].copy() for j, f in enumerate(FLOAT_FIELDS)}
    final["cap_state"] = fs[FLOAT_FIELDS.index("cap_state")].astype(np.int8)
    final["rider_decision"] = fs[FLOAT_FIELDS.index("rider_decision")].astype(np.int8)
    for j, f in enumerate(BOOL_FIELDS):
        final[f] = fb[j].astype(bool)
    final["hit_other"] = h0.astype(bool)
    final["hist"] = fh
    final["k"] = t_n - 1
    for j, f in enumerate(EXTRA_FLOAT_FIELDS):
        final[f] = xfs[j].copy()
    for j, f in enumerate(EXTRA_BOOL_FIELDS):
        final[f] = xfb[j].astype(bool)
    cars = _traffic_final(state0, t_bufs, final, record)
    for f in state0._fields:  # fields the kernel does not advance keep their start values
        final.setdefault(f, getattr(state0, f))
    extra = None
    series = None
    hit = None
    if record:
        names = (
            "ego_s_m", "ego_x_m", "ego_y_m", "ego_yaw_rad", "ego_speed_mps", "ego_accel_mps2", "ego_command",
            "rider_x_m", "rider_y_m", "rider_yaw_rad", "rider_speed_mps", "rider_vx_mps", "rider_vy_mps",
            "rider_accel_mps2",
        )  # fmt: skip
        series = {n: out[:, j, :] for j, n in enumerate(names)}
        series["cap_state"] = outb[:, 0, :].astype(np.int8)
        series["rider_decision"] = outb[:, 3, :].astype(np.int8)
        series["rider_active"] = outb[:, 1, :].astype(bool)
        series["collided"] = outb[:, 2, :].astype(bool)
        hit = outh.astype(bool)
        extra = {
            "extra_x_m": outx[:, 0], "extra_y_m": outx[:, 1], "extra_yaw_rad": outx[:, 2],
            "extra_speed_mps": outx[:, 3], "extra_accel_mps2": outx[:, 4],
            "extra_active": outxb[:, 0].astype(bool), "extra_hit": outxb[:, 1].astype(bool),
            **(cars or {}),
        }  # fmt: skip
    return {
        "series": series,
        "hit": hit,
        "extra": extra,
        "final": final,
        "collision_time_s": coll_t,
        "min_center_distance_m": min_d,
        "metrics": m_out if scored else None,
    }
