"""Fitting the social-force rider to rider tracks (bounded least squares, scipy.optimize).

Per track j the free parameters are ``theta_j = (v0_mps, tau_s, lookahead_m)`` with
``k_des = mass / tau`` (mass and k_des are not separately identifiable from motion: only
their ratio, the speed-relaxation time tau, is). Fixed: mass 95 kg (SFMConfig), sigma 1 m.
The rider's limits are estimated from its own smoothed track, not fitted:
``max_speed_mps`` = 99th percentile of its speed, ``max_accel_mps2`` = 95th percentile of
|acceleration| (the tail above it is mostly tracker jumps), within [0.3, 8] m/s^2.

Residuals of track j (each block divided by the square root of its size, so a track's cost
is a mean square and long tracks do not drown short ones):

- closed-loop: the position error at every step of every ``FIT_HORIZON_S`` (3 s) rollout
  starting every 0.5 s at a moving sample of the track [m];
- one-step: ``ONE_STEP_WEIGHT_S2 * (a_model - a_recorded)`` at every moving sample
  (0.5 s^2: the position error that an acceleration error causes over one second) [m].

All tracks are fitted in one call of :func:`scipy.optimize.least_squares` (trust region
reflective, bounds) with a block-diagonal Jacobian sparsity, so finite differences cost 4
batched rollouts per Jacobian whatever the number of tracks.

The vehicle repulsion (A, b) is identifiable only where a rider comes close to a vehicle.
It is fitted after the per-track parameters, pooled over all riders of the training set
(every category), on the windows whose recorded rider comes within ``NEAR_VEHICLE_M``
(5 m) of a moving vehicle's box; its uncertainty is a bootstrap over tracks. It counts as
identified only where it cuts those windows' ADE by >= 5 %; otherwise profiles keep the
paper's A = 100 N, b = 3.5 1/m and say so.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import numpy.typing as npt
from scipy.optimize import least_squares
from scipy.sparse import lil_matrix

from vei.calibrate.rollout import (
    PackedPaths,
    Windows,
    make_windows,
    pack_paths,
    rollout_sfm,
    sfm_force,
)
from vei.calibrate.tracks import MOVING_MPS, RiderTrack, SceneTracks

FloatArray = npt.NDArray[np.float64]

MASS_KG = 95.0
SIGMA_M = 1.0
FIT_HORIZON_S = 3.0
FIT_STRIDE_S = 0.5
ONE_STEP_WEIGHT_S2 = 0.5
NEAR_VEHICLE_M = 5.0
#: (A, b) count as identified only if they cut the near windows' ADE by >= 5 %.
MIN_FORCE_GAIN = 0.05
#: Bounds of theta = (v0 [m/s], tau [s], lookahead [m]) and of (A [N], b [1/m]).
THETA_LO = np.array([0.2, 0.1, 0.5])
THETA_HI = np.array([12.0, 10.0, 20.0])
THETA_INIT_TAU_S = 1.0
THETA_INIT_LOOKAHEAD_M = 3.0
AB_LO = np.array([0.0, 0.2])
AB_HI = np.array([3000.0, 10.0])
PAPER_A_N = 100.0
PAPER_B_PER_M = 3.5
#: Speed / acceleration quantiles taken as the rider's limits.
SPEED_LIMIT_Q = 0.99
ACCEL_LIMIT_Q = 0.95
#: Range of the acceleration limit [m/s^2]: 8 = about 0.8 g, the most a bicycle or
#: e-scooter brakes before skidding / lifting its rear wheel; a short track's 95th
#: percentile above it is tracker jumps, not riding.
ACCEL_LIMIT_MIN = 0.3
ACCEL_LIMIT_MAX = 8.0


@dataclass(frozen=True)
class TrackFit:
    """Fitted parameters of one track.

    Attributes:
        key: ``<scenario>/<track_id>``. category: 'escooter' | 'cyclist'.
        v0_mps, tau_s, lookahead_m: fitted. k_des_nspm: MASS_KG / tau_s.
        max_speed_mps, max_accel_mps2: limits estimated from the track.
        median_moving_speed_mps: of the smoothed track. duration_s: segment length.
        n_windows: closed-loop windows fitted. ade_fit_m: mean ADE over them (3 s) [m].
        near_vehicle: a moving vehicle came within NEAR_VEHICLE_M of the rider.
    """

    key: str
    category: str
    v0_mps: float
    tau_s: float
    lookahead_m: float
    k_des_nspm: float
    max_speed_mps: float
    max_accel_mps2: float
    median_moving_speed_mps: float
    duration_s: float
    n_windows: int
    ade_fit_m: float
    near_vehicle: bool


@dataclass(frozen=True)
class VehicleFit:
    """Pooled vehicle repulsion.

    Attributes:
        a_veh_n, b_veh_per_m: fitted A [N] and b [1/m].
        a_ci_n, b_ci_per_m: bootstrap 5-95 % intervals (over tracks).
        n_windows, n_tracks: near-vehicle windows / tracks it was fitted on.
        ade_with_m, ade_without_m: mean 3 s ADE of those windows with the fitted force and
            with A = 0 [m] (how much the force explains).
        identified: False when there were too few near windows (< 10 from >= 2 tracks)
            or the fitted force cuts their ADE by less than MIN_FORCE_GAIN (5 %): the data
            then show no measurable repulsion, and profiles keep the paper's A and b.
    """

    a_veh_n: float
    b_veh_per_m: float
    a_ci_n: tuple[float, float]
    b_ci_per_m: tuple[float, float]
    n_windows: int
    n_tracks: int
    ade_with_m: float
    ade_without_m: float
    identified: bool


@dataclass(frozen=True)
class FitResult:
    """Per-track fits and the pooled vehicle repulsion of one training set."""

    tracks: tuple[TrackFit, ...]
    vehicle: VehicleFit
    extra: dict[str, float] = field(default_factory=dict)


def track_limits(tr: RiderTrack) -> tuple[float, float]:
    """(max_speed_mps, max_accel_mps2) of a track: quantiles of its smoothed motion."""
    sp = tr.speed_mps
    acc = np.hypot(tr.ax_mps2, tr.ay_mps2)
    amax = float(np.clip(np.quantile(acc, ACCEL_LIMIT_Q), ACCEL_LIMIT_MIN, ACCEL_LIMIT_MAX))
    return float(np.quantile(sp, SPEED_LIMIT_Q)), amax


def params_for(
    win: Windows,
    theta: FloatArray,
    limits: FloatArray,
    a_veh_n: float,
    b_veh_per_m: float,
) -> dict[str, FloatArray]:
    """Rollout parameters [B] from per-track theta [P, 3] and limits [P, 2]."""
    th = theta[win.track]
    lim = limits[win.track]
    b = win.size
    return {
        "v0_mps": th[:, 0],
        "k_des_nspm": MASS_KG / th[:, 1],
        "mass_kg": np.full(b, MASS_KG),
        "sigma_m": np.full(b, SIGMA_M),
        "lookahead_m": th[:, 2],
        "a_veh_n": np.full(b, a_veh_n),
        "b_veh_per_m": np.full(b, b_veh_per_m),
        "max_speed_mps": lim[:, 0],
        "max_accel_mps2": lim[:, 1],
    }


def _one_step_accel(
    paths: PackedPaths, win: Windows, p: dict[str, FloatArray]
) -> tuple[FloatArray, FloatArray]:
    veh = (
        win.veh_x_m[:, 0],
        win.veh_y_m[:, 0],
        win.veh_yaw_rad[:, 0],
        win.veh_length_m[:, 0],
        win.veh_width_m[:, 0],
        win.veh_active[:, 0],
    )
    use = bool(np.any(p["a_veh_n"] > 0))
    fx, fy, _ = sfm_force(
        paths,
        win.track,
        win.x0_m,
        win.y0_m,
        win.vx0_mps,
        win.vy0_mps,
        win.prog0_m,
        p,
        veh if use else None,
    )
    return fx / p["mass_kg"], fy / p["mass_kg"]


@dataclass(frozen=True)
class _Problem:
    tracks: list[RiderTrack]
    paths: PackedPaths
    win: Windows
    one: Windows
    limits: FloatArray
    w_roll: FloatArray  # [B] 1 / sqrt(rows of its track)
    w_one: FloatArray


def _problem(
    tracks: list[RiderTrack], scenes: dict[str, SceneTracks], dt_s: float, horizon_s: float
) -> _Problem:
    paths = pack_paths(tracks)
    win = make_windows(tracks, scenes, paths, horizon_s, FIT_STRIDE_S, dt_s)
    one = make_windows(tracks, scenes, paths, dt_s, dt_s, dt_s)
    p = len(tracks)
    h = win.horizon_steps
    nroll = np.bincount(win.track, minlength=p) * h * 2
    none = np.bincount(one.track, minlength=p) * 2
    limits = np.array([track_limits(t) for t in tracks]).reshape(p, 2)
    return _Problem(
        tracks,
        paths,
        win,
        one,
        limits,
        1.0 / np.sqrt(np.maximum(nroll[win.track], 1)),
        ONE_STEP_WEIGHT_S2 / np.sqrt(np.maximum(none[one.track], 1)),
    )


def _residuals(pb: _Problem, theta: FloatArray, a: float, b: float) -> FloatArray:
    p = params_for(pb.win, theta, pb.limits, a, b)
    x, y = rollout_sfm(pb.paths, pb.win, p)
    ex = (x[:, 1:] - pb.win.truth_x_m[:, 1:]) * pb.w_roll[:, None]
    ey = (y[:, 1:] - pb.win.truth_y_m[:, 1:]) * pb.w_roll[:, None]
    p1 = params_for(pb.one, theta, pb.limits, a, b)
    axm, aym = _one_step_accel(pb.paths, pb.one, p1)
    rx = (axm - pb.one.ax0_mps2) * pb.w_one
    ry = (aym - pb.one.ay0_mps2) * pb.w_one
    return np.concatenate([ex.ravel(), ey.ravel(), rx, ry])


def _sparsity(pb: _Problem) -> lil_matrix:
    h = pb.win.horizon_steps
    rows_track = np.concatenate(
        [np.repeat(pb.win.track, h), np.repeat(pb.win.track, h), pb.one.track, pb.one.track]
    )
    sp = lil_matrix((rows_track.size, 3 * len(pb.tracks)), dtype=np.int8)
    r = np.arange(rows_track.size)
    for c in range(3):
        sp[r, 3 * rows_track + c] = 1
    return sp


def fit_tracks(
    tracks: list[RiderTrack],
    scenes: dict[str, SceneTracks],
    *,
    dt_s: float = 0.05,
    horizon_s: float = FIT_HORIZON_S,
    bootstrap: int = 20,
    seed: int = 0,
) -> FitResult:
    """Fit every track's (v0, tau, lookahead), then the pooled vehicle repulsion (A, b).

    Args:
        tracks: rider tracks (from :func:`vei.calibrate.tracks.load_scenes`).
        scenes: scenario -> SceneTracks (the vehicles).
        dt_s: engine step [s]. horizon_s: closed-loop rollout length of the fit [s].
        bootstrap: resamples (over tracks) of the (A, b) interval.
        seed: bootstrap seed.
    Returns:
        The FitResult (tracks with no moving window are left out).
    """
    pb = _problem(tracks, scenes, dt_s, horizon_s)
    keep = np.bincount(pb.win.track, minlength=len(tracks)) > 0
    if not keep.all():
        tracks = [t for t, k in zip(tracks, keep, strict=True) if k]
        pb = _problem(tracks, scenes, dt_s, horizon_s)
    if not tracks:
        raise ValueError("no track has a full moving window to fit")
    n = len(tracks)
    med = np.array([t.median_moving_speed_mps() for t in tracks])
    theta0 = np.column_stack(
        [
            np.clip(med, THETA_LO[0], THETA_HI[0]),
            np.full(n, THETA_INIT_TAU_S),
            np.full(n, THETA_INIT_LOOKAHEAD_M),
        ]
    )
    lo, hi = np.tile(THETA_LO, n), np.tile(THETA_HI, n)
    sp = _sparsity(pb)

    def solve(a: float, b: float, start: FloatArray) -> FloatArray:
        res = least_squares(
            lambda z: _residuals(pb, z.reshape(n, 3), a, b),
            start.ravel(),
            bounds=(lo, hi),
            jac_sparsity=sp,
            x_scale=np.tile([1.0, 1.0, 2.0], n),
            diff_step=1e-3,
            max_nfev=60,
            method="trf",
        )
        return res.x.reshape(n, 3)

    # Stage 1: no vehicle force; stage 2: pooled (A, b); stage 3: refit the near tracks.
    theta = solve(0.0, 0.0, theta0)
    vfit = _fit_vehicle(pb, theta, bootstrap, seed)
    if vfit.identified:
        theta = solve(vfit.a_veh_n, vfit.b_veh_per_m, theta)
    a, b = vehicle_values(vfit)
    p = params_for(pb.win, theta, pb.limits, a, b)
    x, y = rollout_sfm(pb.paths, pb.win, p)
    ade = np.hypot(x[:, 1:] - pb.win.truth_x_m[:, 1:], y[:, 1:] - pb.win.truth_y_m[:, 1:]).mean(
        axis=1
    )
    near = np.zeros(n, dtype=bool)
    np.logical_or.at(near, pb.win.track, pb.win.veh_min_gap_m <= NEAR_VEHICLE_M)
    fits = []
    for j, tr in enumerate(tracks):
        sel = pb.win.track == j
        fits.append(
            TrackFit(
                key=tr.key,
                category=tr.category,
                v0_mps=float(theta[j, 0]),
                tau_s=float(theta[j, 1]),
                lookahead_m=float(theta[j, 2]),
                k_des_nspm=float(MASS_KG / theta[j, 1]),
                max_speed_mps=float(pb.limits[j, 0]),
                max_accel_mps2=float(pb.limits[j, 1]),
                median_moving_speed_mps=float(med[j]),
                duration_s=tr.duration_s,
                n_windows=int(sel.sum()),
                ade_fit_m=float(ade[sel].mean()),
                near_vehicle=bool(near[j]),
            )
        )
    return FitResult(tuple(fits), vfit)


def vehicle_values(v: VehicleFit) -> tuple[float, float]:
    """(A [N], b [1/m]) a profile uses: the fit where identified, else the paper's (100, 3.5)."""
    return (v.a_veh_n, v.b_veh_per_m) if v.identified else (PAPER_A_N, PAPER_B_PER_M)


def _fit_vehicle(pb: _Problem, theta: FloatArray, bootstrap: int, seed: int) -> VehicleFit:
    nearw = pb.win.veh_min_gap_m <= NEAR_VEHICLE_M
    idx = np.flatnonzero(nearw)
    tracks_near = np.unique(pb.win.track[idx])
    sub = pb.win.take(idx)
    if idx.size < 10 or tracks_near.size < 2:
        return VehicleFit(
            PAPER_A_N,
            PAPER_B_PER_M,
            (float("nan"),) * 2,
            (float("nan"),) * 2,
            int(idx.size),
            int(tracks_near.size),
            float("nan"),
            float("nan"),
            False,
        )

    def ade_of(ws: Windows, a: float, b: float) -> FloatArray:
        x, y = rollout_sfm(pb.paths, ws, params_for(ws, theta, pb.limits, a, b))
        return np.hypot(x[:, 1:] - ws.truth_x_m[:, 1:], y[:, 1:] - ws.truth_y_m[:, 1:])

    def fit_on(ws: Windows, starts: tuple[tuple[float, float], ...], nfev: int) -> FloatArray:
        best = None
        for a0, b0 in starts:
            r = least_squares(
                lambda z: ade_of(ws, z[0], z[1]).ravel(),
                np.array([a0, b0]),
                bounds=(AB_LO, AB_HI),
                x_scale=np.array([100.0, 1.0]),
                diff_step=1e-3,
                max_nfev=nfev,
            )
            if best is None or r.cost < best.cost:
                best = r
        assert best is not None
        return best.x

    ab = fit_on(sub, ((300.0, 1.0), (PAPER_A_N, PAPER_B_PER_M)), 40)
    rng = np.random.default_rng(seed)
    boots = []
    for _ in range(bootstrap):
        pick = rng.choice(tracks_near, size=tracks_near.size, replace=True)
        rows = np.concatenate([np.flatnonzero(sub.track == t) for t in pick])
        boots.append(fit_on(sub.take(rows), ((float(ab[0]), float(ab[1])),), 15))
    q = np.quantile(np.array(boots), [0.05, 0.95], axis=0) if boots else np.full((2, 2), np.nan)
    ade_with = float(ade_of(sub, ab[0], ab[1]).mean())
    ade_without = float(ade_of(sub, 0.0, 0.0).mean())
    return VehicleFit(
        a_veh_n=float(ab[0]),
        b_veh_per_m=float(ab[1]),
        a_ci_n=(float(q[0, 0]), float(q[1, 0])),
        b_ci_per_m=(float(q[0, 1]), float(q[1, 1])),
        n_windows=int(idx.size),
        n_tracks=int(tracks_near.size),
        ade_with_m=ade_with,
        ade_without_m=ade_without,
        identified=ade_with <= (1.0 - MIN_FORCE_GAIN) * ade_without,
    )


def moving_samples(tr: RiderTrack) -> npt.NDArray[np.bool_]:
    """[N] samples where the smoothed speed exceeds MOVING_MPS."""
    return tr.speed_mps > MOVING_MPS
