"""The geometry of one continuation: a track's motion at its end, carried on.

Pure NumPy. A continuation is computed for the *end* of a track (the run-out); the run-in
is the run-out of the time-reversed track, reversed back (:func:`run_in`).

At the end sample the track has a position, a speed v, a direction of motion (course,
from its last step) and a curvature (the slope of the course over the arc length of its
last second). The continuation keeps the speed (a road user slower than
``standing_speed_mps`` brakes to a stop at ``stop_decel_mps2`` and then stands), and
turns with the curvature decaying as ``kappa0 exp(-s / l)``, so that the whole
continuation turns by ``kappa0 l`` at most: a turn in progress is finished, never
continued into a circle. kappa0 is reduced until ``v^2 |kappa0| <= max_lat_accel`` and
``|kappa0| l <= max_turn``. The body yaw keeps its recorded offset from the course, which
decays with the curvature (over a longer length if its yaw rate would exceed the
recording's own largest yaw step). Samples lie on the track's time grid.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]

#: Length of the end window whose course gives the curvature [s].
END_WINDOW_S = 1.0
#: Arc-length resolution of the integrated continuation path [m].
_DS_M = 0.02
#: A step shorter than this does not define a course [m].
_MIN_STEP_M = 1e-3
#: Floor of the recording's yaw noise per step [rad] (a perfectly smooth recording).
_MIN_YAW_STEP_RAD = 5e-3


def wrap(angle: npt.ArrayLike) -> FloatArray:
    """Angles wrapped to (-pi, pi] [rad]."""
    a = np.asarray(angle, dtype=np.float64)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


@dataclass(frozen=True)
class EndState:
    """The motion of a track at its last sample.

    Attributes:
        t_s: time of the last sample [s]. dt_s: the track's sample step [s].
        x_m, y_m: position [m]. yaw_rad: recorded body yaw [rad].
        course_rad: direction of motion of the last step [rad] (the yaw when standing).
        speed_mps: speed [m/s] (>= 0). curvature_per_m: signed curvature of the motion
            over the last ``END_WINDOW_S`` [1/m] (0 when standing).
        yaw_step_rad: the recording's largest |yaw change| per step over that window [rad]
            (at least 5e-3): the "recorded noise" the join is held to.
        speed_step_mps: the same for the speed [m/s].
        yaw_curvature_per_m: the recorded body yaw's change over the last step per metre
            at the end speed [1/m] (its yaw rate / speed; 0 when standing).
    """

    t_s: float
    dt_s: float
    x_m: float
    y_m: float
    yaw_rad: float
    course_rad: float
    speed_mps: float
    curvature_per_m: float
    yaw_step_rad: float
    speed_step_mps: float
    yaw_curvature_per_m: float = 0.0


def end_state(
    t_s: FloatArray, x_m: FloatArray, y_m: FloatArray, yaw_rad: FloatArray, speed_mps: FloatArray
) -> EndState:
    """The :class:`EndState` of a track's last sample.

    Args:
        t_s, x_m, y_m, yaw_rad, speed_mps: [N >= 1] the track (strictly increasing times;
            a NaN speed is taken from the positions).
    """
    t = np.asarray(t_s, dtype=np.float64)
    x = np.asarray(x_m, dtype=np.float64)
    y = np.asarray(y_m, dtype=np.float64)
    yaw = np.asarray(yaw_rad, dtype=np.float64)
    sp = np.asarray(speed_mps, dtype=np.float64)
    n = t.size
    dt = float(np.median(np.diff(t))) if n > 1 else 0.05
    step = np.hypot(np.diff(x), np.diff(y))
    v = float(sp[-1]) if np.isfinite(sp[-1]) else (float(step[-1]) / dt if n > 1 else 0.0)
    v = max(v, 0.0)
    yaw_end = float(yaw[-1]) if np.isfinite(yaw[-1]) else 0.0
    course = yaw_end
    moving = np.flatnonzero(step > _MIN_STEP_M)
    if moving.size and moving[-1] == n - 2:
        course = math.atan2(y[-1] - y[-2], x[-1] - x[-2])
    w0 = int(np.searchsorted(t, t[-1] - END_WINDOW_S - 1e-9))
    kappa = kappa_yaw = 0.0
    if n - w0 >= 3 and v > 0.0:
        cx, cy = np.diff(x[w0:]), np.diff(y[w0:])
        ds = np.hypot(cx, cy)
        ok = ds > _MIN_STEP_M
        if ok.sum() >= 2:
            th = np.unwrap(np.arctan2(cy[ok], cx[ok]))
            s = np.cumsum(ds)[ok] - 0.5 * ds[ok]
            if s[-1] - s[0] > 1e-6:
                kappa = float(np.polyfit(s, th, 1)[0])
        if np.isfinite(yaw[-2:]).all():  # the last step's yaw rate, per metre at v
            kappa_yaw = float(wrap(yaw[-1] - yaw[-2])) / (v * dt)
    win_yaw = np.unwrap(yaw[w0:][np.isfinite(yaw[w0:])])
    yaw_step = float(np.abs(np.diff(win_yaw)).max()) if win_yaw.size > 1 else 0.0
    win_sp = sp[w0:][np.isfinite(sp[w0:])]
    sp_step = float(np.abs(np.diff(win_sp)).max()) if win_sp.size > 1 else 0.0
    return EndState(
        t_s=float(t[-1]),
        dt_s=dt,
        x_m=float(x[-1]),
        y_m=float(y[-1]),
        yaw_rad=yaw_end,
        course_rad=course,
        speed_mps=v,
        curvature_per_m=kappa,
        yaw_step_rad=max(yaw_step, _MIN_YAW_STEP_RAD),
        speed_step_mps=sp_step,
        yaw_curvature_per_m=kappa_yaw,
    )


@dataclass(frozen=True)
class Motion:
    """How a continuation moves: its duration and its distance over time.

    Attributes:
        standing: the road user was slower than the standing speed (brakes, then stands).
        t_rel_s: [K] sample times after the end sample [s] (dt, 2 dt, ...).
        s_m: [K] distance travelled by then [m]. speed_mps: [K] speed [m/s].
    """

    standing: bool
    t_rel_s: FloatArray
    s_m: FloatArray
    speed_mps: FloatArray


def motion(
    end: EndState, reach_m: float, *, standing_speed_mps: float, stop_decel_mps2: float
) -> Motion:
    """The speed profile of a continuation of length ``reach_m`` [m].

    Duration: reach / max(v, standing speed), rounded up to whole steps (a standing road
    user waits as long as one at the standing speed needs for the distance). A moving road
    user keeps its speed; a slower one brakes to a stop at ``stop_decel_mps2``.
    """
    v = end.speed_mps
    dur = reach_m / max(v, standing_speed_mps)
    k = max(int(math.ceil(dur / end.dt_s - 1e-9)), 1)
    tau = np.arange(1, k + 1) * end.dt_s
    if v >= standing_speed_mps:
        return Motion(False, tau, v * tau, np.full(k, v))
    t_stop = v / stop_decel_mps2
    tt = np.minimum(tau, t_stop)
    s = v * tt - 0.5 * stop_decel_mps2 * tt * tt
    return Motion(True, tau, s, np.maximum(v - stop_decel_mps2 * tau, 0.0))


def end_curvature(
    end: EndState, *, decay_m: float, max_turn_rad: float, max_lat_accel_mps2: float
) -> float:
    """The end curvature, reduced to the lateral-acceleration and total-turn bounds [1/m]."""
    k0 = end.curvature_per_m
    bound = max_turn_rad / decay_m
    if end.speed_mps > 0.0:
        bound = min(bound, max_lat_accel_mps2 / (end.speed_mps * end.speed_mps))
    return float(np.clip(k0, -bound, bound))


def free_path(end: EndState, length_m: float, kappa0: float, decay_m: float) -> FloatArray:
    """[M, 3] the free continuation's path x, y [m], course [rad] every ``_DS_M`` of arc
    length from the end point (s = 0) to ``length_m``: course
    ``course0 + kappa0 decay (1 - exp(-s / decay))``."""
    n = max(int(math.ceil(length_m / _DS_M)), 1) + 1
    s = np.linspace(0.0, max(length_m, _DS_M), n)
    th = end.course_rad + kappa0 * decay_m * (1.0 - np.exp(-s / decay_m))
    return _integrate(end.x_m, end.y_m, s, th)


def _integrate(x0: float, y0: float, s: FloatArray, th: FloatArray) -> FloatArray:
    """[M, 3] positions along arc s with course th (trapezoid on the unit tangent)."""
    ds = np.diff(s)
    c, sn = np.cos(th), np.sin(th)
    x = x0 + np.concatenate([[0.0], np.cumsum(0.5 * (c[1:] + c[:-1]) * ds)])
    y = y0 + np.concatenate([[0.0], np.cumsum(0.5 * (sn[1:] + sn[:-1]) * ds)])
    return np.column_stack([x, y, th])


def path_arc(path: FloatArray) -> FloatArray:
    """[M] arc length along a path's points [m]."""
    return np.concatenate([[0.0], np.cumsum(np.hypot(np.diff(path[:, 0]), np.diff(path[:, 1])))])


def sample(end: EndState, mov: Motion, path: FloatArray, decay_m: float) -> dict[str, FloatArray]:
    """The continuation's samples: {'t_s', 'x_m', 'y_m', 'yaw_rad', 'speed_mps'} [K].

    Positions and course are interpolated along ``path`` at the travelled distance; the
    body yaw is the course plus the end's recorded offset o0 = yaw - course, which decays
    as ``(o0 + (o0 / L + k_yaw - k_path) s) exp(-s / L)``: the yaw starts at the recorded
    yaw turning at the recorded rate (k_yaw: the yaw's change per metre at the end,
    k_path: the path's curvature at s = 0) and ends along the course. L = ``decay_m``,
    or longer where the offset alone would turn the yaw by more than the recording's
    largest yaw step per step. A standing continuation keeps the recorded yaw.
    """
    arc = path_arc(path)
    s = np.minimum(mov.s_m, arc[-1])
    x = np.interp(s, arc, path[:, 0])
    y = np.interp(s, arc, path[:, 1])
    course = np.interp(s, arc, np.unwrap(path[:, 2]))
    if mov.standing:
        yaw = np.full(s.shape, end.yaw_rad)
    else:
        off = float(wrap(end.yaw_rad - end.course_rad))
        step_s = max(end.speed_mps * end.dt_s, 1e-9)
        length = max(decay_m, abs(off) * step_s / end.yaw_step_rad)
        th = np.unwrap(path[:, 2])
        k_path = float((th[1] - th[0]) / (arc[1] - arc[0])) if arc.size > 1 else 0.0
        slope = off / length + end.yaw_curvature_per_m - k_path
        yaw = course + (off + slope * s) * np.exp(-s / length)
        yaw = yaw + (end.yaw_rad - (th[0] + off))  # = yaw at s = 0: joins unwrapped
    return {
        "t_s": grid_times(end, mov.t_rel_s.size),
        "x_m": x,
        "y_m": y,
        "yaw_rad": yaw,
        "speed_mps": mov.speed_mps.copy(),
    }


def grid_times(end: EndState, k: int) -> FloatArray:
    """[k] the times of the k samples after the end sample [s]: on the track's grid,
    written as (i + j) / rate like the recorded times ``i / rate`` where the step is a
    whole-number rate (20 Hz: 0.05 s), so that the spacing is the recording's own."""
    j = np.arange(1, k + 1)
    if end.dt_s <= 0.0:
        return end.t_s + j * 0.05
    rate = 1.0 / end.dt_s
    i_end = end.t_s * round(rate)
    if abs(rate - round(rate)) < 1e-6 and abs(i_end - round(i_end)) < 1e-6:
        return (round(i_end) + j) / float(round(rate))
    return end.t_s + j * end.dt_s


def run_in(
    t_s: FloatArray, x_m: FloatArray, y_m: FloatArray, yaw_rad: FloatArray, speed_mps: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """The track reversed in time (times negated, order reversed, yaw turned by pi): its
    run-out is the original's run-in (turn the result back with :func:`reverse_samples`)."""
    return (
        -np.asarray(t_s, dtype=np.float64)[::-1],
        np.asarray(x_m, dtype=np.float64)[::-1],
        np.asarray(y_m, dtype=np.float64)[::-1],
        (np.asarray(yaw_rad, dtype=np.float64) + np.pi)[::-1],
        np.asarray(speed_mps, dtype=np.float64)[::-1],
    )


def reverse_samples(samples: dict[str, FloatArray]) -> dict[str, FloatArray]:
    """Samples of a reversed track's run-out as the original's run-in (in time order)."""
    return {
        "t_s": -samples["t_s"][::-1],
        "x_m": samples["x_m"][::-1],
        "y_m": samples["y_m"][::-1],
        "yaw_rad": (samples["yaw_rad"] - np.pi)[::-1],
        "speed_mps": samples["speed_mps"][::-1],
    }


def near_turn(yaw: FloatArray, ref: float) -> FloatArray:
    """``yaw`` shifted by whole turns so that its last element lies within pi of ``ref``."""
    if yaw.size == 0 or not math.isfinite(ref):
        return yaw
    return yaw + 2.0 * np.pi * np.round((ref - yaw[-1]) / (2.0 * np.pi))


def lateral_accel(x_m: FloatArray, y_m: FloatArray, t_s: FloatArray) -> FloatArray:
    """[K] |lateral acceleration| of a sampled motion [m/s^2] (central differences; the
    ends one-sided), the plausibility measure of the tests and reports."""
    if x_m.size < 3:
        return np.zeros(x_m.size)
    vx, vy = np.gradient(x_m, t_s), np.gradient(y_m, t_s)
    ax, ay = np.gradient(vx, t_s), np.gradient(vy, t_s)
    sp = np.hypot(vx, vy)
    with np.errstate(invalid="ignore", divide="ignore"):
        lat = np.abs(vx * ay - vy * ax) / sp
    return np.where(sp > 1e-6, lat, 0.0)
