"""Yield / go cases of recorded riders at conflicts with recorded vehicles, and the fit of
the gap-acceptance model (vei.models.decision_core) on them.

Every rider segment (:mod:`vei.calibrate.tracks`) is crossed with every moving vehicle of
its scenario (the instrumented car included). A *conflict* is where their smoothed paths
cross (:func:`vei.models.crossings.path_crossings`), with the engine's conflict zone
(:func:`vei.models.decision_core.zone_half_lengths_core`, the footprints of both). The rule
(constants below):

1. times: the rider's and the vehicle's arc length along their own paths at every step
   (monotone), when each enters the zone, when the vehicle has left it (its rear
   ``CLEAR_MARGIN_M`` beyond); a conflict both never reach within the recordings is
   left out;
2. an *interaction*: both enter the zone at most ``PET_MAX_S`` apart; its *decision
   moment* is the first step at which the rider is within ``horizon_s`` of the zone (its
   time to arrive at its speed, at least half its median moving speed: the engine's
   rule), has not entered it, and the vehicle is tracked and has not yet left it;
3. the *offered gap* there: DTA = TTA_vehicle - TTA_rider (the engine's
   :func:`~vei.models.decision_core.conflict_times_core`);
4. the outcome: *go* when the rider entered the zone before the vehicle, *yield* when the
   vehicle did; *stopped* when the rider stood (speed < ``STOP_MPS``) for at least
   ``STOP_MIN_S`` between the decision and entering the zone.

The fit (:func:`fit_gap_acceptance`): P(go | DTA) = 1 / (1 + exp(-(DTA - t_c) / s)), by
maximum likelihood with Firth's penalty (Firth 1993, Biometrika 80:27; finite estimates
where the cases separate completely, as small samples do), a bootstrap over the cases for
the interval.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass

import numpy as np
import numpy.typing as npt

from vei.calibrate.rollout import PATH_MIN_SPACING_M, decimated
from vei.calibrate.tracks import RiderTrack, SceneTracks
from vei.errors import InputError
from vei.models import decision_core as core
from vei.models.crossings import path_crossings
from vei.models.drivable_path import recorded_arc_length
from vei.models.ego import PathTable, build_path
from vei.types import DEFAULT_DIMENSIONS_M

FloatArray = npt.NDArray[np.float64]

#: An interaction: the rider and the vehicle enter the zone at most this far apart [s]
#: (a rider that crosses long after the vehicle has passed waited for something else: a
#: signal, another road user).
PET_MAX_S = 6.0
#: A rider stops when slower than this [m/s] for at least STOP_MIN_S [s].
STOP_MPS = 0.5
STOP_MIN_S = 1.0
#: The vehicle has left the zone when its centre is this far beyond it [m] (the engine's
#: DecisionConfig.clear_margin_m default).
CLEAR_MARGIN_M = 1.0
#: Default decision horizon [s] (DecisionConfig.horizon_s).
HORIZON_S = 4.0


@dataclass(frozen=True)
class ConflictTrack:
    """One conflict of a rider segment with a vehicle, with both arc lengths over time.

    Attributes:
        scenario, rider, category: the rider segment (RiderTrack.track_id, category).
        vehicle: the vehicle's track id. instrumented: it is the instrumented car.
        s_rider_m, s_vehicle_m: the crossing along both paths [m]. hz_rider_m,
            hz_vehicle_m: the zone's half-lengths along both [m].
        t_s: [N] the rider segment's times [s]. rider_arc_m, rider_speed_mps: [N] its arc
            length along its path [m] and speed [m/s].
        veh_arc_m, veh_speed_mps: [N] the vehicle's at the same times [m, m/s]: before
            the camera first tracks it, extrapolated back at its first tracked speed (it
            approached out of view); NaN after its last tracked sample.
        v_ref_mps: the rider's speed floor of its time to arrive (half its median moving
            speed) [m/s].
    """

    scenario: str
    rider: str
    category: str
    vehicle: str
    instrumented: bool
    s_rider_m: float
    s_vehicle_m: float
    hz_rider_m: float
    hz_vehicle_m: float
    t_s: FloatArray
    rider_arc_m: FloatArray
    rider_speed_mps: FloatArray
    veh_arc_m: FloatArray
    veh_speed_mps: FloatArray
    v_ref_mps: float


@dataclass(frozen=True)
class DecisionCase:
    """One recorded yield / go decision (a row of the fit's data).

    Attributes:
        scenario, rider, category, vehicle, instrumented: who.
        t_decision_s: the decision moment [s]. dta_s: the offered gap there [s];
            tta_rider_s, tta_vehicle_s: both times to arrive [s]; rider_speed_mps,
            vehicle_speed_mps: speeds then [m/s].
        outcome: 'go' (the rider entered the zone first) or 'yield'.
        stopped: the rider stood still before entering the zone.
        pet_s: the time between the two entries [s].
    """

    scenario: str
    rider: str
    category: str
    vehicle: str
    instrumented: bool
    t_decision_s: float
    dta_s: float
    tta_rider_s: float
    tta_vehicle_s: float
    rider_speed_mps: float
    vehicle_speed_mps: float
    outcome: str
    stopped: bool
    pet_s: float

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return asdict(self)


def _path_of(x: FloatArray, y: FloatArray, yaw0: float) -> PathTable:
    k = decimated(x, y, PATH_MIN_SPACING_M)
    return build_path(x[k], y[k], yaw_hint_rad=yaw0, ds_m=0.1, extend_m=5.0)


def rider_conflicts(scene: SceneTracks, rider: RiderTrack) -> list[ConflictTrack]:
    """Every conflict of one rider segment with the scene's moving vehicles."""
    veh = scene.vehicles
    if not veh.ids or rider.t_s.size < 2:
        return []
    rpath = _path_of(rider.x_m, rider.y_m, float(np.arctan2(rider.vy_mps[0], rider.vx_mps[0])))
    r_arc = recorded_arc_length(rpath, rider.x_m, rider.y_m)
    r_sp = rider.speed_mps
    moving = r_sp[r_sp > STOP_MPS]
    v_ref = 0.5 * float(np.median(moving)) if moving.size else 0.5
    rl, rw = DEFAULT_DIMENSIONS_M.get(rider.category, DEFAULT_DIMENSIONS_M["cyclist"])
    k = np.rint(rider.t_s / veh.dt_s).astype(np.intp)
    out: list[ConflictTrack] = []
    for j, vid in enumerate(veh.ids):
        act = veh.active[:, j]
        kv = np.flatnonzero(act)
        if kv.size < 2:
            continue
        vx, vy = veh.x_m[kv, j], veh.y_m[kv, j]
        if np.hypot(vx[-1] - vx[0], vy[-1] - vy[0]) < 1.0 and np.ptp(vx) + np.ptp(vy) < 2.0:
            continue
        vpath = _path_of(vx, vy, float(veh.yaw_rad[kv[0], j]))
        s_r, s_v, sin_abs = path_crossings(rpath, vpath, step_m=0.2)
        inside = (s_r >= 0) & (s_r <= rpath.length_m) & (s_v >= 0) & (s_v <= vpath.length_m)
        if not inside.any():
            continue
        v_arc_all = np.full(act.shape[0], np.nan)
        v_arc_all[kv] = recorded_arc_length(vpath, vx, vy)
        v_sp_all = np.full(act.shape[0], np.nan)
        dt = veh.dt_s
        v_sp_all[kv] = np.gradient(v_arc_all[kv], kv * dt) if kv.size > 1 else 0.0
        ok = (k >= 0) & (k < act.shape[0])
        # Before the camera first tracks the vehicle it approaches at its first tracked
        # speed (it was there, out of view); after its last sample it is gone.
        k0 = int(kv[0])
        v0 = float(np.median(v_sp_all[kv[: max(3, int(round(0.5 / dt)))]]))
        early = np.arange(k0) < k0
        v_arc_all[:k0][early] = v_arc_all[k0] - v0 * (k0 - np.arange(k0)) * dt
        v_sp_all[:k0] = v0
        va = np.where(ok, v_arc_all[np.clip(k, 0, act.shape[0] - 1)], np.nan)
        vs = np.where(ok, v_sp_all[np.clip(k, 0, act.shape[0] - 1)], np.nan)
        for sr, sv, sa in zip(s_r[inside], s_v[inside], sin_abs[inside], strict=True):
            sin_c = max(float(sa), float(np.sin(core.MIN_CROSSING_RAD)))
            cos_c = float(np.sqrt(max(1.0 - sin_c * sin_c, 0.0)))
            hz_r, hz_v = core.zone_half_lengths_core(
                sin_c, cos_c, float(veh.length_m[j]), float(veh.width_m[j]), rl, rw
            )
            out.append(
                ConflictTrack(
                    scenario=scene.scenario,
                    rider=rider.track_id,
                    category=rider.category,
                    vehicle=str(vid),
                    instrumented=j == veh.ego_index,
                    s_rider_m=float(sr),
                    s_vehicle_m=float(sv),
                    hz_rider_m=float(hz_r),
                    hz_vehicle_m=float(hz_v),
                    t_s=rider.t_s,
                    rider_arc_m=r_arc,
                    rider_speed_mps=r_sp,
                    veh_arc_m=va,
                    veh_speed_mps=vs,
                    v_ref_mps=v_ref,
                )  # fmt: skip
            )
    return out


def _first(mask: npt.NDArray[np.bool_]) -> int:
    idx = np.flatnonzero(mask)
    return int(idx[0]) if idx.size else -1


def decision_case(c: ConflictTrack, horizon_s: float = HORIZON_S) -> DecisionCase | None:
    """The recorded decision at one conflict (rule 2-4 of the module), or None (no
    interaction, or an entry outside the recordings)."""
    r_in = _first(c.rider_arc_m >= c.s_rider_m - c.hz_rider_m)
    tracked = np.isfinite(c.veh_arc_m)
    v_in = _first(tracked & (c.veh_arc_m >= c.s_vehicle_m - c.hz_vehicle_m))
    if r_in < 0 or v_in < 0:
        return None
    d_r, tta_r, dta, t_clear, live = core.conflict_times_core(
        c.rider_arc_m, c.rider_speed_mps, np.nan_to_num(c.veh_arc_m, nan=-1e9),
        np.nan_to_num(c.veh_speed_mps), c.s_rider_m, c.s_vehicle_m, c.hz_rider_m,
        c.hz_vehicle_m, CLEAR_MARGIN_M, c.v_ref_mps,
    )  # fmt: skip
    tta_v = dta + tta_r
    pet = float(abs(c.t_s[r_in] - c.t_s[v_in]))
    kd = _first(live & tracked & (d_r > 0) & (tta_r <= horizon_s))
    if kd < 0 or pet > PET_MAX_S:
        return None
    dt = float(c.t_s[1] - c.t_s[0])
    slow = c.rider_speed_mps[kd : max(r_in, kd) + 1] < STOP_MPS
    run = 0
    stopped = False
    for s in slow:
        run = run + 1 if s else 0
        stopped = stopped or run * dt >= STOP_MIN_S
    return DecisionCase(
        scenario=c.scenario, rider=c.rider, category=c.category, vehicle=c.vehicle,
        instrumented=c.instrumented, t_decision_s=float(c.t_s[kd]), dta_s=float(dta[kd]),
        tta_rider_s=float(tta_r[kd]), tta_vehicle_s=float(tta_v[kd]),
        rider_speed_mps=float(c.rider_speed_mps[kd]),
        vehicle_speed_mps=float(c.veh_speed_mps[kd]),
        outcome="go" if r_in < v_in else "yield", stopped=bool(stopped),
        pet_s=pet,
    )  # fmt: skip


def extract_cases(
    scenes: Sequence[SceneTracks], horizon_s: float = HORIZON_S
) -> list[DecisionCase]:
    """Every recorded decision of every rider segment of the scenes (sorted as found)."""
    out: list[DecisionCase] = []
    for sc in scenes:
        for r in sc.riders:
            for c in rider_conflicts(sc, r):
                case = decision_case(c, horizon_s)
                if case is not None:
                    out.append(case)
    return out


@dataclass(frozen=True)
class GapFit:
    """The fitted gap-acceptance model.

    Attributes:
        critical_gap_s: t_c [s] (P(go) = 1/2). scale_s: the logistic scale s [s].
        n_go, n_yield, n_stopped: the cases. interval_critical_gap_s,
        interval_scale_s: 90 % bootstrap intervals (NaN without a bootstrap).
        separated: the cases separate completely (every go above every yield): the scale
        is then bounded by the penalty only.
    """

    critical_gap_s: float
    scale_s: float
    n_go: int
    n_yield: int
    n_stopped: int
    interval_critical_gap_s: tuple[float, float]
    interval_scale_s: tuple[float, float]
    separated: bool

    def to_dict(self) -> dict[str, object]:
        """JSON-ready form."""
        return asdict(self)


def _firth_logit(x: FloatArray, y: FloatArray) -> tuple[float, float]:
    """(b0, b1) of the logistic P(y = 1) = 1 / (1 + exp(-(b0 + b1 x))) maximising the
    log-likelihood plus Firth's penalty 0.5 log det I(b) (I = X' W X, the Fisher
    information; Firth 1993), by BFGS from b = 0."""
    from scipy.optimize import minimize

    xm = np.column_stack([np.ones_like(x), x])

    def neg(b: FloatArray) -> float:
        eta = xm @ b
        ll = float(np.sum(y * eta - np.logaddexp(0.0, eta)))
        p = 1.0 / (1.0 + np.exp(-np.clip(eta, -40, 40)))
        w = p * (1.0 - p)
        sign, logdet = np.linalg.slogdet(xm.T @ (w[:, None] * xm))
        return -(ll + 0.5 * logdet) if sign > 0 else 1e12

    res = minimize(
        neg,
        np.zeros(2),
        method="Nelder-Mead",
        options={"xatol": 1e-8, "fatol": 1e-12, "maxiter": 20000},
    )
    res = minimize(neg, res.x, method="BFGS")
    return float(res.x[0]), float(res.x[1])


def no_fit_reason(cases: Sequence[DecisionCase]) -> str | None:
    """Why the gap-acceptance fit cannot be made on ``cases`` (None: it can): it needs at
    least one rider that went and one that yielded."""
    n_go = sum(c.outcome == "go" for c in cases)
    n_yield = len(cases) - n_go
    if n_go >= 1 and n_yield >= 1:
        return None
    if not cases:
        return "no recorded yield / go case (no rider met a moving vehicle at a conflict)"
    return (
        f"the gap-acceptance fit needs at least one go and one yield case; the "
        f"{len(cases)} usable case{'s' if len(cases) != 1 else ''} {'are' if len(cases) != 1 else 'is'} "
        f"{n_go} go and {n_yield} yield"
    )


def fit_gap_acceptance(
    cases: Sequence[DecisionCase], *, bootstrap: int = 200, seed: int = 0
) -> GapFit:
    """Fit t_c and s on the cases (Firth-penalised maximum likelihood; see the module).

    Raises:
        InputError: fewer than one go and one yield case (nothing to fit).
    """
    x = np.array([c.dta_s for c in cases], dtype=np.float64)
    y = np.array([c.outcome == "go" for c in cases], dtype=np.float64)
    n_go, n_yield = int(y.sum()), int((1 - y).sum())
    reason = no_fit_reason(cases)
    if reason is not None:
        raise InputError(reason)
    b0, b1 = _firth_logit(x, y)
    sep = bool(x[y == 1].min() > x[y == 0].max())
    rng = np.random.default_rng(seed)
    tcs, ss = [], []
    for _ in range(bootstrap):
        i = rng.integers(0, x.size, x.size)
        if y[i].min() == y[i].max():
            continue
        c0, c1 = _firth_logit(x[i], y[i])
        if c1 > 0:
            tcs.append(-c0 / c1)
            ss.append(1.0 / c1)
    nan = float("nan")
    return GapFit(
        critical_gap_s=-b0 / b1,
        scale_s=1.0 / b1,
        n_go=n_go,
        n_yield=n_yield,
        n_stopped=sum(c.stopped for c in cases),
        interval_critical_gap_s=(
            (float(np.quantile(tcs, 0.05)), float(np.quantile(tcs, 0.95))) if tcs else (nan, nan)
        ),
        interval_scale_s=(
            (float(np.quantile(ss, 0.05)), float(np.quantile(ss, 0.95))) if ss else (nan, nan)
        ),
        separated=sep,
    )
