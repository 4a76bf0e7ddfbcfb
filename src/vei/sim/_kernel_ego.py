"""The ego's longitudinal step in the compiled kernel: replayed speed, or PID cruise + CAP.

Imported only when numba is used. The same formulas and order of operations as
:func:`vei.models.ego` / :func:`vei.models.cap` in the NumPy reference step
(:func:`vei.sim.step.step`), for one variant; inlined into the kernel's loop
(``inline="always"``: no call per variant and step). SI units (m, s, m/s, m/s^2).
"""

# ruff: noqa: N803
from __future__ import annotations

import math

import numba
import numpy as np

from vei.sim._kernel_scalar import idx
from vei.sim.kernel_layout import (
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


@numba.njit(cache=True, inline="always")
def ego_consts(P, b, dt, Lr, Wr):  # type: ignore[no-untyped-def]
    """The ego's per-variant constants, read and derived once per variant (not per step).

    Args: P [N_PARAMS, B] the packed parameters, b the variant, dt [s] the step, Lr x Wr
    [m] the rider's footprint. Returns the tuple that :func:`ego_step_c` takes: the
    parameters of P it reads and the values derived from them alone (the PID integral's
    decay factor, its clamp, the actuator's lag factor, 2 |a_min|, half the rider's
    diagonal), each computed by the expression the step used to evaluate every step.
    """
    ki = P[P_KI, b]
    tau = P[P_LAG, b]
    a_min = P[P_AMIN, b]
    return (
        P[P_AMAX, b], P[P_DMAX, b], P[P_HALFW, b], P[P_RANGE, b], a_min, P[P_DBUF, b],
        P[P_TSAFE, b], P[P_RELEASE, b], P[P_RECTOL, b], P[P_PAPERLAW, b] > 0.5,
        math.exp(-dt / P[P_IWIN, b]), ki, P[P_ILIM, b] / (ki if ki > 0 else 1.0),
        P[P_KP, b], P[P_KD, b], -math.expm1(-dt / tau) if tau > 0 else 1.0,
        2.0 * abs(a_min), 0.5 * math.hypot(Lr, Wr),
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
        decay, ki, lim, kp, kd, alpha, two_abs_amin, half_diag_r,
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
        den = amax if a_act_n >= 0.0 else dmax
        u = min(1.0, max(-1.0, a_act_n / den))
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
                i, w = idx(p_s0, p_ds, n_p, s)
                qx = egeo[0][0, i] + w * egeo[0][5, i]
                qy = egeo[0][1, i] + w * egeo[0][6, i]
                qc = egeo[0][3, i] + w * egeo[0][8, i]
                qs = egeo[0][4, i] + w * egeo[0][9, i]
                s_q = s + (px - qx) * qc + (py - qy) * qs
                i, w = idx(p_s0, p_ds, n_p, s_q)
                fx_ = egeo[0][0, i] + w * egeo[0][5, i]
                fy_ = egeo[0][1, i] + w * egeo[0][6, i]
                pc = egeo[0][3, i] + w * egeo[0][8, i]
                ps = egeo[0][4, i] + w * egeo[0][9, i]
                ddx, ddy = px - fx_, py - fy_
                s_q = s_q + ddx * pc + ddy * ps
                lat = ddy * pc - ddx * ps
                d_front = s_q - s - 0.5 * Le
                if abs(lat) <= halfw and d_front + half_diag_r > 0.0:
                    cr, sr = math.cos(pyaw), math.sin(pyaw)
                    ext = 0.5 * Lr * abs(cr * pc + sr * ps) + 0.5 * Wr * abs(sr * pc - cr * ps)
                    g = d_front - ext
                    if d_front + ext > 0.0 and g <= rng:
                        ahead = True
                        gap = max(g, 0.0)
            d_safe = max(v * v / two_abs_amin, tsafe * v) + d_buf
            trigger = ahead and gap < d_safe
            release = cap == 1 and (not trigger) and ((not ahead) or gap > d_safe + rel_m)
            recovered = cap == 2 and abs(v - vd) <= rectol
            new = cap
            if trigger:
                new = 1
            elif release:
                new = 2
            elif recovered:
                new = 0
            braking = new == 1
            if paperlaw:
                room = d_safe - d_buf
                a = max(-v * v / (2.0 * room), a_min) if room > 0 else 0.0
            else:
                gg = gap if ahead else 1e9
                room = gg - d_buf
                if room > 0:
                    a = max(-v * v / (2.0 * room), a_min)
                else:
                    a = a_min if v > 0 else 0.0
            a_brake = a if braking else 0.0
            if not collided:
                cap = new
            if release:
                pid_i = 0.0
                pid_e = err
        pid_i = pid_i * decay + err * dt
        pid_i = min(max(pid_i, -lim), lim)
        deriv = (err - pid_e) / dt
        u = min(1.0, max(-1.0, kp * err + ki * pid_i + kd * deriv))
        pid_e = err
        if braking:
            den = amax if a_brake >= 0.0 else dmax
            u = min(1.0, max(-1.0, a_brake / den))
        a_cmd = u * (amax if u >= 0.0 else dmax)
        a_act_n = a_act + alpha * (a_cmd - a_act)
        v_new = max(0.0, v + a_act_n * dt)
        s_new = s + v_new * dt
        if v_new <= 0.0 and a_act_n < 0.0:
            a_rep_n = (v_new - v) / dt
        else:
            a_rep_n = a_act_n
    if collided:
        s_new = s
        v_new = 0.0
        a_act_n = 0.0
        a_rep_n = 0.0
        u = 0.0
    return s_new, v_new, a_act_n, a_rep_n, u, pid_i, pid_e, cap
