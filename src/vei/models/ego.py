"""Ego vehicle: path following, PID speed control, actuator, and the CAP state machine.

Pure functions over arrays with a leading batch axis ``[B]`` (any broadcastable shape
works; B = 1 for a single vehicle). They never import the engine: the built-in engine
(:mod:`vei.sim.engine`) and the CARLA backend call the same functions each tick, the
latter with the speed measured by the simulator.

Pipeline of one control tick (what the engine does, and what a backend should do)::

    rider_ahead, gap = corridor_check(path, ego_s, ...)        # CAP perception
    state, a_brake, braking = cap_step(state, v, v_d, rider_ahead, gap, ...)
    u_pid, pid = pid_step(pid, v_d - v, dt, kp, ki, kd, 1.0, window)  # throttle/brake in [-1, 1]
    pid = pid_reset_where(pid, entered_recover, v_d - v)       # integral reset on RECOVER entry
    u = where(braking, accel_to_command(a_brake, ...), u_pid)  # CARLA: VehicleControl(u)
    a = actuator_step(a, command_to_accel(u, ...), lag, dt)    # built-in engine only
    v = speed_step(v, a, dt)

Conventions: speeds [m/s] >= 0, accelerations [m/s^2] (negative = braking), the command u
in [-1, 1] (u >= 0: throttle u, u < 0: brake -u, like CARLA's VehicleControl).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import numpy.typing as npt

from vei.errors import InputError
from vei.models import ego_core as core
from vei.models.ego_core import BRAKE, CRUISE, RECOVER  # noqa: F401 (the CAP state codes)

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
ArrayLike = npt.ArrayLike

#: Names of the CAP states CRUISE, BRAKE, RECOVER (int8 codes 0, 1, 2 in the engine's arrays).
CAP_STATE_NAMES: tuple[str, ...] = ("CRUISE", "BRAKE", "RECOVER")


# --------------------------------------------------------------------------------------
# Path
# --------------------------------------------------------------------------------------
def uniform_grid_index(
    x: ArrayLike, x0: float, dx: float, n: int
) -> tuple[npt.NDArray[np.intp], FloatArray]:
    """Cell index and interpolation weight of x on the uniform grid ``x0 + k * dx``, k < n.

    Clamped to the grid; shared by the arc-length (PathTable) and time (TimeTable) tables.

    Args:
        x: [...] query values (same unit as x0, dx). x0: first grid value. dx: spacing (> 0).
        n: number of grid entries.
    Returns:
        (i [...] intp, w [...] in [0, 1]): x lies between entries i and i + 1.
    """
    f = (np.asarray(x, dtype=np.float64) - x0) * (1.0 / dx)
    if np.ndim(f) == 0:
        f = np.array(f)
    np.clip(f, 0.0, n - 1.0, out=f)
    i = np.minimum(f.astype(np.intp), max(n - 2, 0))
    f -= i
    return i, f


@dataclass(frozen=True)
class PathTable:
    """An arc-length parametrised path, resampled on a uniform grid of arc length.

    Attributes:
        s_start_m: arc length of the first table entry [m] (negative: the table extends
            ``extend_m`` before the path's start, straight along the initial heading).
        ds_m: grid spacing [m].
        x_m, y_m: [N] positions on the grid [m].
        yaw_rad: [N] path heading on the grid [rad], unwrapped (continuous).
        length_m: arc length of the recorded path [m]; s in [0, length_m] is the recorded
            part, beyond it the table continues straight along the final heading.

    Derived on construction: ``cos_yaw``, ``sin_yaw`` [N]; ``end_x_m``, ``end_y_m`` (the
    recorded path's final point, s = length_m).
    """

    s_start_m: float
    ds_m: float
    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    length_m: float

    def __post_init__(self) -> None:
        # Precomputed tables for fast batched lookups (value + slope to the next entry).
        cos_yaw, sin_yaw = np.cos(self.yaw_rad), np.sin(self.yaw_rad)

        def slope(a: FloatArray) -> FloatArray:
            d = np.zeros_like(a)
            d[:-1] = np.diff(a)
            return d

        object.__setattr__(self, "cos_yaw", cos_yaw)
        object.__setattr__(self, "sin_yaw", sin_yaw)
        object.__setattr__(
            self,
            "_slopes",
            {
                "x": slope(self.x_m),
                "y": slope(self.y_m),
                "yaw": slope(self.yaw_rad),
                "cos": slope(cos_yaw),
                "sin": slope(sin_yaw),
            },
        )
        object.__setattr__(
            self,
            "_values",
            {"x": self.x_m, "y": self.y_m, "yaw": self.yaw_rad, "cos": cos_yaw, "sin": sin_yaw},
        )
        ex, ey, _ = self.lookup(self.length_m)
        object.__setattr__(self, "end_x_m", float(ex))
        object.__setattr__(self, "end_y_m", float(ey))

    def index(self, s_m: ArrayLike) -> tuple[npt.NDArray[np.intp], FloatArray]:
        """Grid index and interpolation weight of arc lengths s (clamped to the table).

        Args:
            s_m: [...] arc length [m].
        Returns:
            (i [...] intp, w [...] in [0, 1)): s lies between entries i and i + 1.
        """
        return uniform_grid_index(s_m, self.s_start_m, self.ds_m, self.x_m.shape[0])

    def values_at(self, i: npt.NDArray[np.intp], w: FloatArray, *names: str) -> list[FloatArray]:
        """Linearly interpolated columns ('x', 'y', 'yaw', 'cos', 'sin') at (i, w) from :meth:`index`.

        'cos'/'sin' are the interpolated cosine / sine of the heading (not renormalised:
        their norm differs from 1 by < (d_yaw)^2 / 8 per grid cell).
        """
        vals = self._values  # type: ignore[attr-defined]
        slopes = self._slopes  # type: ignore[attr-defined]
        return [vals[n][i] + w * slopes[n][i] for n in names]

    @property
    def table(self) -> FloatArray:
        """[N, 3] columns x_m, y_m, yaw_rad (for one-gather lookups)."""
        return np.stack([self.x_m, self.y_m, self.yaw_rad], axis=1)

    def lookup(self, s_m: ArrayLike) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Position and heading at arc length s (linear interpolation; clamped to the table).

        Args:
            s_m: [...] arc length [m] (0 = the path's first recorded point).
        Returns:
            (x_m, y_m, yaw_rad) [...].
        """
        i, w = self.index(s_m)
        x, y, yaw = self.values_at(i, w, "x", "y", "yaw")
        return x, y, yaw


def build_path(
    x_m: ArrayLike,
    y_m: ArrayLike,
    *,
    yaw_hint_rad: float = 0.0,
    ds_m: float = 0.1,
    extend_m: float = 300.0,
    heading_window_m: float = 1.0,
    where: str = "path",
) -> PathTable:
    """Arc-length table of a recorded path (e.g. the ego's positions at the sim rate).

    Consecutive points closer than 1 mm are merged (a standing vehicle adds no length).
    The heading is the direction of the chord between the points ``heading_window_m / 2``
    before and after (robust to decimetre jitter), unwrapped. The table extends
    ``extend_m`` straight beyond both ends.

    Args:
        x_m, y_m: [M] recorded positions in time order [m].
        yaw_hint_rad: heading used when the path has no length (a standing vehicle).
        ds_m: grid spacing [m]. extend_m: straight extension at both ends [m].
        heading_window_m: chord length for the heading [m].
        where: name used in error messages.
    Returns:
        The PathTable.
    """
    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    if x.ndim != 1 or x.shape != y.shape or x.size == 0:
        raise InputError("expected 1-D x and y of equal, non-zero length", path=where)
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(y))):
        raise InputError("path has non-finite positions", path=where)
    seg = np.hypot(np.diff(x), np.diff(y))
    keep = np.concatenate([[True], seg > 1e-3])
    x, y = x[keep], y[keep]
    s = np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(x), np.diff(y)))])
    length = float(s[-1])
    if length < ds_m:
        yaw0 = yaw1 = float(yaw_hint_rad)
        grid = np.array([0.0])
        gx, gy = np.array([x[0]]), np.array([y[0]])
        gyaw = np.array([yaw0])
    else:
        n = int(np.floor(length / ds_m)) + 1
        grid = np.arange(n) * ds_m
        gx = np.interp(grid, s, x)
        gy = np.interp(grid, s, y)
        h = max(1, int(round(0.5 * heading_window_m / ds_m)))
        lo = np.clip(np.arange(n) - h, 0, n - 1)
        hi = np.clip(np.arange(n) + h, 0, n - 1)
        gyaw = np.unwrap(np.arctan2(gy[hi] - gy[lo], gx[hi] - gx[lo]))
        yaw0, yaw1 = float(gyaw[0]), float(gyaw[-1])
    m = int(np.ceil(extend_m / ds_m))
    ext = np.arange(1, m + 1) * ds_m
    bx = gx[0] - ext[::-1] * np.cos(yaw0)
    by = gy[0] - ext[::-1] * np.sin(yaw0)
    ax = gx[-1] + ext * np.cos(yaw1)
    ay = gy[-1] + ext * np.sin(yaw1)
    return PathTable(
        s_start_m=float(-m * ds_m),
        ds_m=float(ds_m),
        x_m=np.concatenate([bx, gx, ax]),
        y_m=np.concatenate([by, gy, ay]),
        yaw_rad=np.concatenate([np.full(m, yaw0), gyaw, np.full(m, yaw1)]),
        length_m=float(grid[-1]),
    )


def project_onto_path(
    path: PathTable, x_m: ArrayLike, y_m: ArrayLike, s_guess_m: ArrayLike, iterations: int = 3
) -> tuple[FloatArray, FloatArray]:
    """Local projection of points onto the path, starting from a guess of their arc length.

    Each iteration moves s by the along-path component of the offset to the path point at
    s (Newton step for a straight segment). Converges when the guess is within the local
    radius of curvature; use the ego's own s (or the previous projection) as the guess.

    Args:
        path: the PathTable. x_m, y_m: [...] points [m]. s_guess_m: [...] guess [m].
        iterations: number of correction steps.
    Returns:
        (s_m, lateral_m) [...]: arc length of the foot point and the signed lateral offset
        (positive = left of the path's direction).
    """
    s = np.asarray(s_guess_m, dtype=np.float64)
    for _ in range(iterations):
        px, py, yaw = path.lookup(s)
        s = s + (x_m - px) * np.cos(yaw) + (y_m - py) * np.sin(yaw)
    px, py, yaw = path.lookup(s)
    lat = -(x_m - px) * np.sin(yaw) + (y_m - py) * np.cos(yaw)
    return s, lat


def median_moving_speed_mps(speed_mps: ArrayLike, moving_threshold_mps: float = 0.5) -> float:
    """Median of a recorded speed profile over the samples where the vehicle moves.

    The default cruise speed v_d for a real recording (DESIGN.md): the speed the driver
    actually kept, ignoring standstill.

    Args:
        speed_mps: [M] recorded speeds [m/s]. moving_threshold_mps: moving above this.
    Returns:
        The median moving speed [m/s]; raises InputError if the vehicle never moves.
    """
    v = np.asarray(speed_mps, dtype=np.float64)
    moving = v[np.isfinite(v) & (v > moving_threshold_mps)]
    if moving.size == 0:
        raise InputError(
            f"the ego never moves faster than {moving_threshold_mps} m/s: no cruise speed can be "
            "derived; set ego.cruise_speed_mps explicitly",
            field="speed_mps",
        )
    return float(np.median(moving))


# --------------------------------------------------------------------------------------
# PID and actuator
# --------------------------------------------------------------------------------------
class PIDState(NamedTuple):
    """PID memory, arrays [B].

    Attributes:
        integral_m: integral of the speed error [m/s * s = m].
        prev_error_mps: the previous speed error [m/s] (for the derivative).
    """

    integral_m: FloatArray
    prev_error_mps: FloatArray

    @staticmethod
    def initial(error_mps: ArrayLike) -> PIDState:
        """Fresh state: zero integral, previous error = the current one (no derivative kick)."""
        e = np.array(error_mps, dtype=np.float64, copy=True)
        return PIDState(np.zeros_like(e), e)


def pid_step(
    state: PIDState,
    error_mps: ArrayLike,
    dt_s: float,
    kp: ArrayLike = 0.05,
    ki: ArrayLike = 0.05,
    kd: ArrayLike = 0.05,
    integral_limit: ArrayLike = 1.0,
    integral_window_s: ArrayLike = np.inf,
) -> tuple[FloatArray, PIDState]:
    """One PID step on the speed error e = v_d - v, producing a command in [-1, 1].

    ``I <- I exp(-dt / window) + e dt`` (window = inf: plain integral), clamped so that
    ``|ki I| <= integral_limit``; ``u = clip(kp e + ki I + kd (e - e_prev) / dt, -1, 1)``.

    Args:
        state: PIDState [B]. error_mps: [B] speed error [m/s].
        dt_s: step [s]. kp, ki, kd: gains [B] or scalars. integral_limit: [B] or scalar.
        integral_window_s: [B] or scalar, the integral's memory time constant [s].
    Returns:
        (u [B] in [-1, 1], new PIDState).
    """
    e = np.asarray(error_mps, dtype=np.float64)
    decay = core.pid_decay(dt_s, np.asarray(integral_window_s, dtype=np.float64))
    ki_a = np.asarray(ki, dtype=np.float64)
    lim = core.pid_limit(np.asarray(integral_limit, dtype=np.float64), ki_a)
    u, integral = core.pid_core(
        e, np.asarray(state.integral_m, dtype=np.float64), state.prev_error_mps, dt_s, decay,
        lim, np.asarray(kp, dtype=np.float64), ki_a, np.asarray(kd, dtype=np.float64),
    )  # fmt: skip
    return np.asarray(u), PIDState(np.asarray(integral), e)


def pid_reset_where(state: PIDState, mask: ArrayLike, error_mps: ArrayLike) -> PIDState:
    """Reset the PID (zero integral, previous error = current error) where mask is True."""
    m = np.asarray(mask, dtype=bool)
    e = np.asarray(error_mps, dtype=np.float64)
    return PIDState(np.where(m, 0.0, state.integral_m), np.where(m, e, state.prev_error_mps))


def command_to_accel(
    u: ArrayLike, max_accel_mps2: ArrayLike, max_decel_mps2: ArrayLike
) -> FloatArray:
    """Acceleration demanded by a command u in [-1, 1]: u * max_accel (u >= 0), u * max_decel (u < 0).

    Args:
        u: [B] command. max_accel_mps2, max_decel_mps2: [B] or scalars, both > 0.
    Returns:
        [B] demanded acceleration [m/s^2].
    """
    u = np.clip(np.asarray(u, dtype=np.float64), -1.0, 1.0)
    return np.asarray(core.command_to_accel_core(u, max_accel_mps2, max_decel_mps2))


def accel_to_command(
    a_mps2: ArrayLike, max_accel_mps2: ArrayLike, max_decel_mps2: ArrayLike
) -> FloatArray:
    """The command u in [-1, 1] that demands acceleration a (inverse of command_to_accel, clipped)."""
    a = np.asarray(a_mps2, dtype=np.float64)
    return np.asarray(core.accel_to_command_core(a, max_accel_mps2, max_decel_mps2))


def actuator_step(
    a_mps2: ArrayLike, a_cmd_mps2: ArrayLike, lag_s: ArrayLike, dt_s: float
) -> FloatArray:
    """First-order lag of the actual acceleration towards the demanded one (exact discretisation).

    ``a' = a + (1 - exp(-dt / tau)) (a_cmd - a)``; tau = 0 means no lag (a' = a_cmd).

    Args:
        a_mps2: [B] actual acceleration. a_cmd_mps2: [B] demand. lag_s: [B] or scalar tau.
        dt_s: step [s].
    Returns:
        [B] new actual acceleration [m/s^2].
    """
    alpha = core.lag_factor(np.asarray(lag_s, dtype=np.float64), dt_s)
    return np.asarray(core.actuator_core(a_mps2, np.asarray(a_cmd_mps2), alpha))


def speed_step(v_mps: ArrayLike, a_mps2: ArrayLike, dt_s: float) -> FloatArray:
    """``v' = max(0, v + a dt)``: the vehicle brakes to a stop, never reverses."""
    return np.asarray(core.speed_core(np.asarray(v_mps), np.asarray(a_mps2), dt_s))


# --------------------------------------------------------------------------------------
# CAP
# --------------------------------------------------------------------------------------
def safe_distance(
    v_mps: ArrayLike, t_safe_s: ArrayLike, d_buf_m: ArrayLike, a_min_mps2: ArrayLike
) -> FloatArray:
    """``d_safe = max(v^2 / (2 |a_min|), T_safe v) + d_buf`` [m] (paper eq. cap_safe_dist)."""
    v = np.asarray(v_mps, dtype=np.float64)
    return np.asarray(core.safe_distance_core(v, np.asarray(t_safe_s), d_buf_m, a_min_mps2))


def gap_braking_accel(
    v_mps: ArrayLike, gap_m: ArrayLike, d_buf_m: ArrayLike, a_min_mps2: ArrayLike
) -> FloatArray:
    """Gap law ``a = -v^2 / (2 (d - d_buf))`` saturated at a_min (a_min where d <= d_buf).

    The constant deceleration that stops the car exactly d_buf short of an obstacle at gap
    d; recomputed each step it stays constant along the ideal stop and corrects lag.

    Args:
        v_mps: [B] speed. gap_m: [B] gap d [m]. d_buf_m, a_min_mps2: [B] or scalars.
    Returns:
        [B] demanded acceleration [m/s^2], in [a_min, 0].
    """
    v = np.asarray(v_mps, dtype=np.float64)
    gap = np.asarray(gap_m, dtype=np.float64)
    return np.asarray(core.gap_braking_core(v, gap, d_buf_m, a_min_mps2))


def paper_braking_accel(
    v_mps: ArrayLike, t_safe_s: ArrayLike, d_buf_m: ArrayLike, a_min_mps2: ArrayLike
) -> FloatArray:
    """The paper's command ``a = -v^2 / (2 (d_safe(v) - d_buf))`` saturated at a_min.

    With d_safe from the current speed this is ``-min(|a_min|, v / (2 T_safe))`` whenever
    T_safe v dominates; recomputed every step the speed decays exponentially and the car
    travels 2 T_safe v0 after the trigger (DESIGN.md's careful note).

    Args:
        v_mps: [B] speed; t_safe_s, d_buf_m, a_min_mps2: [B] or scalars.
    Returns:
        [B] demanded acceleration [m/s^2], in [a_min, 0].
    """
    v = np.asarray(v_mps, dtype=np.float64)
    d_safe = safe_distance(v, t_safe_s, d_buf_m, a_min_mps2)
    return np.asarray(core.paper_braking_core(v, d_safe, d_buf_m, a_min_mps2))


def corridor_check(
    path: PathTable,
    ego_s_m: ArrayLike,
    ego_length_m: ArrayLike,
    rider_x_m: ArrayLike,
    rider_y_m: ArrayLike,
    rider_yaw_rad: ArrayLike,
    rider_length_m: ArrayLike,
    rider_width_m: ArrayLike,
    rider_active: ArrayLike,
    corridor_half_width_m: ArrayLike,
    detection_range_m: ArrayLike,
) -> tuple[BoolArray, FloatArray]:
    """Is the rider ahead in the ego's path corridor, and how far is it along the path?

    The rider's centre is projected onto the ego's path: first along the path's heading
    at the ego (straight-path guess), then one local correction at the guessed foot point.
    It is "ahead in the corridor" when it is active, its lateral offset from the path is
    at most ``corridor_half_width_m``, some part of it lies ahead of the ego's front
    bumper and its gap is within ``detection_range_m``.

    The gap d is the along-path distance from the ego's front bumper to the rider's
    nearest extent along the path (its box half-extent ``l/2 |cos dpsi| + w/2 |sin dpsi|``,
    dpsi = rider heading relative to the path), clipped at 0.

    Args:
        path: the ego's PathTable. ego_s_m: [B] ego arc length [m] (centre).
        ego_length_m: [B] or scalar.
        rider_x_m, rider_y_m, rider_yaw_rad: [B] rider pose as the CAP perceives it.
        rider_length_m, rider_width_m: [B] or scalars. rider_active: [B] bool.
        corridor_half_width_m, detection_range_m: [B] or scalars [m].
    Returns:
        (ahead [B] bool, gap_m [B] >= 0; +inf where not ahead).
    """
    shape = np.broadcast_shapes(np.shape(ego_s_m), np.shape(rider_x_m), np.shape(rider_y_m))

    def flat(a: ArrayLike) -> FloatArray:
        a = np.asarray(a, dtype=np.float64)
        if a.ndim == 0:
            return a  # scalars broadcast by themselves
        return np.broadcast_to(a, shape).reshape(-1)

    s_e, rx, ry = flat(ego_s_m), flat(rider_x_m), flat(rider_y_m)
    i, w = path.index(s_e)
    ex, ey, ec, es = path.values_at(i, w, "x", "y", "cos", "sin")
    s_q, _ = core.path_foot_core(s_e, rx, ry, ex, ey, ec, es)
    i, w = path.index(s_q)
    px, py, pc, ps = path.values_at(i, w, "x", "y", "cos", "sin")
    s_q, lat = core.path_foot_core(s_q, rx, ry, px, py, pc, ps)
    l_r, w_r = flat(rider_length_m), flat(rider_width_m)
    d_front, cand = core.corridor_entry_core(
        s_q, lat, s_e, flat(ego_length_m), flat(corridor_half_width_m),
        core.half_diagonal_core(l_r, w_r),
    )  # fmt: skip
    active = np.asarray(rider_active, dtype=bool)
    if active.ndim or not bool(active):
        cand &= np.broadcast_to(active, shape).reshape(-1)
    ahead = np.zeros(cand.shape, dtype=bool)
    gap = np.full(cand.shape, np.inf)
    idx = np.flatnonzero(cand)
    if idx.size:
        yaw = flat(rider_yaw_rad)[idx]
        cr, sr, pci, psi = np.cos(yaw), np.sin(yaw), pc[idx], ps[idx]

        def at(a: FloatArray) -> FloatArray:
            return a if a.ndim == 0 else a[idx]

        ext = core.box_extent_core(cr, sr, pci, psi, at(l_r), at(w_r))
        ok, g = core.corridor_gap_core(d_front[idx], ext, at(flat(detection_range_m)))
        ahead[idx] = ok
        gap[idx] = np.where(ok, g, np.inf)
    return ahead.reshape(shape), gap.reshape(shape)


def cap_step(
    cap_state: ArrayLike,
    v_mps: ArrayLike,
    v_cruise_mps: ArrayLike,
    rider_ahead: ArrayLike,
    gap_m: ArrayLike,
    *,
    t_safe_s: ArrayLike = 2.0,
    d_buf_m: ArrayLike = 3.0,
    a_min_mps2: ArrayLike = -6.0,
    release_margin_m: ArrayLike = 2.0,
    recover_tolerance_mps: ArrayLike = 0.2,
    paper_per_step: ArrayLike = False,
) -> tuple[npt.NDArray[np.int8], FloatArray, BoolArray, BoolArray]:
    """One tick of the CAP finite-state machine (CRUISE=0 / BRAKE=1 / RECOVER=2).

    Transitions, in this order:
      - any state -> BRAKE when the rider is ahead in the corridor and d < d_safe(v);
      - BRAKE -> RECOVER when the rider is not ahead any more, or d > d_safe + release_margin;
      - RECOVER -> CRUISE when |v - v_d| <= recover_tolerance.
    In BRAKE the demanded acceleration is the gap law (default) or the paper's per-step
    law (``paper_per_step``), saturated at a_min; otherwise the caller uses its PID.

    Args:
        cap_state: [B] int8 current state. v_mps: [B] ego speed. v_cruise_mps: [B] v_d.
        rider_ahead, gap_m: [B] from :func:`corridor_check` (with perception delay applied
            by the caller: pass the delayed rider pose to corridor_check).
        t_safe_s, d_buf_m, a_min_mps2, release_margin_m, recover_tolerance_mps: [B] or
            scalars (CAPConfig). paper_per_step: [B] bool or scalar.
    Returns:
        (new_state [B] int8, a_brake_mps2 [B] (0 where not braking), braking [B] bool,
        entered_recover [B] bool: True where BRAKE -> RECOVER happened now (reset the PID)).
    """
    st = np.asarray(cap_state, dtype=np.int8)
    v = np.asarray(v_mps, dtype=np.float64)
    ahead = np.asarray(rider_ahead, dtype=bool)
    gap = np.asarray(gap_m, dtype=np.float64)
    d_safe = safe_distance(v, t_safe_s, d_buf_m, a_min_mps2)
    new, release = core.cap_transition_core(
        st, v, v_cruise_mps, ahead, gap, d_safe, release_margin_m, recover_tolerance_mps
    )
    new = np.asarray(new).astype(np.int8)
    release = np.asarray(release)
    braking = new == BRAKE
    paper = np.asarray(paper_per_step, dtype=bool)
    if paper.ndim == 0 and not bool(paper):
        a = gap_braking_accel(v, np.where(ahead, gap, 1e9), d_buf_m, a_min_mps2)
    elif paper.ndim == 0:
        a = core.paper_braking_core(v, d_safe, d_buf_m, a_min_mps2)
    else:
        a = np.where(
            paper,
            core.paper_braking_core(v, d_safe, d_buf_m, a_min_mps2),
            gap_braking_accel(v, np.where(ahead, gap, 1e9), d_buf_m, a_min_mps2),
        )
    return new, np.where(braking, a, 0.0), braking, release
