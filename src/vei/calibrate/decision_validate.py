"""Validation of the rider's yield / go decision on the recordings, leave-one-scenario-out.

For every scenario with rider tracks the gap-acceptance model is fitted on the cases of
the other scenarios (:func:`vei.calibrate.decisions.fit_gap_acceptance`; where they hold
no yield or no go case, the *arrive-first* rule t_c = 0 s: the rider goes when it would
reach the zone first) and the held-out riders are checked:

- **decisions, open loop**: each recorded case (:func:`~vei.calibrate.decisions.
  extract_cases`) predicted go when its offered gap DTA >= t_c; accuracy against the
  recorded outcome;
- **decisions, closed loop**: the whole segment simulated from its first sample by the
  calibrated social-force rider (:mod:`vei.calibrate.rollout`: speeds from its own
  recording, the rest the training population's; the recorded vehicles' repulsion) with
  decisions (:mod:`vei.models.decision_core` against every recorded vehicle whose path
  crosses its own, each conflict decided on its own, the strongest speed cap wins);
  who enters each case's zone first, against the recording;
- **riders that stop** (the recorded segment, once riding (> 1 m/s), stands: speed < 0.5
  m/s for >= 1 s): the median speed while present, simulated against recorded (within
  30 %?), and where the first such stop is along the path (within 3 m?), with and without
  decisions; the whole segment simulated from its first sample on paths whose jittering
  waits collapse (as the engine's);
- **every rider**: ADE / FDE of the windows of :func:`vei.calibrate.validate.validate_loso`
  (3 s, 5 s) with decisions against the calibrated SFM without.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt

from vei.calibrate.decisions import (
    CLEAR_MARGIN_M,
    HORIZON_S,
    STOP_MIN_S,
    STOP_MPS,
    ConflictTrack,
    DecisionCase,
    extract_cases,
    fit_gap_acceptance,
    no_fit_reason,
    rider_conflicts,
)
from vei.calibrate.fit import fit_tracks
from vei.calibrate.profile import build_profile, params_for_recorded_rider
from vei.calibrate.rollout import (
    PARAM_NAMES,
    PackedPaths,
    Windows,
    displacement_errors,
    make_windows,
    pack_paths,
    sfm_force,
)
from vei.calibrate.tracks import RiderTrack, SceneTracks
from vei.errors import InputError
from vei.models import decision_core as core

FloatArray = npt.NDArray[np.float64]
#: t_c [s] where a training fold holds no go or no yield case: go when arriving first.
ARRIVE_FIRST_S = 0.0
#: Tolerances of the stop profile: median speed ratio, stop position [m].
SPEED_TOLERANCE = 0.30
STOP_TOLERANCE_M = 3.0


@dataclass(frozen=True)
class WindowConflicts:
    """The conflicts of B windows (K per window, padded; ``valid`` marks real ones).

    Attributes:
        s_rider_m, s_vehicle_m, hz_rider_m, hz_vehicle_m, valid: [B, K].
        veh_arc_m, veh_speed_mps: [B, H + 1, K] the vehicle along its path (+inf arc once it
            is gone: it has left every zone).
        v_ref_mps: [B] unused here (the engine's speed floor comes from the parameters).
    """

    s_rider_m: FloatArray
    s_vehicle_m: FloatArray
    hz_rider_m: FloatArray
    hz_vehicle_m: FloatArray
    valid: npt.NDArray[np.bool_]
    veh_arc_m: FloatArray
    veh_speed_mps: FloatArray


def window_conflicts(
    win: Windows, tracks: Sequence[RiderTrack], conflicts: Sequence[Sequence[ConflictTrack]]
) -> WindowConflicts:
    """Per-window conflict arrays from each track's conflicts (conflicts[j] of tracks[j])."""
    b, h = win.size, win.horizon_steps
    k = max([len(conflicts[j]) for j in set(win.track.tolist())], default=0)
    k = max(k, 1)
    z = np.zeros((b, k))
    out = {n: z.copy() for n in ("s_rider_m", "s_vehicle_m", "hz_rider_m", "hz_vehicle_m")}
    valid = np.zeros((b, k), dtype=bool)
    arc = np.full((b, h + 1, k), np.inf)
    sp = np.zeros((b, h + 1, k))
    for i in range(b):
        j, s0 = int(win.track[i]), int(win.start[i])
        for m, c in enumerate(conflicts[j]):
            out["s_rider_m"][i, m] = c.s_rider_m
            out["s_vehicle_m"][i, m] = c.s_vehicle_m
            out["hz_rider_m"][i, m] = c.hz_rider_m
            out["hz_vehicle_m"][i, m] = c.hz_vehicle_m
            valid[i, m] = True
            a = c.veh_arc_m[s0 : s0 + h + 1]
            v = c.veh_speed_mps[s0 : s0 + h + 1]
            arc[i, : a.size, m] = np.where(np.isfinite(a), a, np.inf)
            sp[i, : v.size, m] = np.nan_to_num(v)
    return WindowConflicts(**out, valid=valid, veh_arc_m=arc, veh_speed_mps=sp)


def rollout_decisions(
    paths: PackedPaths,
    win: Windows,
    params: dict[str, FloatArray],
    conf: WindowConflicts,
    decide: dict[str, FloatArray],
) -> tuple[FloatArray, FloatArray]:
    """Closed-loop social-force rollouts of every window with the yield / go decision.

    Args:
        paths, win, params: as :func:`vei.calibrate.rollout.rollout_sfm`.
        conf: the windows' conflicts. decide: [B] critical_gap_s, horizon_s,
            yield_decel_mps2, stop_margin_m.
    Returns:
        (x_m, y_m) [B, H + 1].
    """
    b, h, dt = win.size, win.horizon_steps, win.dt_s
    p = {n: np.broadcast_to(np.asarray(params[n], dtype=np.float64), (b,)) for n in PARAM_NAMES}
    kk = conf.valid.shape[1]
    x, y = win.x0_m.copy(), win.y0_m.copy()
    vx, vy = win.vx0_mps.copy(), win.vy0_mps.copy()
    prog = win.prog0_m.copy()
    outx, outy = np.empty((b, h + 1)), np.empty((b, h + 1))
    outx[:, 0], outy[:, 0] = x, y
    inv_m = 1.0 / p["mass_kg"]
    vmax = p["max_speed_mps"]
    rows = paths.rows(win.track)
    state = np.zeros((b, kk), dtype=np.int8)
    v_ref = core.reference_speed_core(p["v0_mps"], p["lookahead_m"], p["sigma_m"])[:, None]
    tau = (p["mass_kg"] / p["k_des_nspm"])[:, None]
    d = {n: np.asarray(decide[n], dtype=np.float64)[:, None] for n in decide}
    for k in range(h):
        veh = (
            win.veh_x_m[:, k], win.veh_y_m[:, k], win.veh_yaw_rad[:, k],
            win.veh_length_m[:, k], win.veh_width_m[:, k], win.veh_active[:, k],
        )  # fmt: skip
        gi, w = paths.index_rows(rows, prog)
        q = paths.at4(gi, w)
        pr = np.maximum(prog + (x - q[:, 0]) * q[:, 2] + (y - q[:, 1]) * q[:, 3], prog)
        sp = np.sqrt(vx * vx + vy * vy)
        d_r, tta_r, dta, t_clear, live = core.conflict_times_core(
            pr[:, None], sp[:, None], conf.veh_arc_m[:, k], conf.veh_speed_mps[:, k],
            conf.s_rider_m, conf.s_vehicle_m, conf.hz_rider_m, conf.hz_vehicle_m,
            CLEAR_MARGIN_M, v_ref,
        )  # fmt: skip
        live = live & conf.valid
        state = core.decide_core(
            state, live, dta, tta_r, d_r, d["critical_gap_s"], d["horizon_s"]
        ).astype(np.int8)
        cap = core.yield_speed_core(
            state, d_r, sp[:, None], tta_r, t_clear, d["stop_margin_m"],
            d["yield_decel_mps2"], tau,
        )  # fmt: skip
        fx, fy, prog = sfm_force(paths, rows, x, y, vx, vy, prog, p, veh, cap.min(axis=1))
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


#: A rider rides once faster than this [m/s]; the stops validated come after that (the
#: wait a segment may start with is the camera's first sight of it, not a decision).
RIDING_MPS = 1.0


def first_stop(speed: FloatArray, dt_s: float) -> int:
    """Index where the first stop after the rider first rides begins (speed < STOP_MPS for
    >= STOP_MIN_S after it exceeded RIDING_MPS), -1 if none."""
    riding = np.flatnonzero(speed > RIDING_MPS)
    if riding.size == 0:
        return -1
    run = 0
    need = int(round(STOP_MIN_S / dt_s))
    for i in range(int(riding[0]), speed.size):
        run = run + 1 if speed[i] < STOP_MPS else 0
        if run >= need:
            return i - run + 1
    return -1


@dataclass(frozen=True)
class StopProfile:
    """One recorded rider that stops, and its simulations.

    Attributes:
        key: scenario/track. median_speed_mps: recorded median speed while present.
        median_speed_sfm_mps, median_speed_decide_mps: simulated (without / with decisions).
        stop_arc_m: where the recorded first stop begins, along its path [m].
        stop_error_sfm_m, stop_error_decide_m: distance [m] of the simulated first stop
            from it (NaN: the simulated rider never stops).
    """

    key: str
    median_speed_mps: float
    median_speed_sfm_mps: float
    median_speed_decide_mps: float
    stop_arc_m: float
    stop_error_sfm_m: float
    stop_error_decide_m: float

    def ok(self, decide: bool = True) -> tuple[bool, bool]:
        """(median speed within SPEED_TOLERANCE, stop within STOP_TOLERANCE_M)."""
        med = self.median_speed_decide_mps if decide else self.median_speed_sfm_mps
        err = self.stop_error_decide_m if decide else self.stop_error_sfm_m
        return (
            abs(med / self.median_speed_mps - 1.0) <= SPEED_TOLERANCE,
            bool(np.isfinite(err) and err <= STOP_TOLERANCE_M),
        )


@dataclass(frozen=True)
class DecisionValidation:
    """Result of :func:`validate_decisions` (see the module).

    Attributes:
        cases: every recorded case. fit: the fit on all of them (GapFit).
        folds: held-out scenario -> the t_c used [s].
        open_loop_correct, closed_loop_correct: [n cases] bool (closed loop NaN-free:
            False where the simulated rider never reached the zone).
        stops: the riders that stop. ade_m, fde_m: {model: {horizon: mean}} of the windows
            ('SFM calibrated', 'SFM decisions'). n_windows: {horizon: windows}.
        fit_reason: why there is no fit ('' when there is one).
        folds_without_fit: held-out scenario -> why its training cases had no fit (its t_c
            is then :data:`ARRIVE_FIRST_S`).
    """

    cases: tuple[DecisionCase, ...]
    fit: object
    folds: dict[str, float]
    open_loop_correct: npt.NDArray[np.bool_]
    closed_loop_correct: npt.NDArray[np.bool_]
    stops: tuple[StopProfile, ...]
    ade_m: dict[str, dict[float, float]] = field(default_factory=dict)
    fde_m: dict[str, dict[float, float]] = field(default_factory=dict)
    n_windows: dict[float, int] = field(default_factory=dict)
    fit_reason: str = ""
    folds_without_fit: dict[str, str] = field(default_factory=dict)

    def format(self) -> str:
        """The figures as text (``vei calibrate decisions``)."""
        return "\n".join(_lines(self))

    def to_dict(self) -> dict:
        """JSON-ready form (decisions.json)."""
        return _document(self)


def _fold_tc(cases: Sequence[DecisionCase]) -> float:
    outs = {c.outcome for c in cases}
    if outs != {"go", "yield"}:
        return ARRIVE_FIRST_S
    return float(fit_gap_acceptance(cases, bootstrap=0).critical_gap_s)


def _params(profile: dict, tracks: Sequence[RiderTrack], idx: FloatArray) -> dict:
    rows = [
        params_for_recorded_rider(
            profile,
            tr.category,
            tr.median_moving_speed_mps(),
            float(np.quantile(tr.speed_mps, 0.99)),
        )
        for tr in tracks
    ]
    return {k: np.array([rows[j][k] for j in idx]) for k in rows[0]}


def _decide_params(b: int, t_c: float, horizon_s: float) -> dict[str, FloatArray]:
    from vei.config.behaviour import DecisionConfig

    d = DecisionConfig()
    return {
        "critical_gap_s": np.full(b, t_c),
        "horizon_s": np.full(b, horizon_s),
        "yield_decel_mps2": np.full(b, d.yield_decel_mps2),
        "stop_margin_m": np.full(b, d.stop_margin_m),
    }


def validate_decisions(
    scenes: Sequence[SceneTracks],
    horizons_s: Sequence[float] = (3.0, 5.0),
    *,
    decision_horizon_s: float = HORIZON_S,
    dt_s: float = 0.05,
) -> DecisionValidation:
    """Leave-one-scenario-out validation of the decisions (see the module docstring)."""
    from vei.calibrate.rollout import rollout_sfm

    folds = [s.scenario for s in scenes if s.riders]
    if len(folds) < 2:
        raise InputError(
            f"leave-one-scenario-out needs riders in >= 2 scenarios, found {len(folds)}"
        )
    by_name = {s.scenario: s for s in scenes}
    cases = extract_cases(scenes, decision_horizon_s)
    reason = no_fit_reason(cases)
    fit = fit_gap_acceptance(cases) if reason is None else None
    fold_reasons: dict[str, str] = {}
    tc_of: dict[str, float] = {}
    open_ok = np.zeros(len(cases), dtype=bool)
    closed_ok = np.zeros(len(cases), dtype=bool)
    stops: list[StopProfile] = []
    errs: dict[str, dict[float, list]] = {
        m: {h: [] for h in horizons_s} for m in ("SFM calibrated", "SFM decisions")
    }
    fdes: dict[str, dict[float, list]] = {m: {h: [] for h in horizons_s} for m in errs}
    for held in folds:
        train_cases = [c for c in cases if c.scenario != held]
        t_c = _fold_tc(train_cases)
        tc_of[held] = t_c
        why = no_fit_reason(train_cases)
        if why is not None:
            fold_reasons[held] = why
        for i, c in enumerate(cases):
            if c.scenario == held:
                open_ok[i] = (c.dta_s >= t_c) == (c.outcome == "go")
        train = [t for s in scenes if s.scenario != held for t in s.riders]
        test = list(by_name[held].riders)
        profile = build_profile(
            fit_tracks(train, by_name, dt_s=dt_s, bootstrap=0), {"held_out": held}
        )
        paths = pack_paths(test)
        whole = pack_paths(test, collapse_waits=True)  # standing starts: no jitter loops
        confl = [rider_conflicts(by_name[held], tr) for tr in test]
        # whole segments from their first sample
        for j, tr in enumerate(test):
            h = tr.t_s.size - 1
            win = make_windows(test, by_name, whole, h * dt_s, dt_s=dt_s, starts=[(j, 0)])
            prm = _params(profile, test, win.track)
            x0, y0 = rollout_sfm(whole, win, prm)
            x1, y1 = rollout_decisions(
                whole,
                win,
                prm,
                window_conflicts(win, test, confl),
                _decide_params(1, t_c, decision_horizon_s),
            )
            sim_arc = [_arc_on(whole, j, xx[0], yy[0]) for xx, yy in ((x0, y0), (x1, y1))]
            for i, c in enumerate(cases):
                if c.scenario == held and c.rider == tr.track_id:
                    cf = next(cc for cc in confl[j] if cc.vehicle == c.vehicle)
                    closed_ok[i] = _entered_first(sim_arc[1], cf) == (c.outcome == "go")
            sp_rec = tr.speed_mps
            k_rec = first_stop(sp_rec, dt_s)
            if k_rec < 0:
                continue
            arc_rec = whole.arc_m[j]
            meds = []
            stop_err = []
            for xx, yy, arc in ((x0, y0, sim_arc[0]), (x1, y1, sim_arc[1])):
                sp = np.hypot(np.diff(xx[0]), np.diff(yy[0])) / dt_s
                meds.append(float(np.median(sp)))
                ks = first_stop(sp, dt_s)
                stop_err.append(float(abs(arc[ks] - arc_rec[k_rec])) if ks >= 0 else float("nan"))
            stops.append(
                StopProfile(
                    f"{held}/{tr.track_id}",
                    float(np.median(sp_rec)),
                    meds[0],
                    meds[1],
                    float(arc_rec[k_rec]),
                    stop_err[0],
                    stop_err[1],
                )
            )
        for h in horizons_s:
            win = make_windows(test, by_name, paths, h, 0.5, dt_s)
            if win.size == 0:
                continue
            prm = _params(profile, test, win.track)
            preds = {
                "SFM calibrated": rollout_sfm(paths, win, prm),
                "SFM decisions": rollout_decisions(
                    paths,
                    win,
                    prm,
                    window_conflicts(win, test, confl),
                    _decide_params(win.size, t_c, decision_horizon_s),
                ),
            }
            for m, (x, y) in preds.items():
                a, f = displacement_errors(win, x, y)
                errs[m][h].append(a)
                fdes[m][h].append(f)
    ade = {
        m: {h: float(np.concatenate(v[h]).mean()) for h in horizons_s if v[h]}
        for m, v in errs.items()
    }
    fde = {
        m: {h: float(np.concatenate(v[h]).mean()) for h in horizons_s if v[h]}
        for m, v in fdes.items()
    }
    nwin = {h: int(sum(a.size for a in errs["SFM calibrated"][h])) for h in horizons_s}
    return DecisionValidation(
        tuple(cases), fit, tc_of, open_ok, closed_ok, tuple(stops), ade, fde, nwin,
        reason or "", fold_reasons,
    )  # fmt: skip


def _arc_on(paths: PackedPaths, j: int, x: FloatArray, y: FloatArray) -> FloatArray:
    """Monotone arc length [m] of positions (x, y) [N] along packed path j."""
    prog = np.empty(x.size)
    rows = paths.rows(np.array([j]))
    p = float(paths.arc_m[j][0])
    for i in range(x.size):
        gi, w = paths.index_rows(rows, np.array([p]))
        q = paths.at4(gi, w)[0]
        p = max(p + (x[i] - q[0]) * q[2] + (y[i] - q[1]) * q[3], p)
        prog[i] = p
    return prog


def _entered_first(arc: FloatArray, c: ConflictTrack) -> bool:
    """Did the rider (its arc over time, from the segment's first sample) enter the zone
    before the vehicle? (A rider that never enters it did not.)"""
    r_in = np.flatnonzero(arc >= c.s_rider_m - c.hz_rider_m)
    v_in = np.flatnonzero(
        np.isfinite(c.veh_arc_m) & (c.veh_arc_m >= c.s_vehicle_m - c.hz_vehicle_m)
    )
    if r_in.size == 0:
        return False
    return v_in.size == 0 or r_in[0] < v_in[0]


def _lines(v: DecisionValidation) -> list[str]:
    """The validation of the decisions as lines of text (vei calibrate decisions)."""
    cases = v.cases
    n_go = sum(c.outcome == "go" for c in cases)
    lines = [
        f"recorded decisions: {len(cases)} ({n_go} go, {len(cases) - n_go} yield, "
        f"{sum(c.stopped for c in cases)} with a stop)"
    ]
    for c in cases:
        lines.append(
            f"  {c.scenario}/{c.rider} vs vehicle {c.vehicle}{' (instrumented car)' if c.instrumented else ''}: "
            f"{c.outcome}, offered gap DTA {c.dta_s:+.2f} s (rider {c.tta_rider_s:.1f} s, car "
            f"{c.tta_vehicle_s:.1f} s), PET {c.pet_s:.1f} s"
        )
    fit = v.fit
    if fit is not None:
        lines.append(
            f"fit: critical gap {fit.critical_gap_s:+.2f} s (90 % bootstrap "
            f"{fit.interval_critical_gap_s[0]:+.2f} .. {fit.interval_critical_gap_s[1]:+.2f}), "
            f"scale {fit.scale_s:.2f} s{' (cases separate completely: the scale is the penalty s)' if fit.separated else ''}"
        )
    else:
        lines.append(f"fit: none: {v.fit_reason or 'no usable case'}")
    for held, why in v.folds_without_fit.items():
        lines.append(
            f"  fold without {held}: no fit ({why}); its critical gap is the default "
            f"{v.folds.get(held, ARRIVE_FIRST_S):+.2f} s (who arrives first goes)"
        )
    ok_o, ok_c = v.open_loop_correct, v.closed_loop_correct
    if len(cases):
        lines.append(
            f"decision accuracy, leave-one-scenario-out: open loop {int(ok_o.sum())}/{len(cases)}, "
            f"closed loop {int(ok_c.sum())}/{len(cases)}"
        )
    for st in v.stops:
        for label, decide in (("without", False), ("with", True)):
            sp_ok, stop_ok = st.ok(decide)
            med = st.median_speed_decide_mps if decide else st.median_speed_sfm_mps
            err = st.stop_error_decide_m if decide else st.stop_error_sfm_m
            lines.append(
                f"  stop {st.key} ({label} decisions): median speed {med:.2f} vs recorded "
                f"{st.median_speed_mps:.2f} m/s ({'within' if sp_ok else 'not within'} 30 %), "
                f"first stop {f'{err:.1f} m from the recorded one' if err == err else 'none'} "
                f"({'within' if stop_ok else 'not within'} 3 m)"
            )
    for m, per in v.ade_m.items():
        cells = ", ".join(f"ADE@{h:g}s {per[h]:.2f} FDE@{h:g}s {v.fde_m[m][h]:.2f}" for h in per)
        lines.append(f"  {m:15s} {cells} m")
    return lines


def _document(v: DecisionValidation) -> dict:
    """decisions.json: the cases, the fit, the folds' t_c and the validation figures."""
    fit = v.fit
    return {
        "cases": [c.to_dict() for c in v.cases],
        "fit": None if fit is None else fit.to_dict(),
        "fit_reason": None if fit is not None else (v.fit_reason or "no usable case"),
        "folds_without_fit": dict(v.folds_without_fit),
        "folds_critical_gap_s": v.folds,
        "open_loop_correct": np.asarray(v.open_loop_correct).tolist(),
        "closed_loop_correct": np.asarray(v.closed_loop_correct).tolist(),
        "stops": [
            {k: (None if isinstance(x, float) and x != x else x) for k, x in vars(s).items()}
            for s in v.stops
        ],
        "ade_m": {m: {f"{h:g}": x for h, x in d.items()} for m, d in v.ade_m.items()},
        "fde_m": {m: {f"{h:g}": x for h, x in d.items()} for m, d in v.fde_m.items()},
        "n_windows": {f"{h:g}": n for h, n in v.n_windows.items()},
    }
