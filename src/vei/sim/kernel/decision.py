"""The rider's yield / go decision in the compiled kernel (vei.sim.decisions on scalars).

Imported only when numba is used. For one social-force rider of one variant: the conflict
it attends to (the first whose zone exit lies ahead of its progress), a fresh start (FREE)
when that conflict changed since the previous step, and the laws of
:mod:`vei.models.decision_core` compiled on scalars: the new decision state and the speed
cap of its desired velocity. Inlined into the kernel's loop (``inline="always"``). SI
units (m, s, m/s, m/s^2).
"""

# ruff: noqa: N803
from __future__ import annotations

import math

import numba

from vei.models import decision_core as core
from vei.sim.kernel.scalar import idx  # noqa: F401  (registers the cores' select on scalars)

_inline = numba.njit(cache=True, inline="always")
conflict_times = _inline(core.conflict_times_core)
decide = _inline(core.decide_core)
yield_speed = _inline(core.yield_speed_core)
capped_velocity = _inline(core.capped_velocity_core)
reference_speed = _inline(core.reference_speed_core)


@numba.njit(cache=True, inline="always")
def current_conflict(cexit, K, prog):  # type: ignore[no-untyped-def]
    """Index of the first conflict whose zone exit cexit[c] [m] is >= prog [m] (K: none;
    the same as numpy's searchsorted(cexit, prog, 'left'))."""
    c = 0
    while c < K and cexit[c] < prog:
        c += 1
    return c


@numba.njit(cache=True, inline="always")
def decide_step(  # type: ignore[no-untyped-def]
    state, prog_prev, prog, v_r, s_e, v_e, conf, t_c, horizon, a_yield, stop_m, clear_m,
    v_ref, tau,
):  # fmt: skip
    """One step of the decision (vei.sim.decisions.decision_step on scalars).

    Args: state (0 FREE, 1 GO, 2 YIELD) of the previous step; the rider's progress [m] at
    the previous step and now, its speed [m/s]; the ego's arc length [m] and speed [m/s];
    conf = (K, cexit, cs_r, cs_e, chz_r, chz_e) the conflicts ([K] arrays [m]); the
    rider's critical gap t_c [s], horizon [s], yield deceleration [m/s^2], stop and clear
    margins [m], speed floor v_ref [m/s] and relaxation time tau [s].
    Returns (new state, speed cap [m/s], +inf where none).
    """
    K, cexit, cs_r, cs_e, chz_r, chz_e = conf
    c_prev = current_conflict(cexit, K, prog_prev)
    c = current_conflict(cexit, K, prog)
    if c != c_prev:
        state = core.FREE
    if c >= K:
        return core.FREE, math.inf
    d_r, tta_r, dta, t_clear, live = conflict_times(
        prog, v_r, s_e, v_e, cs_r[c], cs_e[c], chz_r[c], chz_e[c], clear_m, v_ref
    )
    new = decide(state, live, dta, tta_r, d_r, t_c, horizon)
    cap = yield_speed(new, d_r, v_r, tta_r, t_clear, stop_m, a_yield, tau)
    return new, cap
