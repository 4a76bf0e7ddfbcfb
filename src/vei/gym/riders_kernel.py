"""The vector env's extra social-force riders (``sim.sfm_riders``), compiled (numba).

:func:`step_riders` advances every environment's extra riders by one step right after
:func:`vei.gym.kernel.step_envs` moved its ego and primary rider: the riders' laws are the
engine kernel's own :func:`vei.sim.kernel.riders.extra_riders_step` (replayed, or the
social force along their paths with ego repulsion, obstacle braking, their own yield / go
decisions, and the repulsion of each other, of the primary rider and by pedestrians),
fed with the ego's and the primary rider's state of step k (``PREV``, which step_envs
keeps) and the ego's pose at k + 1 (their contact latch), as in
:mod:`vei.sim.kernel.loop`. A separate loop, scenario by scenario, so that each
scenario's tables are bound once, compiled without numba's reference counting
(``_nrt=False``: it allocates nothing, and every array it touches is owned by the caller;
numba refuses to compile an allocation there): the ~40 views and tuple members the
inlined engine step binds per environment cost an atomic reference count each, 5x the
riders' own step (3 replayed riders at B = 10^4: 6.4 ms a step with counting, 1.1 ms
without).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numba

from vei.sim.kernel.layout import P_ARR, P_BRR, P_SFM, P_USERF
from vei.sim.kernel.riders import extra_riders_step


@numba.njit(cache=True, nogil=True, _nrt=False)
def step_riders(run, dt, K, SC, PREV, EGO_N, DIM, P, OX, OY, OYAW, OACT, xr, TERMS):  # type: ignore[no-untyped-def]
    """Advance the extra riders of the environments with ``run[b]`` from step K[b] - 1 to
    K[b] (step_envs has advanced K), in place (xr's XS [B, 9, R], XB [B, 4, R]), adding
    their new ego contacts to TERMS[b, 0].

    Args: dt [s]; SC [B] scenario indices; PREV [N_PREV, B] (vei.gym.kernel.N_PREV: the
    ego's and the primary rider's state at step k); EGO_N the float state FS [15, B] of
    vei.gym.kernel at k + 1 (rows 1-3: the ego's x, y, yaw); DIM [S, 4]
    (ego length, width, ...) [m]; P [N_PARAMS, S]; the others' OX, OY, OYAW [S, T, O],
    OACT [S, T, O] (the pedestrians' repulsion); xr: vei.gym.packed.ExtraRiders.group()
    then XS, XB and their scratch NXS [9, R], NXB [4, R].
    """
    (
        x_n, XTAB, xt0, xdt, xtend, xnr, xsfm0, XPATH, xps0, xpds, xpn, xplen, xpex, xpey,
        xL, xW, xrad, xv0, xvmax, prad, rep_on, PED, PRAD, n_ped, XDN, XDC, XS, XB, NXS, NXB,
    ) = xr  # fmt: skip
    B = run.shape[0]
    for sc in range(x_n.shape[0]):
        R = x_n[sc]
        if R == 0:
            continue
        xtrk = (XTAB[sc], xt0[sc], xdt[sc], xtend[sc], xnr[sc], xsfm0[sc])
        xpth = (XPATH[sc], xps0[sc], xpds[sc], xpn[sc], xplen[sc], xpex[sc], xpey[sc])
        xgeo = (xL[sc], xW[sc], xrad[sc])
        oth = (OX[sc], OY[sc], OYAW[sc], OYAW[sc], OACT[sc])  # [3] (the speeds) unread
        dec = (0, 0, 0, 0, 0, 0, XDN[sc], XDC[sc, 0], XDC[sc, 1], XDC[sc, 2], XDC[sc, 3], XDC[sc, 4])  # fmt: skip
        peds, prads = PED[sc, : n_ped[sc]], PRAD[sc, : n_ped[sc]]
        v0s, vmaxs = xv0[sc], xvmax[sc]
        sfm = P[P_SFM, sc] > 0.5
        use_rf = rep_on[sc] and P[P_USERF, sc] > 0.5
        a_rr, b_rr = P[P_ARR, sc], P[P_BRR, sc]
        Le, We, pr = DIM[sc, 0], DIM[sc, 1], prad[sc]
        for b in range(B):
            if not run[b] or SC[b] != sc:
                continue
            k = K[b] - 1
            h0 = 0
            for j in range(R):
                h0 += 1 if XB[b, 3, j] else 0
            # all R_max columns: a scenario's padding riders never enter their span
            extra_riders_step(
                k, (k + 1) * dt, dt, P, sc, sfm, use_rf, a_rr, b_rr,
                (XS[b], XB[b], NXS, NXB, v0s, vmaxs), xtrk, xpth, xgeo,
                PREV[5, b], PREV[6, b], PREV[7, b] > 0.5, pr, oth, peds, prads,
                (PREV[0, b], PREV[1, b], PREV[2, b], PREV[3, b], PREV[4, b]), Le, We,
                (EGO_N[1, b], EGO_N[2, b], EGO_N[3, b]), dec,
            )  # fmt: skip
            h1 = 0
            for j in range(R):
                h1 += 1 if XB[b, 3, j] else 0
            TERMS[b, 0] += h1 - h0


__all__ = ["step_riders"]
