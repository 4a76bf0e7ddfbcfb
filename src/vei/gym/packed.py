"""The vector env's scenario tables as padded arrays for its compiled step (vei.gym.kernel).

:class:`Packed` stacks every scenario of a :class:`vei.gym.world.World` along a first axis
S (padded to the longest), and :class:`ExtraRiders` the extra social-force riders of the
several-rider mode (``sim.sfm_riders``, vei.sim.riders) the same way: R_max riders per
scenario, the engine kernel's own tables (:func:`vei.sim.kernel.pack.riders_group`,
:func:`vei.sim.kernel.pack.decisions_group`) stacked.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vei.errors import ConfigError
from vei.gym.world import World
from vei.policy.observation import category_code


def _pad(arrs: list[np.ndarray], axis: int) -> np.ndarray:
    """Stack arrays along a new first axis, padding ``axis`` with the last value."""
    n = max(a.shape[axis] for a in arrs)
    out = []
    for a in arrs:
        pad = [(0, 0)] * a.ndim
        pad[axis] = (0, n - a.shape[axis])
        out.append(np.pad(a, pad, mode="edge") if a.shape[axis] else np.zeros_like(a, shape=[
            n if d == axis else s for d, s in enumerate(a.shape)]))  # fmt: skip
    return np.ascontiguousarray(np.stack(out))


class Packed:
    """The world's scenario tables as padded arrays for the compiled step (vei.gym.kernel)."""

    def __init__(self, world: World) -> None:
        from vei.models import ego_core
        from vei.sim.kernel.layout import PARAM_FIELDS
        from vei.sim.kernel.pack import path_rows, table_rows

        f = np.float64
        ws = world.scenarios
        arrs = [w.arrays for w in ws]
        self.dt = float(arrs[0].dt_s)
        if any(abs(a.dt_s - self.dt) > 0 for a in arrs):
            raise ConfigError("the scenarios of an environment must share the engine step")
        self.P = np.ascontiguousarray(
            np.stack(
                [
                    np.array([float(np.asarray(getattr(w.params, p))[0]) for w in ws])
                    for p in PARAM_FIELDS
                ]
            )
        )
        self.ALPHA = np.array(
            [
                float(ego_core.lag_factor(np.float64(w.params.actuator_lag_s[0]), self.dt))
                for w in ws
            ]
        )
        self.DIM = np.array(
            [[a.ego_length_m, a.ego_width_m, a.rider_length_m, a.rider_width_m] for a in arrs], f
        )
        self.EP = _pad([path_rows(a.ego_path) for a in arrs], 1)
        self.ep_s0 = np.array([a.ego_path.s_start_m for a in arrs], f)
        self.ep_ds = np.array([a.ego_path.ds_m for a in arrs], f)
        self.ep_n = np.array([a.ego_path.x_m.shape[0] for a in arrs], np.int64)
        cols = ("x_m", "y_m", "yaw_rad", "speed_mps", "vx_mps", "vy_mps", "arc_m")
        self.RT = _pad([table_rows(a.rider_track, cols) for a in arrs], 1)
        self.rt_t0 = np.array([a.rider_track.t0_s for a in arrs], f)
        self.rt_dt = np.array([a.rider_track.dt_s for a in arrs], f)
        self.rt_tend = np.array([a.rider_track.t_end_s for a in arrs], f)
        self.rt_n = np.array([a.rider_track.data.shape[0] for a in arrs], np.int64)
        # recording time from which an SFM rider is driven (vei.sim.riders.sfm_entry_s)
        self.rt_sfm0 = np.array([a.rider_sfm_entry_s for a in arrs], f)
        self.RP = _pad([path_rows(a.rider_path) for a in arrs], 1)
        rp = [a.rider_path for a in arrs]
        self.rp_s0 = np.array([p.s_start_m for p in rp], f)
        self.rp_ds = np.array([p.ds_m for p in rp], f)
        self.rp_n = np.array([p.x_m.shape[0] for p in rp], np.int64)
        self.rp_len = np.array([p.length_m for p in rp], f)
        self.rp_ex = np.array([p.end_x_m for p in rp], f)
        self.rp_ey = np.array([p.end_y_m for p in rp], f)
        self.T_n = np.array([a.n_steps for a in arrs], np.int64)
        self.path_end = np.array(
            [float(a.ego_track.data[-1, a.ego_track.col("s_m")]) for a in arrs], f
        )
        self.cat_r = np.array([category_code(a.rider_category) for a in arrs], f)
        no = max(1, world.max_others)
        tmax = int(self.T_n.max())

        def others(name: str, dtype: Any) -> np.ndarray:
            out = np.zeros((len(arrs), tmax, no), dtype=dtype)
            for s, a in enumerate(arrs):
                v = getattr(a, name)
                out[s, : v.shape[0], : v.shape[1]] = v
            return out

        self.OX, self.OY = others("other_x_m", f), others("other_y_m", f)
        self.OYAW, self.OSP = others("other_yaw_rad", f), others("other_speed_mps", f)
        self.OACT = others("other_active", np.bool_)
        self.OL = np.zeros((len(arrs), no))
        self.OW = np.zeros((len(arrs), no))
        self.OCAT = np.zeros((len(arrs), no))
        for s, a in enumerate(arrs):
            n = len(a.other_ids)
            self.OL[s, :n], self.OW[s, :n] = a.other_length_m, a.other_width_m
            self.OCAT[s, :n] = [category_code(c) for c in a.other_categories]
        self.n_o = np.array([len(a.other_ids) for a in arrs], np.int64)
        # the primary rider's conflicts with the ego path (its yield / go decision)
        kc = max([a.conflicts.n for a in arrs] + [1])
        self.CF = np.zeros((len(arrs), 5, kc))
        for s, a in enumerate(arrs):
            c = a.conflicts
            for r, v in enumerate((c.exit_m, c.s_rider_m, c.s_ego_m, c.hz_rider_m, c.hz_ego_m)):
                self.CF[s, r, : c.n] = v
        self.cf_n = np.array([a.conflicts.n for a in arrs], np.int64)
        # the extra social-force riders (sim.sfm_riders), None when no scenario has one
        xr = ExtraRiders(world, self.P)
        self.xr: ExtraRiders | None = xr if xr.n.max() > 0 else None
        roads = [w.road for w in ws]
        self.road_on = all(r is not None for r in roads)
        if self.road_on:
            self.ROAD = _pad([r.on for r in roads], 0) if len(roads) == 1 else self._roads(roads)
            self.rd_x0 = np.array([r.x0_m for r in roads], f)
            self.rd_y0 = np.array([r.y0_m for r in roads], f)
            self.rd_cell = np.array([r.cell_m for r in roads], f)
            self.rd_nx = np.array([r.on.shape[1] for r in roads], np.int64)
            self.rd_ny = np.array([r.on.shape[0] for r in roads], np.int64)
        else:
            self.ROAD = np.zeros((len(arrs), 1, 1), np.uint8)
            self.rd_x0 = self.rd_y0 = np.zeros(len(arrs))
            self.rd_cell = np.ones(len(arrs))
            self.rd_nx = self.rd_ny = np.zeros(len(arrs), np.int64)

    @staticmethod
    def _roads(roads: list[Any]) -> np.ndarray:
        ny = max(r.on.shape[0] for r in roads)
        nx = max(r.on.shape[1] for r in roads)
        out = np.zeros((len(roads), ny, nx), np.uint8)
        for s, r in enumerate(roads):
            out[s, : r.on.shape[0], : r.on.shape[1]] = r.on
        return out


class ExtraRiders:
    """The extra riders of every scenario, padded to R_max riders (R_max >= 1).

    Args: world; P [N_PARAMS, S] the scenarios' kernel parameters (:attr:`Packed.P`).

    Attributes (S scenarios): n [S] riders per scenario; tables as
    :func:`vei.sim.kernel.pack.riders_group` with a leading S axis: XTAB [S, R, 14, M],
    xt0, xdt, xtend [S, R] [s], xnr [S, R], xsfm0 [S, R] [s], XPATH [S, R, 10, N], xps0,
    xpds [S, R] [m], xpn [S, R], xplen, xpex, xpey [S, R] [m], xL, xW, xrad [S, R] [m];
    xv0, xvmax [S, R] desired and maximum speeds [m/s] (vei.sim.kernel.riders.riders_state0
    of the scenario's parameters); prad [S] the primary's radius [m]; rep_on [S] the
    rider-rider repulsion; PED [S, Pm] the pedestrians among the others, PRAD [S, Pm]
    their radii [m], n_ped [S]; XCAT [S, R] category codes; decisions: XDN [S, R] conflicts
    per rider, XDC [S, 5, R, Kc] (exit, s_rider, s_ego, hz_rider, hz_ego) [m].
    """

    def __init__(self, world: World, P: np.ndarray) -> None:  # noqa: N803
        from vei.sim.kernel.pack import decisions_group, riders_group
        from vei.sim.kernel.riders import riders_state0
        from vei.sim.step import initial_state

        ws = world.scenarios
        s_n = len(ws)
        groups, decs = [], []
        for w in ws:
            st = initial_state(w.arrays, w.params)
            groups.append(riders_group(w.arrays, st, 1, 1, False))
            decs.append(decisions_group(w.arrays))
        self.n = np.array([g[0] for g in groups], np.int64)
        r = max(1, int(self.n.max()))
        m = max(g[1].shape[2] for g in groups)
        npth = max(g[7].shape[2] for g in groups)
        f = np.float64
        self.XTAB = np.zeros((s_n, r, 14, m))
        self.XPATH = np.zeros((s_n, r, 10, npth))
        per = {name: np.zeros((s_n, r)) for name in (
            "xt0", "xdt", "xtend", "xsfm0", "xps0", "xpds", "xplen", "xpex", "xpey", "xL", "xW",
            "xrad", "xv0", "xvmax", "XCAT")}  # fmt: skip
        self.xnr = np.ones((s_n, r), np.int64)
        self.xpn = np.ones((s_n, r), np.int64)
        self.prad = np.zeros(s_n)
        self.rep_on = np.zeros(s_n, np.bool_)
        pm = max([len(g[21]) for g in groups] + [1])
        self.PED = np.zeros((s_n, pm), np.int64)
        self.PRAD = np.zeros((s_n, pm))
        self.n_ped = np.array([len(g[21]) for g in groups], np.int64)
        kc = max([d[7].shape[1] for d in decs] + [1])
        self.XDN = np.zeros((s_n, r), np.int64)
        self.XDC = np.zeros((s_n, 5, r, kc))
        for s, (g, d, w) in enumerate(zip(groups, decs, ws, strict=True)):
            n = g[0]
            self.prad[s], self.rep_on[s] = g[19], g[20]
            self.PED[s, : self.n_ped[s]], self.PRAD[s, : self.n_ped[s]] = g[21], g[22]
            if n == 0:
                continue
            self.XTAB[s, :n, :, : g[1].shape[2]] = g[1]
            self.XPATH[s, :n, :, : g[7].shape[2]] = g[7]
            for name, col in (("xt0", 2), ("xdt", 3), ("xtend", 4), ("xsfm0", 6), ("xps0", 8),
                              ("xpds", 9), ("xplen", 11), ("xpex", 12), ("xpey", 13),
                              ("xL", 14), ("xW", 15), ("xrad", 16)):  # fmt: skip
                per[name][s, :n] = g[col]
            self.xnr[s, :n], self.xpn[s, :n] = g[5], g[10]
            p1 = np.ascontiguousarray(P[:, s : s + 1])
            _, _, _, _, v0, vmax = riders_state0.py_func(0, p1, n, g[23], g[24], g[17], g[18])
            per["xv0"][s, :n], per["xvmax"][s, :n] = v0, vmax
            per["XCAT"][s, :n] = [category_code(c) for c in w.arrays.riders.categories]
            self.XDN[s, :n] = d[6]
            for q in range(5):
                self.XDC[s, q, :n, : d[7 + q].shape[1]] = d[7 + q]
        for s, n in enumerate(self.n):  # padding riders: never in their span, never active
            per["xt0"][s, n:], per["xtend"][s, n:] = np.inf, -np.inf
            per["xdt"][s, n:] = per["xpds"][s, n:] = 1.0
        for name, arr in per.items():
            setattr(self, name, np.ascontiguousarray(arr, f))
        self.r_max = r

    def group(self) -> tuple[Any, ...]:
        """The tables in vei.gym.kernel.step_envs' ``xr`` order."""
        return (
            self.n, self.XTAB, self.xt0, self.xdt, self.xtend, self.xnr, self.xsfm0,
            self.XPATH, self.xps0, self.xpds, self.xpn, self.xplen, self.xpex, self.xpey,
            self.xL, self.xW, self.xrad, self.xv0, self.xvmax, self.prad, self.rep_on,
            self.PED, self.PRAD, self.n_ped, self.XDN, self.XDC,
        )  # fmt: skip


__all__ = ["ExtraRiders", "Packed"]
