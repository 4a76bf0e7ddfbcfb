"""The vector env's reacting cars (``traffic.cars_react``): their state and tables.

Reacting cars (vei.sim.traffic: IDM cars that notice a deviation from their recorded
leader) are stepped by the engine's own NumPy step (:func:`vei.sim.step.step`) in the
vector env's backend 'numpy', and by the engine kernel's compiled car step in the backend
'numba' (:mod:`vei.gym.cars_kernel`, on the tables of :class:`CarTables`). Either way the
vector env keeps, per environment, their SimState fields (vei.sim.traffic.CAR_FLOAT_FIELDS,
car_mode) and the contact latches and secondary-collision summaries
(vei.sim.contacts.initial_contact_state), which decide when a touched car stops:
:func:`car_state_arrays`.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def reacting_cars(world: Any) -> bool:
    """True where the configuration's cars react (traffic.cars_react) and some scenario of
    the world (vei.gym.world.World) has a reacting car."""
    return bool(world.scenarios[0].params.cars_react[0]) and any(
        ws.arrays.traffic.n for ws in world.scenarios
    )


def car_state_arrays(world: Any, b: int) -> dict[str, np.ndarray]:
    """Per-environment arrays of the reacting cars' and contact latches' SimState fields:
    name -> [b, ...] with each trailing axis padded to the largest scenario's (C cars or
    n_o others; the padded columns are never read), dtype of the engine's field."""
    from vei.sim.contacts import initial_contact_state
    from vei.sim.traffic import initial_traffic_state

    shapes: dict[str, tuple[tuple[int, ...], np.dtype]] = {}
    for ws in world.scenarios:
        a = ws.arrays
        f0 = {
            **initial_traffic_state(a, 1),
            **initial_contact_state(1, len(a.other_ids), a.traffic.n),
        }
        for name, v in f0.items():
            old = shapes.get(name, (v.shape[1:], v.dtype))[0]
            shapes[name] = (
                tuple(max(x, y) for x, y in zip(old, v.shape[1:], strict=True)),
                v.dtype,
            )
    return {name: np.zeros((b, *sh), dt) for name, (sh, dt) in shapes.items()}


class CarTables:
    """Every scenario's reacting cars (vei.sim.traffic.Traffic) padded to C_max >= 1 cars.

    Args: world (vei.gym.world.World); no: the others' padded width (vei.gym.packed.Packed);
    tt: the longest scenario's engine steps.

    Attributes (S scenarios): n [S] cars per scenario; tidx [S, C] their indices among the
    others; tL, tW [S, C] [m]; tci [S, no] each other's car index (-1: not a car); ptab
    [S, C, 10, N] path rows, ps0, pds [S, C] [m], pn [S, C]; srec, vrec, arec [S, T, C]
    recorded arc [m], speed [m/s], acceleration [m/s^2]; tact [S, T, C]; esrec, evrec [S, T]
    the recorded ego's arc [m] and speed [m/s]; leader maps mtab [S, C + 1, C, 4, M], m0
    [S, C + 1] [m], mn [S, C + 1], pair [S, C + 1, C]; veh [S, no] the others that are
    vehicles (a rear-end contact). Padding: never-active cars with one-entry tables.
    """

    def __init__(self, world: Any, no: int, tt: int) -> None:
        trs = [ws.arrays.traffic for ws in world.scenarios]
        s_n = len(trs)
        self.n = np.array([t.n for t in trs], np.int64)
        c = max(1, int(self.n.max()))
        npth = max(t.ptab.shape[2] for t in trs)
        m = max(t.mtab.shape[3] for t in trs)
        self.tidx = np.zeros((s_n, c), np.int64)
        self.tL, self.tW = np.zeros((s_n, c)), np.zeros((s_n, c))
        self.tci = np.full((s_n, no), -1, np.int64)
        self.ptab = np.zeros((s_n, c, 10, npth))
        self.ps0, self.pds = np.zeros((s_n, c)), np.ones((s_n, c))
        self.pn = np.ones((s_n, c), np.int64)
        self.srec, self.vrec, self.arec = (np.zeros((s_n, tt, c)) for _ in range(3))
        self.tact = np.zeros((s_n, tt, c), np.bool_)
        self.esrec, self.evrec = np.zeros((s_n, tt)), np.zeros((s_n, tt))
        self.mtab = np.zeros((s_n, c + 1, c, 4, m))
        self.m0 = np.zeros((s_n, c + 1))
        self.mn = np.ones((s_n, c + 1), np.int64)
        self.pair = np.zeros((s_n, c + 1, c), np.bool_)
        self.veh = np.zeros((s_n, no), np.bool_)
        for s, (ws, t) in enumerate(zip(world.scenarios, trs, strict=True)):
            a = ws.arrays
            self.veh[s, : len(a.other_ids)] = np.asarray(a.other_categories) == "vehicle"
            n = t.n
            if n == 0:
                continue
            self.tidx[s, :n], self.tL[s, :n], self.tW[s, :n] = t.idx, t.length_m, t.width_m
            self.tci[s, t.idx] = np.arange(n)
            self.ptab[s, :n, :, : t.ptab.shape[2]] = t.ptab
            self.ps0[s, :n], self.pds[s, :n], self.pn[s, :n] = t.ps0, t.pds, t.pn
            nt = t.s_rec_m.shape[0]
            for dst, src in ((self.srec, t.s_rec_m), (self.vrec, t.v_rec_mps),
                             (self.arec, t.a_rec_mps2), (self.tact, t.active)):  # fmt: skip
                dst[s, :nt, :n] = src
            self.esrec[s, :nt], self.evrec[s, :nt] = t.ego_s_rec_m, t.ego_v_rec_mps
            self.mtab[s, : n + 1, :n, :, : t.mtab.shape[3]] = t.mtab
            self.m0[s, : n + 1], self.mn[s, : n + 1] = t.m0, t.mn
            self.pair[s, : n + 1, :n] = t.pair

    def group(self) -> tuple[Any, ...]:
        """The tables in vei.gym.cars_kernel.step_cars' ``ct`` order."""
        return (
            self.n, self.tidx, self.tL, self.tW, self.tci, self.ptab, self.ps0, self.pds,
            self.pn, self.srec, self.vrec, self.arec, self.tact, self.esrec, self.evrec,
            self.mtab, self.m0, self.mn, self.pair, self.veh,
        )  # fmt: skip


#: The reacting cars' state of one environment in step_cars' ``cs`` order (names of
#: vei.gym.vector.VeiVectorEnv.CARS: SimState fields).
CAR_STATE_ORDER = (
    "car_s_m", "car_v_mps", "car_timer_s", "car_x_m", "car_y_m", "car_yaw_rad", "car_mode",
    "car_hit", "car_hit_with", "rider_hit_other", "sec_count", "sec_first_t_s", "sec_striker",
    "sec_struck", "sec_max_speed_mps", "rear_end",
)  # fmt: skip


__all__ = ["CAR_STATE_ORDER", "CarTables", "car_state_arrays", "reacting_cars"]
