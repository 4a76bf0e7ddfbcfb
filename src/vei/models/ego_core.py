"""The ego's control laws, written once for both engines: PID, actuator, CAP laws and states.

Every function here uses NumPy ufuncs, arithmetic and :func:`select` only, so the same
source runs vectorised on arrays ``[B]`` (the NumPy reference step through
:mod:`vei.models.ego`) and compiled by numba on scalars (the compiled kernel,
:mod:`vei.sim.kernel.ego`), like :func:`vei.boxes.overlap_core` for the box overlap.
The order of operations is the compiled kernel's (its outputs are pinned bit for bit by
tests/sim/kernel/test_kernel_regression.py); on arrays NumPy's vectorised ``exp`` / ``expm1`` may
differ from the C library's in the last bit, nothing else does.

Three helpers stand for what NumPy and numba spell differently: :func:`select`
(``np.where``; numba compiles it to ``a if cond else b`` on scalars), :func:`maximum` and
:func:`minimum` (``np.maximum`` / ``np.minimum``; numba compiles them to Python's ``max`` /
``min`` on scalars, one instruction instead of numba's NaN-propagating ufunc, whose extra
compares lie on the step's critical path). Both return the first argument on a tie (so
``0.0`` vs ``-0.0`` resolves alike); they differ only for NaN, which the laws never see.
:func:`select` evaluates both arguments, so every division is guarded.

Units: speeds [m/s], accelerations [m/s^2] (negative = braking), distances [m], times [s];
the command u in [-1, 1] (u >= 0 throttle, u < 0 brake).
"""

from __future__ import annotations

from typing import Any

import numpy as np

#: CAP states (int8 codes in the engine's arrays).
CRUISE, BRAKE, RECOVER = 0, 1, 2


def select(cond: Any, a: Any, b: Any) -> Any:
    """``a`` where ``cond`` else ``b`` (``np.where``; a scalar ternary when numba compiles it)."""
    return np.where(cond, a, b)


def maximum(a: Any, b: Any) -> Any:
    """Elementwise maximum (``np.maximum``; Python's ``max`` when numba compiles it)."""
    return np.maximum(a, b)


def minimum(a: Any, b: Any) -> Any:
    """Elementwise minimum (``np.minimum``; Python's ``min`` when numba compiles it)."""
    return np.minimum(a, b)


# ----------------------------------------------------------------------------- PID
def pid_decay(dt_s: Any, integral_window_s: Any) -> Any:
    """Per-step decay of the PID integral, ``exp(-dt / window)`` (window = inf: 1)."""
    return np.exp(-dt_s / integral_window_s)


def pid_limit(integral_limit: Any, ki: Any) -> Any:
    """Clamp of the PID integral [m]: ``integral_limit / ki`` (``/ 1`` where ki <= 0)."""
    return integral_limit / select(ki > 0, ki, 1.0)


def pid_core(
    err: Any,
    integral: Any,
    prev_err: Any,
    dt_s: Any,
    decay: Any,
    lim: Any,
    kp: Any,
    ki: Any,
    kd: Any,
) -> tuple[Any, Any]:
    """One PID step on the speed error err = v_d - v [m/s].

    ``I <- clip(I decay + e dt, -lim, lim)``; ``u = clip(kp e + ki I + kd (e - e_prev) / dt,
    -1, 1)``; decay from :func:`pid_decay`, lim from :func:`pid_limit`.
    Returns (u, new integral [m]); the new previous error is err itself.
    """
    integral = integral * decay + err * dt_s
    integral = minimum(maximum(integral, -lim), lim)
    deriv = (err - prev_err) / dt_s
    u = minimum(1.0, maximum(-1.0, kp * err + ki * integral + kd * deriv))
    return u, integral


# ------------------------------------------------------------------------ actuator
def command_to_accel_core(u: Any, max_accel_mps2: Any, max_decel_mps2: Any) -> Any:
    """Demanded acceleration of a command u in [-1, 1]: u max_accel (u >= 0), u max_decel (u < 0)."""
    return u * select(u >= 0.0, max_accel_mps2, max_decel_mps2)


def accel_to_command_core(a_mps2: Any, max_accel_mps2: Any, max_decel_mps2: Any) -> Any:
    """The command in [-1, 1] that demands a (inverse of :func:`command_to_accel_core`, clipped)."""
    return minimum(
        1.0, maximum(-1.0, a_mps2 / select(a_mps2 >= 0.0, max_accel_mps2, max_decel_mps2))
    )


def lag_factor(lag_s: Any, dt_s: Any) -> Any:
    """Actuator lag factor ``1 - exp(-dt / tau)`` (exact discretisation; tau <= 0: 1, no lag)."""
    pos = lag_s > 0
    return select(pos, -np.expm1(-dt_s / select(pos, lag_s, 1.0)), 1.0)


def actuator_core(a_mps2: Any, a_cmd_mps2: Any, alpha: Any) -> Any:
    """First-order lag of the actual acceleration: ``a + alpha (a_cmd - a)`` (alpha: :func:`lag_factor`)."""
    return a_mps2 + alpha * (a_cmd_mps2 - a_mps2)


def speed_core(v_mps: Any, a_mps2: Any, dt_s: Any) -> Any:
    """``v' = max(0, v + a dt)``: the vehicle brakes to a stop, never reverses."""
    return maximum(0.0, v_mps + a_mps2 * dt_s)


def reported_accel_core(v_mps: Any, v_new_mps: Any, a_act_mps2: Any, dt_s: Any) -> Any:
    """Reported acceleration: the actuator's, or the speed change where braking stopped the car."""
    stopped = np.logical_and(v_new_mps <= 0.0, a_act_mps2 < 0.0)
    return select(stopped, (v_new_mps - v_mps) / dt_s, a_act_mps2)


# ----------------------------------------------------------------------------- CAP
def safe_distance_core(v_mps: Any, t_safe_s: Any, d_buf_m: Any, a_min_mps2: Any) -> Any:
    """``d_safe = max(v^2 / (2 |a_min|), T_safe v) + d_buf`` [m] (paper eq. cap_safe_dist)."""
    return maximum(v_mps * v_mps / (2.0 * np.abs(a_min_mps2)), t_safe_s * v_mps) + d_buf_m


def gap_braking_core(v_mps: Any, gap_m: Any, d_buf_m: Any, a_min_mps2: Any) -> Any:
    """Gap law ``a = -v^2 / (2 (d - d_buf))`` saturated at a_min (a_min, or 0 standing, where d <= d_buf)."""
    room = gap_m - d_buf_m
    ok = room > 0
    a = -v_mps * v_mps / (2.0 * select(ok, room, 1.0))
    return select(ok, maximum(a, a_min_mps2), select(v_mps > 0, a_min_mps2, 0.0))


def paper_braking_core(v_mps: Any, d_safe_m: Any, d_buf_m: Any, a_min_mps2: Any) -> Any:
    """The paper's law ``a = -v^2 / (2 (d_safe - d_buf))`` saturated at a_min (0 where d_safe <= d_buf)."""
    room = d_safe_m - d_buf_m
    ok = room > 0
    a = -v_mps * v_mps / (2.0 * select(ok, room, 1.0))
    return select(ok, maximum(a, a_min_mps2), 0.0)


def cap_transition_core(
    cap_state: Any,
    v_mps: Any,
    v_cruise_mps: Any,
    ahead: Any,
    gap_m: Any,
    d_safe_m: Any,
    release_margin_m: Any,
    recover_tolerance_mps: Any,
) -> tuple[Any, Any]:
    """One transition of the CAP state machine (CRUISE=0 / BRAKE=1 / RECOVER=2), in this order.

    Any state -> BRAKE when the rider is ahead and d < d_safe; BRAKE -> RECOVER when it is
    not ahead any more or d > d_safe + release_margin; RECOVER -> CRUISE when |v - v_d| <=
    recover_tolerance. Returns (new state, release: BRAKE -> RECOVER happened now).
    """
    trigger = np.logical_and(ahead, gap_m < d_safe_m)
    release = np.logical_and(
        np.logical_and(cap_state == BRAKE, np.logical_not(trigger)),
        np.logical_or(np.logical_not(ahead), gap_m > d_safe_m + release_margin_m),
    )
    recovered = np.logical_and(
        cap_state == RECOVER, np.abs(v_mps - v_cruise_mps) <= recover_tolerance_mps
    )
    new = select(trigger, BRAKE, select(release, RECOVER, select(recovered, CRUISE, cap_state)))
    return new, release


# The CAP's corridor test (vei.models.ego.corridor_check on arrays, the compiled kernel on
# scalars): the rider's centre projected onto the ego's path, then its box against the
# corridor. The path lookups differ between the engines (vei.sim.tables.PathTable vs the
# kernel's packed table); the geometry after them is this.


def path_foot_core(
    s_m: Any, x_m: Any, y_m: Any, px_m: Any, py_m: Any, cos_p: Any, sin_p: Any
) -> tuple[Any, Any]:
    """One projection step of the point (x, y) [m] onto the path through p [m] with heading
    (cos_p, sin_p) at arc length s [m]: the foot's arc length ``s + (x - px) cos + (y - py)
    sin`` [m] and the signed lateral offset ``(y - py) cos - (x - px) sin`` [m] (left > 0)."""
    dx = x_m - px_m
    dy = y_m - py_m
    return s_m + dx * cos_p + dy * sin_p, dy * cos_p - dx * sin_p


def half_diagonal_core(length_m: Any, width_m: Any) -> Any:
    """Half the diagonal of a box [m]: the radius of the circle around it."""
    return 0.5 * np.hypot(length_m, width_m)


def corridor_entry_core(
    s_foot_m: Any, lateral_m: Any, s_ego_m: Any, ego_length_m: Any, half_width_m: Any,
    rider_half_diag_m: Any,
) -> tuple[Any, Any]:  # fmt: skip
    """(d_front [m], may be ahead): the foot's distance ahead of the ego's front bumper, and
    whether the rider's centre is within the corridor's half width and its circle reaches
    past the bumper (the cheap test before its box is oriented)."""
    d_front = s_foot_m - s_ego_m - 0.5 * ego_length_m
    entry = np.logical_and(np.abs(lateral_m) <= half_width_m, d_front + rider_half_diag_m > 0.0)
    return d_front, entry


def box_extent_core(
    cos_yaw: Any, sin_yaw: Any, cos_p: Any, sin_p: Any, length_m: Any, width_m: Any
) -> Any:
    """Half-extent [m] along the path direction (cos_p, sin_p) of a box with heading
    (cos_yaw, sin_yaw): ``l/2 |cos dpsi| + w/2 |sin dpsi|``, dpsi its heading relative to
    the path."""
    along = np.abs(cos_yaw * cos_p + sin_yaw * sin_p)
    across = np.abs(sin_yaw * cos_p - cos_yaw * sin_p)
    return 0.5 * length_m * along + 0.5 * width_m * across


def corridor_gap_core(d_front_m: Any, extent_m: Any, range_m: Any) -> tuple[Any, Any]:
    """(ahead, gap [m]): part of the rider's box lies ahead of the bumper and its near side
    within the detection range; the gap from the bumper to that side, clipped at 0."""
    g = d_front_m - extent_m
    ahead = np.logical_and(d_front_m + extent_m > 0.0, g <= range_m)
    return ahead, maximum(g, 0.0)
