"""The vector env's reacting cars (``traffic.cars_react``), compiled (numba).

:func:`step_cars` advances every environment's reacting cars by one step after
:func:`vei.gym.kernel.step_envs` (and :func:`vei.gym.riders_kernel.step_riders`) moved its
ego and riders, with the engine kernel's own laws, in the order of
:mod:`vei.sim.kernel.loop`: the cars' step (:func:`vei.sim.kernel.traffic.traffic_step`:
IDM cars that notice a deviation from their recorded leader, fed with the ego's arc length
and speed of step k from ``PREV``), the ego's contact test with the cars at their new
poses (step_envs tests the other road users; the caller blanks the cars' columns of the
presence it gives step_envs), then the contacts of :mod:`vei.sim.kernel.contacts` (the
ego's new contacts, the extra riders', the rider's with the others, a driven car's with any
other: the secondary-collision summaries, and a touched car stops). Scenario by scenario,
so that each scenario's tables are bound once, without numba's reference counting
(``_nrt=False``, as vei.gym.riders_kernel: it allocates nothing).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math

import numba

from vei.gym.kernel import B_ACT, F_RX, F_RY, F_RYAW, F_X, F_Y, F_YAW
from vei.models import traffic_core as core
from vei.sim.kernel.contacts import car_contacts, ego_contacts, extra_contacts, rider_contacts
from vei.sim.kernel.scalar import sat
from vei.sim.kernel.traffic import traffic_step


@numba.njit(cache=True, nogil=True, _nrt=False)
def step_cars(  # type: ignore[no-untyped-def]
    run, dt, K, SC, PREV, FS, BS, HIT0, HIT, DIM, P,
    OX, OY, OYAW, OSP, OACT, OL, OW, n_o, ct, cs, xk, scr, TERMS,
):  # fmt: skip
    """Advance the reacting cars of the environments with ``run[b]`` from step K[b] - 1 to
    K[b] (step_envs has advanced K), in place, adding the ego's new contacts with them to
    TERMS[b, 0]; the contact latches and secondary summaries of every environment, also
    in a world's scenarios without cars (the NumPy step keeps them wherever the world has
    reacting cars).

    Args: dt [s]; K, SC [B]; PREV [N_PREV, B] (vei.gym.kernel: the ego's and the rider's
    step-k state); FS [15, B], BS [5, B] the state at k + 1; HIT0, HIT [B, O] uint8 the
    ego's contacts with the others before and after step_envs; DIM [S, 4] [m]; P
    [N_PARAMS, S]; the others' OX, OY, OYAW [S, T, O], OSP [S, T, O] [m/s], OACT [S, T, O]
    (all present, the cars too), OL, OW [S, O] [m], n_o [S]; ct: vei.gym.cars.CarTables
    .group(); cs: the cars' state [B, ...] in vei.gym.cars.CAR_STATE_ORDER; xk: None or
    (XS [B, 9, R], XB [B, 4, R] the extra riders at k + 1, XV [B, 2, R] their speed [m/s]
    and yaw [rad] at k, XH0 [B, R] their contact latches at k); scr: scratch (F [6, C]
    floats, CM [C] ints, SEC [6]).
    """
    (
        c_n, tidx, tL, tW, tci, ptab, ps0, pds, pn, srec, vrec, arec, tact, esrec, evrec,
        mtab, m0, mn, pair, veh,
    ) = ct  # fmt: skip
    (
        CS, CV, CTM, CX, CY, CYAW, CMODE, CHIT, CHW, RHIT, SN, SF, SSTR, SSTK, SMAX, SREAR,
    ) = cs  # fmt: skip
    F, CM, sec = scr
    B = run.shape[0]
    for sc in range(c_n.shape[0]):  # a scenario without cars: its contacts all the same
        C = c_n[sc]
        no = n_o[sc]
        Le, We, Lr, Wr = DIM[sc, 0], DIM[sc, 1], DIM[sc, 2], DIM[sc, 3]
        tg = (C, tL[sc, :C], tW[sc, :C], mtab[sc], m0[sc], mn[sc], pair[sc])
        trec = (srec[sc], vrec[sc], arec[sc], tact[sc], esrec[sc], evrec[sc],
                OX[sc], OY[sc], OYAW[sc], tidx[sc, :C])  # fmt: skip
        tpath = (ptab[sc], ps0[sc], pds[sc], pn[sc])
        others = (OX[sc], OY[sc], OYAW[sc], OSP[sc], OACT[sc, :, :no], OL[sc, :no],
                  OW[sc, :no], veh[sc, :no])  # fmt: skip
        ci = tci[sc, :no]
        cv0, cyaw0, cm0 = F[0, :C], F[1, :C], CM[:C]
        for b in range(B):
            if not run[b] or SC[b] != sc:
                continue
            k = K[b] - 1
            t_new = (k + 1) * dt
            cmode = CMODE[b, :C]
            cx, cy, cyaw = CX[b, :C], CY[b, :C], CYAW[b, :C]
            for j in range(C):  # the cars' speed, yaw and mode at step k (contacts)
                cv0[j], cyaw0[j], cm0[j] = CV[b, j], CYAW[b, j], cmode[j]
            cst = (CS[b, :C], CV[b, :C], CTM[b, :C], cx, cy, cyaw, cmode,
                   F[2, :C], F[3, :C], F[4, :C], F[5, :C])  # fmt: skip
            if C > 0:  # (traffic_step reads kn = k + 1 <= T_n - 1 of the padded tables:
                # an environment at its scenario's last step is truncated, never stepped)
                traffic_step(k, dt, P, sc, True, tg, trec, tpath, cst, PREV[4, b], PREV[3, b], We)
            # the ego's contacts with the cars at their new poses (vei.sim.kernel.loop)
            ex, ey, eyaw = FS[F_X, b], FS[F_Y, b], FS[F_YAW, b]
            h1 = HIT[b, :no]
            for j in range(C):
                oj = tidx[sc, j]
                if OACT[sc, k + 1, oj] and h1[oj] == 0:
                    rr = 0.5 * (math.hypot(Le, We) + math.hypot(OL[sc, oj], OW[sc, oj]))
                    ddx, ddy = cx[j] - ex, cy[j] - ey
                    if ddx * ddx + ddy * ddy <= rr * rr:
                        if sat(ex, ey, eyaw, Le, We, cx[j], cy[j], cyaw[j], OL[sc, oj], OW[sc, oj]):
                            h1[oj] = 1
                            TERMS[b, 0] += 1.0
            # contacts of any two road users (vei.sim.contacts.contact_step's order)
            sec[0], sec[1], sec[2] = SN[b], SF[b], SSTR[b]
            sec[3], sec[4], sec[5] = SSTK[b], SMAX[b], 1.0 if SREAR[b] else 0.0
            cars = ((ci, cx, cy, cyaw), (ci, cv0, cyaw0, cm0), C)
            ego_now = (ex, ey, eyaw, PREV[3, b], PREV[2, b])
            ego_contacts(k + 1, t_new, others, HIT0[b, :no], h1, cars, ego_now, sec, Le)
            if xk is not None:
                XS, XB, XV, XH0 = xk
                R = XB.shape[2]
                extra_contacts(t_new, ego_now, XS[b], (XV[b, 0], XV[b, 1]), XH0[b],
                               XB[b, 3, :R], sec, no)  # fmt: skip
            rsp, ryaw = PREV[8, b], PREV[9, b]
            rider_now = (FS[F_RX, b], FS[F_RY, b], FS[F_RYAW, b], rsp * math.cos(ryaw),
                         rsp * math.sin(ryaw), BS[B_ACT, b] > 0)  # fmt: skip
            rhit = RHIT[b, :no]
            rider_contacts(k + 1, t_new, others, rhit, cars, rider_now, sec, Lr, Wr)
            carg = (cmode, CHIT[b, :C], CHW[b, :C], tidx[sc, :C], tL[sc, :C], tW[sc, :C])
            car_contacts(k + 1, t_new, others, h1, rhit, cars, carg, sec)
            for j in range(C):  # a car stopped by a contact stands
                if cmode[j] == core.STOPPED:
                    CV[b, j] = 0.0
            SN[b], SF[b], SSTR[b] = int(sec[0]), sec[1], int(sec[2])
            SSTK[b], SMAX[b], SREAR[b] = int(sec[3]), sec[4], sec[5] > 0.5


__all__ = ["step_cars"]
