"""The built-in engine: batched, vectorised, deterministic closed-loop simulation.

One scenario, B variants (arrays with a leading batch axis ``[B]``), a fixed step. The
ego follows its recorded path with a speed set by its mode (replay of the recorded speed,
PID cruise, PID + CAP); the primary rider is replayed (time-shifted) or driven by social
forces; every other recorded road user is replayed. Collisions are oriented-box overlaps.

Entry points:
    arrays = prepare_scenario(scenario, SimConfig())               # once per scenario
    params = VariantParams.from_case(case_preset("normal-cap"), arrays, B, time_shift_s=...)
    result = simulate(arrays, params)                              # SimResult [B, T]
    # or, step by step (pure):
    state = initial_state(arrays, params); state = step(state, params, arrays)
    # or, the named configurations in one batch:
    result = run_cases(scenario, ["replay", "normal", ...], time_shift_s=2.0)
    # large batches: the compiled kernel (numba), same model, ~10x faster at B >= 1e3:
    result = simulate(arrays, params, record="none", kernel="auto")
    # a sweep's scalar metrics, scored inside the compiled kernel (no [B, T] series):
    frame = simulate_metrics(arrays, params, names=("collision", "min_ttc_s"))

Batch layout: :func:`simulate` sorts the variants into contiguous blocks of equal (ego
mode, rider model) so that each block runs only its own branches (no per-variant mode
masks), and restores the caller's order in the outputs.

Order of one step k -> k + 1 (t = k dt):
  1. CAP perception: the rider pose of step k - n (n = perception delay in steps; not
     perceived while k < n); corridor test on the ego path; CAP state machine.
  2. Ego: PID (or the CAP's braking demand) -> command u in [-1, 1] -> demanded
     acceleration -> first-order actuator lag -> v' = max(0, v + a dt) -> s' = s + v' dt
     (semi-implicit); replay-speed: s and v from the recording at t + dt.
  3. Rider: replay = the recording at (t + dt - shift) (inactive outside its span); SFM =
     forces from the state at step k (ego box at step k), semi-implicit Euler. An SFM
     rider enters at the first step whose shifted recording time reaches the track's
     start, with the recorded position, heading and velocity there; its goal is the point
     ``lookahead_m`` ahead along its own recorded path from its progress (the local
     projection of its position, never decreasing), the final point near the end; it
     leaves (inactive) once within ``arrive_radius_m`` of the final point and the
     recording's span is over.
  3b. Extra riders (``SimConfig.sfm_riders``, vei.sim.riders): the same social force on
     each from the state at step k, plus the repulsion between all SFM riders and from
     recorded pedestrians (which acts on the primary too in this mode); replayed in replay
     variants; ego contacts latched in ``extra_hit``.
  4. Collision of the new poses: ego box vs rider box (if active). On collision both stop
     (speed 0, frozen pose) and stay so to the end; recording continues. Ego vs replayed
     others: recorded (``hit_other``) but nothing stops.

Determinism: no randomness; the same inputs give bit-identical outputs, and the
computation of one variant does not depend on the others in the batch (B single runs
equal one batch of B).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import numpy.typing as npt

from vei.config import CASE_PRESETS, CaseConfig, SimConfig, case_preset
from vei.errors import ConfigError
from vei.policy.perception_random import label_keys
from vei.sim.batch import BatchFlags, Block, batch_flags, group_keys
from vei.sim.kernel.policy_pack import kernel_mask
from vei.sim.observe import PolicyDriver
from vei.sim.result import (
    _RECORDED,
    _RECORDED_BEHAVIOUR,
    _RECORDED_CARS,
    _RECORDED_EXTRA,
    _RECORDED_PEDS,
    SimResult,
)
from vei.sim.state import EGO_POLICY, ScenarioArrays, SimState, VariantParams, prepare_scenario
from vei.sim.step import initial_state, step
from vei.types import Scenario

if TYPE_CHECKING:
    import pandas as pd

    from vei.config.metrics import MetricsConfig

FloatArray = npt.NDArray[np.float64]
_XNAMES = tuple(name for name, _, _ in _RECORDED_EXTRA + _RECORDED_CARS + _RECORDED_PEDS)
#: Every [B, T] series the engine records (the behaviour's beside the digested ones).
_SERIES = _RECORDED + _RECORDED_BEHAVIOUR
Record = Literal["full", "none"]
Kernel = Literal["numpy", "numba", "auto"]


def simulate(
    arrays: ScenarioArrays,
    params: VariantParams,
    *,
    record: Record = "full",
    progress: bool = False,
    kernel: Kernel = "numpy",
) -> SimResult:
    """Run B variants of one scenario over the whole span (arrays.t_s).

    Args:
        arrays: from :func:`prepare_scenario` (fixes dt and the span).
        params: [B] variants.
        record: 'full' = every time series [B, T] (memory ~ 16 float64 x B x T);
            'none' = only the summaries (collision time, minimum centre distance) and the
            final state (sweeps that score online, benchmarks).
        progress: show a rich progress bar (when stderr is a terminal; NumPy kernel).
            Policy variants (ego_mode 3, vei.policy) always run the NumPy step loop with
            :class:`vei.sim.observe.PolicyDriver`; the other variants of the batch keep
            the requested kernel.
        kernel: 'numpy' (default): the reference, :func:`step` in a loop; 'numba': the
            compiled kernel :mod:`vei.sim.kernel` (same model, ~10-50x faster at large B,
            needs numba; agrees with 'numpy' to rounding, not bit for bit); 'auto':
            'numba' when importable, else 'numpy'. Each kernel on its own is deterministic
            and batch-invariant (B single runs equal one batch of B, bit for bit).
    Returns:
        SimResult.
    """
    if record not in ("full", "none"):
        raise ConfigError(f"record must be 'full' or 'none', got {record!r}")
    if kernel not in ("numpy", "numba", "auto"):
        raise ConfigError(f"kernel must be 'numpy', 'numba' or 'auto', got {kernel!r}")
    from vei.sim import kernel as compiled

    use_numba = kernel == "numba" or (kernel == "auto" and compiled.available())
    # social-force pedestrians (vei.sim.pedestrians) run the NumPy step only
    use_numba = use_numba and not (arrays.peds.n and bool(params.peds_sfm.any()))
    # Group the variants into contiguous blocks of equal (ego mode, rider model, policy);
    # the outputs are put back into the caller's order at the end.
    keys = group_keys(params)
    perm = np.argsort(keys, kind="stable")
    # Policy variants (ego_mode 3) sort last and run the NumPy step loop, but for those the
    # compiled kernel runs (aeb, idm, compiled policies: vei.sim.kernel.policy_pack), which
    # sort before them with the others; all keep the requested kernel.
    in_kernel = kernel_mask(params) if use_numba else params.ego_mode != EGO_POLICY
    perm = perm[np.argsort(~in_kernel[perm], kind="stable")]
    sorted_already = bool(np.all(perm == np.arange(perm.size)))
    run_params = params if sorted_already else params.take(perm)
    b = params.batch_size
    n_kernel = int(np.count_nonzero(in_kernel))
    # Perception draws are keyed by each variant's label (a sweep's variant id, a run's
    # configuration name), not by its position: the same in any batch (vei run = sweep).
    vkeys = label_keys(params.labels)[perm] if n_kernel < b else None
    if use_numba and 0 < n_kernel < b:
        parts = [
            _run_sorted(arrays, run_params.take(slice(0, n_kernel)), record, progress, True),
            _run_sorted(
                arrays,
                run_params.take(slice(n_kernel, b)),
                record,
                progress,
                False,
                None if vkeys is None else vkeys[n_kernel:],
            ),
        ]
        bufs, hit_buf, xbufs, coll_t, min_d, state, v2x = _merge_runs(parts)
    else:
        bufs, hit_buf, xbufs, coll_t, min_d, state, v2x = _run_sorted(
            arrays, run_params, record, progress, use_numba and n_kernel == b, vkeys
        )
    if not sorted_already:
        inv = np.empty_like(perm)
        inv[perm] = np.arange(perm.size)
        for name in bufs:
            bufs[name] = bufs[name][:, inv]
        if hit_buf is not None:
            hit_buf = hit_buf[:, inv]
        for name in xbufs:
            xbufs[name] = xbufs[name][:, inv]
        coll_t, min_d = coll_t[inv], min_d[inv]
        if v2x is not None:
            v2x = {name: values[inv] for name, values in v2x.items()}
        state = SimState(
            **{
                name: (val if name == "k" else val[:, :, inv] if name == "hist" else val[inv])
                for name, val in zip(SimState._fields, state, strict=True)
            }
        )
    series: dict[str, np.ndarray | None] = {
        name: (bufs[name].T if bufs else None) for name, _, _ in _SERIES
    }
    return SimResult(
        t_s=arrays.t_s.copy(),
        labels=params.labels.copy(),
        params=params,
        scenario_id=arrays.scenario_id,
        rider_id=arrays.rider_id,
        rider_category=arrays.rider_category,
        ego_length_m=arrays.ego_length_m,
        ego_width_m=arrays.ego_width_m,
        rider_length_m=arrays.rider_length_m,
        rider_width_m=arrays.rider_width_m,
        hit_other=None if hit_buf is None else hit_buf.transpose(1, 0, 2),
        collision_time_s=coll_t,
        min_center_distance_m=min_d,
        other_ids=arrays.other_ids,
        other_categories=arrays.other_categories,
        other_length_m=arrays.other_length_m,
        other_width_m=arrays.other_width_m,
        other_x_m=arrays.other_x_m,
        other_y_m=arrays.other_y_m,
        other_yaw_rad=arrays.other_yaw_rad,
        other_speed_mps=arrays.other_speed_mps,
        other_active=arrays.other_active,
        final_state=state,
        extra_ids=arrays.riders.ids,
        extra_categories=arrays.riders.categories,
        extra_length_m=arrays.riders.length_m,
        extra_width_m=arrays.riders.width_m,
        car_ids=tuple(arrays.other_ids[j] for j in arrays.traffic.idx),
        ped_ids=tuple(arrays.other_ids[j] for j in arrays.peds.idx),
        routes=arrays.routes,
        v2x=v2x,
        **{name: (xbufs[name].transpose(1, 0, 2) if name in xbufs else None) for name in _XNAMES},
        **series,
    )


def _run_sorted(
    arrays: ScenarioArrays,
    run_params: VariantParams,
    record: Record,
    progress: bool,
    use_numba: bool,
    variant_keys: npt.NDArray[np.uint64] | None = None,
) -> tuple[Any, ...]:
    """Run a batch already sorted into blocks; returns ([T, B] series buffers, hit
    buffer, extra-rider buffers, collision times, minimum distances, final state, what V2X
    did (vei.sim.observe.PolicyDriver.v2x_report; None without V2X))."""
    from vei.sim import kernel as compiled

    fl = batch_flags(run_params, arrays.dt_s)
    b, t_n = run_params.batch_size, arrays.n_steps
    no = len(arrays.other_ids)
    state = initial_state(arrays, run_params, fl)
    bufs: dict[str, np.ndarray] = {}
    xbufs: dict[str, np.ndarray] = {}  # extra riders [T, B, R]
    n_x = arrays.riders.n
    hit_buf = None
    if record == "full":
        for name, _, dtype in _SERIES:
            bufs[name] = np.empty((t_n, b), dtype=dtype)
        hit_buf = np.empty((t_n, b, no), dtype=bool)
        for name, _, dtype in _RECORDED_EXTRA:
            xbufs[name] = np.empty((t_n, b, n_x), dtype=dtype)
        for name, _, dtype in _RECORDED_CARS:  # reacting cars [T, B, C]
            xbufs[name] = np.empty((t_n, b, arrays.traffic.n), dtype=dtype)
        if not use_numba:  # pedestrians [T, B, P] (the NumPy step only)
            for name, _, dtype in _RECORDED_PEDS:
                xbufs[name] = np.empty((t_n, b, arrays.peds.n), dtype=dtype)
    coll_t = np.full(b, np.nan)
    min_d = np.full(b, np.inf)

    def _rec(st: SimState) -> None:
        k = st.k
        if bufs:
            for name, attr, _ in _SERIES:
                bufs[name][k] = getattr(st, attr)
            hit_buf[k] = st.hit_other
            for name, attr, _ in _RECORDED_EXTRA + _RECORDED_CARS + _RECORDED_PEDS:
                if name in xbufs:
                    xbufs[name][k] = getattr(st, attr)
        newly = st.collided & np.isnan(coll_t)
        if newly.any():
            coll_t[newly] = arrays.t_s[k]
        dx = st.rider_x_m - st.ego_x_m
        dy = st.rider_y_m - st.ego_y_m
        d = np.sqrt(dx * dx + dy * dy)
        np.minimum(min_d, np.where(st.rider_active, d, np.inf), out=min_d)

    if use_numba:
        out = compiled.run(arrays, run_params, state, fl.hist_len, record == "full")
        # Variant-major [B, T] series: store as time-major views so that the common
        # code ([T, B] buffers, transposed at the end) applies.
        if out["series"] is not None:
            bufs = {name: arr.T for name, arr in out["series"].items()}
            hit_buf = out["hit"].transpose(1, 0, 2)
            xbufs = {name: arr.transpose(1, 0, 2) for name, arr in out["extra"].items()}
        return (
            bufs,
            hit_buf,
            xbufs,
            out["collision_time_s"],
            out["min_center_distance_m"],
            SimState(**out["final"]),
            None,
        )
    driver = PolicyDriver(arrays, run_params, fl, variant_keys) if fl.any_policy else None
    _rec(state)
    bar = None
    task = None
    if progress:
        import sys

        if sys.stderr.isatty():
            from rich.progress import Progress

            bar = Progress(transient=True)
            bar.start()
            task = bar.add_task(f"simulating {b} variant(s)", total=t_n - 1)
    try:
        for _ in range(1, t_n):
            action = driver.act(state) if driver is not None else None
            state = step(state, run_params, arrays, fl, action)
            _rec(state)
            if bar is not None:
                bar.advance(task)
    finally:
        if bar is not None:
            bar.stop()
    return (
        bufs,
        hit_buf,
        xbufs,
        coll_t,
        min_d,
        state,
        (driver.v2x_report() if driver is not None else None),
    )


def _merge_runs(parts: list[tuple[Any, ...]]) -> tuple[Any, ...]:
    """Concatenate :func:`_run_sorted` outputs along the batch axis (in order)."""
    (b0, h0, x0, c0, m0, s0, v0), (b1, h1, x1, c1, m1, s1, v1) = parts
    bufs = {name: np.concatenate([b0[name], b1[name]], axis=1) for name in b0}
    hit = None if h0 is None else np.concatenate([h0, h1], axis=1)
    xb = {name: np.concatenate([x0[name], x1[name]], axis=1) for name in x0}
    hl = max(s0.hist.shape[1], s1.hist.shape[1])

    def pad(h: np.ndarray) -> np.ndarray:
        return np.pad(h, ((0, 0), (0, hl - h.shape[1]), (0, 0)))

    merged = {
        name: (
            v0 if name == "k"
            else np.concatenate([pad(v0), pad(v1)], axis=2) if name == "hist"
            else np.concatenate([v0, v1], axis=0)
        )
        for name, v0, v1 in zip(SimState._fields, s0, s1, strict=True)
    }  # fmt: skip
    v2x = None
    if v0 is not None or v1 is not None:
        from vei.policy.v2x.report import empty

        v0 = empty(c0.size) if v0 is None else v0
        v1 = empty(c1.size) if v1 is None else v1
        v2x = {name: np.concatenate([v0[name], v1[name]]) for name in v0}
    return (bufs, hit, xb, np.concatenate([c0, c1]), np.concatenate([m0, m1]),
            SimState(**merged), v2x)  # fmt: skip


def simulate_metrics(
    arrays: ScenarioArrays,
    params: VariantParams,
    cfg: MetricsConfig | None = None,
    *,
    names: Sequence[str],
    kernel: Kernel = "auto",
    full_batch: int = 256,
) -> pd.DataFrame:
    """Scalar metrics of B variants, without keeping their time series.

    Variants the compiled kernel runs (every ego mode but a policy, with kernel 'numba',
    or 'auto' and numba importable) are scored inside it: each keeps its own [T] channels
    (ego pose, speed, acceleration; rider pose, speed, presence, collision) as scratch and
    :func:`vei.metrics.fused.run_metrics` turns them into one row at the end of the
    variant, so memory is O(B x n_metrics + threads x T), never B x T. The others (policy
    variants, which run the NumPy step loop; every variant with kernel 'numpy' or without
    numba; metrics without a fused implementation) run ``simulate(record='full')`` in
    sub-batches of ``full_batch`` and are scored by :func:`vei.metrics.summarize`. Either
    way a row equals ``summarize(as_timeseries_trace(simulate(...).to_trace()), cfg,
    names=names, params={rider mass, full brake of each variant})`` bit for bit (what a
    sweep stored before; tests/sim/test_engine_metrics.py).

    Args:
        arrays: from :func:`prepare_scenario`. params: [B] variants.
        cfg: metric thresholds (vei.metrics.MetricsConfig; paper defaults when None).
        names: scalar metric names (vei.metrics.SCALAR_METRICS).
        kernel: as :func:`simulate`.
        full_batch: variants per full-recording sub-batch of the fallback (memory ~ 16
            float64 x full_batch x T).
    Returns:
        DataFrame of B rows in ``params`` order, one column per name (dtypes as
        summarize's: bool collision flags, '' / label strings, float otherwise).
    """
    import pandas as pd

    from vei.config.metrics import MetricsConfig
    from vei.metrics import as_timeseries_trace, sensor_params, summarize
    from vei.sim import kernel as compiled

    if kernel not in ("numpy", "numba", "auto"):
        raise ConfigError(f"kernel must be 'numpy', 'numba' or 'auto', got {kernel!r}")
    if full_batch < 1:
        raise ConfigError(f"full_batch must be >= 1, got {full_batch}")
    cfg = MetricsConfig() if cfg is None else cfg
    names = tuple(names)
    b = params.batch_size
    if b < 1:
        raise ConfigError("simulate_metrics needs at least one variant")
    use_numba = kernel == "numba" or (kernel == "auto" and compiled.available())
    fused = np.zeros(b, dtype=bool)
    from vei.metrics.fused_layout import FUSED_METRICS, config_vector, metrics_frame

    if use_numba and all(n in kernel_metrics() for n in names):
        fused = kernel_mask(params) & ~(params.peds_sfm & bool(arrays.peds.n))
    parts: list[tuple[np.ndarray, pd.DataFrame]] = []
    idx = np.flatnonzero(fused)
    if idx.size:
        sub = params.take(idx)
        perm = np.argsort(group_keys(sub), kind="stable")  # blocks, as simulate runs them
        run_params = sub.take(perm)
        fl = batch_flags(run_params, arrays.dt_s)
        state = initial_state(arrays, run_params, fl)
        out = compiled.run(arrays, run_params, state, fl.hist_len, False, config_vector(cfg))
        rows = np.empty_like(out["metrics"])
        rows[perm] = out["metrics"]
        frame = metrics_frame(rows, [n for n in names if n in FUSED_METRICS], cfg)
        if len(frame.columns) < len(names):  # secondary collisions, where: the kernel's state
            frame = _with_state_metrics(
                frame, names, arrays, sub, out["final"], out["collision_time_s"], perm
            )
        parts.append((idx, frame))
    rest = np.flatnonzero(~fused)
    for start in range(0, rest.size, full_batch):
        sel = rest[start : start + full_batch]
        sub = params.take(sel)
        result = simulate(arrays, sub, record="full", kernel=kernel)
        run_params = {
            "rider_mass_kg": sub.mass_kg,
            "ego_max_decel_mps2": sub.max_decel_mps2_ego,
            **sensor_params(list(sub.perception)),
        }
        trace = as_timeseries_trace(result.to_trace())
        parts.append((sel, summarize(trace, cfg, names=names, params=run_params)))
    if len(parts) == 1:
        return parts[0][1]
    order = np.concatenate([i for i, _ in parts])
    frame = pd.concat([f for _, f in parts], ignore_index=True)
    return frame.iloc[np.argsort(order, kind="stable")].reset_index(drop=True)


def kernel_metrics() -> tuple[str, ...]:
    """The scalar metrics :func:`simulate_metrics` scores inside the compiled kernel's pass:
    the fused ones (vei.metrics.fused_layout.FUSED_METRICS), the secondary collisions
    (vei.metrics.secondary: the kernel's own contact latches) and where the contacts
    happened (vei.metrics.where: from the kernel's final state)."""
    from vei.metrics.fused_layout import FUSED_METRICS
    from vei.metrics.secondary import SECONDARY_METRICS
    from vei.metrics.where import WHERE_METRICS

    return FUSED_METRICS + SECONDARY_METRICS + WHERE_METRICS


def _with_state_metrics(
    frame: pd.DataFrame,
    names: Sequence[str],
    arrays: ScenarioArrays,
    params: VariantParams,
    final: dict[str, np.ndarray],
    collision_time_s: np.ndarray,
    perm: npt.NDArray[np.intp],
) -> pd.DataFrame:
    """``frame`` with the requested secondary-collision and where columns from the
    kernel's final state and [B] collision times (its variants sorted by ``perm`` from
    ``params``' order), in ``names`` order."""
    import pandas as pd

    from vei.continuation.where import run_where
    from vei.metrics.secondary import secondary_column, secondary_record
    from vei.metrics.where import WHERE_METRICS, where_column
    from vei.sim.contacts import agent_name

    def back(a: np.ndarray) -> np.ndarray:
        out = np.empty_like(a)
        out[perm] = a
        return out

    ids = (arrays.rider_id, arrays.other_ids, arrays.riders.ids)
    rec = secondary_record(
        back(final["sec_count"]), back(final["sec_first_t_s"]),
        [agent_name(int(c), *ids) for c in back(final["sec_striker"])],
        [agent_name(int(c), *ids) for c in back(final["sec_struck"])],
        back(final["sec_max_speed_mps"]), back(final["rear_end"]),
    )  # fmt: skip
    b = perm.size
    labels = run_where(
        dict(arrays.routes), arrays.rider_id,
        collision_time_s=back(np.asarray(collision_time_s)),
        time_shift_s=params.time_shift_s,
        rider_xy_m=np.stack([back(final["rider_x_m"]), back(final["rider_y_m"])], axis=-1),
        rider_sfm=params.rider_sfm, secondary_time_s=rec["first_t_s"],
        secondary_striker=list(rec["striker"]), secondary_struck=list(rec["struck"]),
    )  # fmt: skip
    cols = {}
    for n in names:
        if n in frame.columns:
            cols[n] = frame[n]
        elif n in WHERE_METRICS:
            cols[n] = where_column(n, labels, b)
        else:
            cols[n] = secondary_column(n, rec, b)
    return pd.DataFrame(cols)


def run_cases(
    scenario: Scenario | ScenarioArrays,
    cases: Sequence[str | CaseConfig],
    *,
    time_shift_s: float = 0.0,
    sim: SimConfig | None = None,
    record: Record = "full",
    kernel: Kernel = "numpy",
) -> SimResult:
    """Run several configurations (names of CASE_PRESETS or CaseConfigs) as one batch.

    Variant i is ``cases[i]`` with the same time shift; ``labels`` are the case names.

    Args:
        scenario: a Scenario (prepared with ``sim``) or already prepared arrays.
        cases: e.g. ``PAPER_CASES``. time_shift_s: the rider's time shift [s].
        sim: engine settings (ignored when arrays are passed).
        record, kernel: as :func:`simulate`.
    Returns:
        SimResult with B = len(cases).
    """
    arrays = scenario if isinstance(scenario, ScenarioArrays) else prepare_scenario(scenario, sim)
    parts = []
    for c in cases:
        case = c if isinstance(c, CaseConfig) else case_preset(c)
        parts.append(VariantParams.from_case(case, arrays, 1, time_shift_s=time_shift_s))
    if not parts:
        raise ConfigError("run_cases needs at least one configuration")
    return simulate(arrays, VariantParams.concat(parts), record=record, kernel=kernel)


__all__ = [
    "CASE_PRESETS",
    "SimState",
    "ScenarioArrays",
    "VariantParams",
    "_RECORDED",
    "BatchFlags",
    "Block",
    "group_keys",
    "SimResult",
    "batch_flags",
    "initial_state",
    "prepare_scenario",
    "run_cases",
    "simulate",
    "simulate_metrics",
    "step",
]
