"""The ego's longitudinal step in the compiled kernel: replayed speed, or PID cruise + CAP.

Imported only when numba is used. The PID, actuator, CAP laws and CAP state machine are
:mod:`vei.models.ego_core`'s functions, compiled here on scalars (the NumPy reference step
runs the same functions on arrays through :mod:`vei.models.ego`), and the CAP's corridor
test is :mod:`vei.sim.kernel.corridor`'s; this module adds the per-variant control flow,
for one variant, inlined into the kernel's loop (``inline="always"``: no call per variant and step). SI units (m, s, m/s, m/s^2).
"""

# ruff: noqa: N803
from __future__ import annotations

import numba
import numpy as np

from vei.models import ego_core as core
from vei.sim.kernel.corridor import corridor_at, half_diagonal, path_point
from vei.sim.kernel.layout import (
    P_AMAX,
    P_AMIN,
    P_DBUF,
    P_DMAX,
    P_HALFW,
    P_ILIM,
    P_IWIN,
    P_KD,
    P_KI,
    P_KP,
    P_LAG,
    P_PAPERLAW,
    P_RANGE,
    P_RECTOL,
    P_RELEASE,
    P_TSAFE,
)
from vei.sim.kernel.scalar import idx  # also registers select / maximum / minimum on scalars

_inline = numba.njit(cache=True, inline="always")
pid_decay = _inline(core.pid_decay)
pid_limit = _inline(core.pid_limit)
pid_core = _inline(core.pid_core)
lag_factor = _inline(core.lag_factor)
command_to_accel = _inline(core.command_to_accel_core)
accel_to_command = _inline(core.accel_to_command_core)
actuator = _inline(core.actuator_core)
speed = _inline(core.speed_core)
reported_accel = _inline(core.reported_accel_core)
safe_distance = _inline(core.safe_distance_core)
gap_braking = _inline(core.gap_braking_core)
paper_braking = _inline(core.paper_braking_core)
cap_transition = _inline(core.cap_transition_core)


@numba.njit(cache=True, inline="always")
def ego_consts(P, b, dt, Lr, Wr):  # type: ignore[no-untyped-def]
    """The ego's per-variant constants, read and derived once per variant (not per step).

    Args: P [N_PARAMS, B] the packed parameters, b the variant, dt [s] the step, Lr x Wr
    [m] the rider's footprint. Returns the tuple that :func:`ego_step_c` takes: the
    parameters of P it reads and the values derived from them alone (the PID integral's
    decay factor and clamp, the actuator's lag factor, half the rider's
    diagonal), each computed by the expression the step used to evaluate every step.
    """
    ki = P[P_KI, b]
    return (
        P[P_AMAX, b], P[P_DMAX, b], P[P_HALFW, b], P[P_RANGE, b], P[P_AMIN, b], P[P_DBUF, b],
        P[P_TSAFE, b], P[P_RELEASE, b], P[P_RECTOL, b], P[P_PAPERLAW, b] > 0.5,
        pid_decay(dt, P[P_IWIN, b]), ki, pid_limit(P[P_ILIM, b], ki),
        P[P_KP, b], P[P_KD, b], lag_factor(P[P_LAG, b], dt), half_diagonal(Lr, Wr),
    )  # fmt: skip


@numba.njit(cache=True, inline="always")
def ego_step(  # type: ignore[no-untyped-def]
    k, t_new, dt, P, b, mode, delay, vd, hist_len,
    s, v, a_act, pid_i, pid_e, cap, collided,
    rx, ry, ryaw, r_act, hist, egeo,
):  # fmt: skip
    """:func:`ego_step_c` with the constants read from P (kept for callers that do not hoist them)."""
    c = ego_consts(P, b, dt, egeo[9], egeo[10])
    return ego_step_c(
        k, t_new, dt, c, mode, delay, vd, hist_len,
        s, v, a_act, pid_i, pid_e, cap, collided,
        rx, ry, ryaw, r_act, hist, egeo,
    )  # fmt: skip


@numba.njit(cache=True, inline="always")
def ego_step_c(  # type: ignore[no-untyped-def]
    k, t_new, dt, c, mode, delay, vd, hist_len,
    s, v, a_act, pid_i, pid_e, cap, collided,
    rx, ry, ryaw, r_act, hist, egeo,
):  # fmt: skip
    """One step of the ego of one variant from step k to k + 1 (time t_new [s]).

    Args: c the variant's constants (:func:`ego_consts`); mode 0 replay, 1 PID cruise,
    2 PID + CAP; delay the perception delay [steps]; vd the cruise speed [m/s]; the ego
    state (s [m], v [m/s], a_act [m/s^2], PID integral [m] and previous error [m/s], CAP
    state, collided); the rider now (pose, active) and the perception ring hist = (hx, hy,
    hyaw, hact) [hist_len]; egeo = (path, p_s0, p_ds, n_p, etab, e_t0, e_dt, n_e, Le, Lr,
    Wr): the ego path [10, n_p] on the arc grid p_s0 + i p_ds and recorded speed table
    [4, n_e] on t = e_t0 + i e_dt (values then slopes), footprints Le (ego length), Lr x Wr
    (rider) [m]. The ring's arrays and the path are indexed in place (``hist[0][slot]``,
    ``egeo[0][r, i]``), never bound to names: a name holding an array across the step's
    branches makes numba keep an atomic reference-count increment and decrement per array
    and step (~8 % of the kernel's time when the ring was unpacked here).
    Returns (s_new, v_new, a_act_n, a_rep_n, u, pid_i, pid_e, cap): the new arc length,
    speed, actuator and reported accelerations, command in [-1, 1], PID and CAP state.
    """
    (
        amax, dmax, halfw, rng, a_min, d_buf, tsafe, rel_m, rectol, paperlaw,
        decay, ki, lim, kp, kd, alpha, half_diag_r,
    ) = c  # fmt: skip
    p_s0, p_ds, n_p = egeo[1], egeo[2], egeo[3]
    e_t0, e_dt, n_e, Le, Lr, Wr = egeo[5], egeo[6], egeo[7], egeo[8], egeo[9], egeo[10]
    u = 0.0
    if mode == 0:
        i, w = idx(e_t0, e_dt, n_e, t_new)
        s_new = egeo[4][0, i] + w * egeo[4][2, i]
        v_new = egeo[4][1, i] + w * egeo[4][3, i]
        a_act_n = (v_new - v) / dt
        a_rep_n = a_act_n
        u = accel_to_command(a_act_n, amax, dmax)
    else:
        err = vd - v
        braking = False
        a_brake = 0.0
        if mode == 2:
            if hist_len == 1 or delay == 0:
                px, py, pyaw, pact = rx, ry, ryaw, r_act
            else:
                lag_k = k - delay
                slot = lag_k % hist_len
                px, py, pyaw = hist[0][slot], hist[1][slot], hist[2][slot]
                pact = hist[3][slot] > 0.5 and lag_k >= 0
            ahead = False
            gap = np.inf
            if pact and not collided:
                q = path_point(egeo[0], p_s0, p_ds, n_p, s)
                ahead, g = corridor_at(egeo[0], p_s0, p_ds, n_p, s, q, px, py, pyaw, Lr, Wr,
                                       half_diag_r, Le, halfw, rng)  # fmt: skip
                if ahead:
                    gap = g
            d_safe = safe_distance(v, tsafe, d_buf, a_min)
            new, release = cap_transition(cap, v, vd, ahead, gap, d_safe, rel_m, rectol)
            braking = new == core.BRAKE
            if paperlaw:
                a = paper_braking(v, d_safe, d_buf, a_min)
            else:
                a = gap_braking(v, gap if ahead else 1e9, d_buf, a_min)
            a_brake = a if braking else 0.0
            if not collided:
                cap = new
            if release:
                pid_i = 0.0
                pid_e = err
        u, pid_i = pid_core(err, pid_i, pid_e, dt, decay, lim, kp, ki, kd)
        pid_e = err
        if braking:
            u = accel_to_command(a_brake, amax, dmax)
        a_cmd = command_to_accel(u, amax, dmax)
        a_act_n = actuator(a_act, a_cmd, alpha)
        v_new = speed(v, a_act_n, dt)
        s_new = s + v_new * dt
        a_rep_n = reported_accel(v, v_new, a_act_n, dt)
    if collided:
        s_new = s
        v_new = 0.0
        a_act_n = 0.0
        a_rep_n = 0.0
        u = 0.0
    return s_new, v_new, a_act_n, a_rep_n, u, pid_i, pid_e, cap
