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

Compiled per feature set: a run compiles only the parts of the world it uses (other road
users, extra riders, decisions, reacting cars, fused metrics: :class:`Features`), each
set once per machine and installation. numba caches the machine code beside this package,
or in a user cache directory when the package's folder is not writable
(``$NUMBA_CACHE_DIR``, else the platform's user cache, e.g. ``~/.cache/numba``). The
first call that has to compile a feature set says so (:func:`compile_message`, inside the
calling step's own progress line off a terminal: :func:`vei.io.progress.activity`);
:func:`is_cold` tells beforehand. Processes compiling the same set take turns
(:func:`vei.sim.kernel.cache.compiling`): a sweep's workers compile it once.
"""

from __future__ import annotations

import contextlib
import warnings
from typing import Any

import numpy as np

from vei.errors import DependencyError
from vei.sim.kernel import cache
from vei.sim.kernel.layout import BOOL_FIELDS, FLOAT_FIELDS, P_DELAY, PARAM_FIELDS
from vei.sim.kernel.pack import (
    ALL_FEATURES,
    Features,
    cars_final,
    decisions_group,
    ego_group,
    features_of,
    others_group,
    out_group,
    rider_group,
    riders_group,
    secondary_final,
    state_group,
    traffic_group,
)
from vei.sim.kernel.policy_pack import check_outputs, policy_group
from vei.sim.riders import EXTRA_BOOL_FIELDS, EXTRA_FLOAT_FIELDS, EXTRA_INT_FIELDS

__all__ = [
    "ALL_FEATURES", "Features", "available", "compile_message", "features_of", "is_cold",
    "run",
]  # fmt: skip

_KERNEL: Any = None  # (kernel, variant) dispatchers, once imported
_WARM: set[str] = set()  # feature sets this process has run (their machine code is loaded)
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


def compile_message(features: Features) -> str:
    """What the first call of a feature set on a machine (and installation) prints while
    numba compiles it."""
    return (
        f"compiling vei's engine kernel for this machine ({features.name}; once per "
        "installation and feature set, about 10-60 s; later runs load it in about a second)"
    )


def _build() -> Any:
    """The compiled kernel's dispatchers (imports numba and the loop once; numba compiles
    or loads a feature set on its first call)."""
    global _KERNEL
    if _KERNEL is not None:
        return _KERNEL
    if not available():
        raise DependencyError("the compiled engine kernel needs numba (pip install numba)")
    from vei.sim.kernel.loop import kernel, kernel_seq, variant

    cache.drop_stale(kernel, variant, kernel_seq)
    _KERNEL = (kernel, variant, kernel_seq)
    return _KERNEL


def _cache_dir() -> Any:
    return cache.cache_dir(_build()[0])


def is_cold(features: Features = ALL_FEATURES) -> bool:
    """True when ``features`` has no machine code cached for this machine and installation
    yet (its first call compiles); False when it loads from the cache, or when numba is not
    installed."""
    if features.name in _WARM or not available():
        return False
    return cache.is_cold(_cache_dir(), features.name)


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
        variant-major buffer), or None), 'hit' ([B, T, n_o] or None), 'extra', 'final'
        (SimState fields), 'collision_time_s', 'min_center_distance_m', 'metrics'
        ([B, N_FUSED] rows of vei.metrics.fused.FUSED_METRICS, or None).
    """
    import numba

    from vei.io.progress import activity
    from vei.metrics.fused_layout import N_FUSED

    kernel = _build()[0]
    scored = metrics_cfg is not None
    feats = features_of(arrays, params, scored)
    t_n = arrays.n_steps
    b = params.batch_size
    tt = t_n if record else 1
    p_mat = np.ascontiguousarray(
        np.stack([np.asarray(getattr(params, f), dtype=np.float64) for f in PARAM_FIELDS])
    )
    p_mat[P_DELAY] = params.delay_steps(arrays.dt_s)
    out = out_group(state0, b, tt, hist_len, record)
    others = others_group(arrays, state0, b, tt) if feats.others else None
    xr = riders_group(arrays, state0, b, tt, record) if feats.riders else None
    dec = decisions_group(arrays) if feats.decisions else None
    traffic = traffic_group(arrays, state0, b, tt) if feats.traffic else None
    pol = policy_group(arrays, params) if feats.policy else None
    m_out = np.empty((b if scored else 1, N_FUSED))
    metrics = None
    if scored:
        t_m = np.ascontiguousarray(arrays.t_s, dtype=np.float64)
        dt_m = float(t_m[1] - t_m[0]) if t_m.size > 1 else 0.0  # as vei.types.Trace.dt_s
        metrics = (t_m, dt_m, np.ascontiguousarray(metrics_cfg, dtype=np.float64), m_out)
    cold = is_cold(feats)
    folder = _cache_dir()
    # Variants differ in cost (a collided one stops its rider's social force): the threads
    # take them in chunks of _CHUNK on demand, not one equal block each (which left a core
    # idle for ~20 % of the run of a batch sorted by time shift); results do not change.
    prev_chunk = numba.set_parallel_chunksize(_CHUNK)
    turn = cache.compiling(folder, feats.name) if cold else contextlib.nullcontext()
    try:
        with turn:
            cold = cold and cache.is_cold(folder, feats.name)  # another process may have
            announce = activity(compile_message(feats)) if cold else contextlib.nullcontext()
            with announce, warnings.catch_warnings():
                # a user's policy is a first-class function value (numba calls it experimental)
                warnings.simplefilter("ignore", numba.NumbaExperimentalFeatureWarning)
                args = (
                    t_n, float(arrays.dt_s), int(hist_len), bool(record),
                    ego_group(arrays), rider_group(arrays), p_mat, state_group(state0), out,
                    others, xr, dec, traffic, metrics, pol,
                )  # fmt: skip
                if pol is None or pol[0] is None:  # numba's parallel loop
                    kernel(*args)
                else:
                    _threads(_build()[2], b, args)
            if cold:
                cache.mark_compiled(folder, feats.name)
    finally:
        numba.set_parallel_chunksize(prev_chunk)
    _WARM.add(feats.name)
    if pol is not None:
        check_outputs(params, pol, arrays.dt_s)
    return _unpack(arrays, state0, record, tt, out, others, xr, traffic, m_out if scored else None)


def _threads(kernel_seq: Any, b: int, args: tuple[Any, ...]) -> None:
    """Run variants 0..b-1 by :func:`vei.sim.kernel.loop.kernel_seq` in chunks from
    numba's number of threads (each call releases the GIL; variants are independent, so
    the results do not depend on the chunking)."""
    import itertools
    import threading

    import numba

    n = max(1, min(numba.get_num_threads(), b))
    chunk = max(_CHUNK, -(-b // (8 * n)))
    if n == 1:
        kernel_seq(0, b, *args)
        return
    kernel_seq(0, min(chunk, b), *args)  # compiles or loads once, before the threads
    nxt = itertools.count(1)
    errors: list[BaseException] = []

    def work() -> None:
        try:
            while (lo := next(nxt) * chunk) < b:
                kernel_seq(lo, min(lo + chunk, b), *args)
        except BaseException as exc:  # noqa: BLE001 - re-raised in the caller
            errors.append(exc)

    pool = [threading.Thread(target=work) for _ in range(n)]
    for t in pool:
        t.start()
    for t in pool:
        t.join()
    if errors:
        raise errors[0]


def _unpack(
    arrays: Any, state0: Any, record: bool, tt: int, out: tuple, others: tuple | None,
    xr: tuple | None, traffic: tuple | None, metrics: np.ndarray | None,
) -> dict[str, Any]:  # fmt: skip
    """:func:`run`'s result from the kernel's output groups (see there)."""
    t_n = arrays.n_steps
    o, ob, fs, fb, fh, coll_t, min_d, secf = out
    final = {f: fs[j].copy() for j, f in enumerate(FLOAT_FIELDS)}
    final["cap_state"] = fs[FLOAT_FIELDS.index("cap_state")].astype(np.int8)
    final["rider_decision"] = fs[FLOAT_FIELDS.index("rider_decision")].astype(np.int8)
    for j, f in enumerate(BOOL_FIELDS):
        final[f] = fb[j].astype(bool)
    final["hist"] = fh
    final["k"] = t_n - 1
    if others is not None:
        final["hit_other"] = others[8].astype(bool)
        final["rider_hit_other"] = others[11].astype(bool)
    if xr is not None:
        for j, f in enumerate(EXTRA_FLOAT_FIELDS):
            final[f] = xr[-2][j].astype(np.int8) if f in EXTRA_INT_FIELDS else xr[-2][j].copy()
        for j, f in enumerate(EXTRA_BOOL_FIELDS):
            final[f] = xr[-1][j].astype(bool)
    secondary_final(secf, final)
    cars = cars_final(state0, traffic, final, record, tt)
    for f in state0._fields:  # fields the kernel does not advance keep their start values
        final.setdefault(f, getattr(state0, f))
    series = hit = extra = None
    if record:
        names = (
            "ego_s_m", "ego_x_m", "ego_y_m", "ego_yaw_rad", "ego_speed_mps", "ego_accel_mps2", "ego_command",
            "rider_x_m", "rider_y_m", "rider_yaw_rad", "rider_speed_mps", "rider_vx_mps", "rider_vy_mps",
            "rider_accel_mps2",
        )  # fmt: skip
        series = {n: o[:, j, :] for j, n in enumerate(names)}
        series["cap_state"] = ob[:, 0, :].astype(np.int8)
        series["rider_decision"] = ob[:, 3, :].astype(np.int8)
        series["rider_active"] = ob[:, 1, :].astype(bool)
        series["collided"] = ob[:, 2, :].astype(bool)
        b = o.shape[0]
        no = len(arrays.other_ids)
        hit = others[9].astype(bool) if others is not None else np.zeros((b, tt, no), bool)
        n_x = arrays.riders.n
        if xr is not None:
            outx, outxb = xr[25], xr[26]
        else:
            outx, outxb = np.zeros((b, 5, tt, n_x)), np.zeros((b, 2, tt, n_x), dtype=np.uint8)
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
        "metrics": metrics,
    }
