"""Recorded pedestrians that walk by the social force (vei.models.pedestrian_core): their
tables (once per scenario) and their NumPy step.

:func:`prepare_pedestrians` takes every recorded pedestrian among the replayed others: its
path (through its recorded positions, a wait by its first point, extended 20 m), its
desired speed (its median recorded speed while walking, > 0.3 m/s; Weidmann's 1.34 m/s
for one that stands throughout), its recorded arc length at every engine step.
:func:`pedestrian_step` advances them for B variants where ``peds_sfm``: present while
its recording says so (its span, with its continuation); at its first present step it
starts from its recorded pose and velocity; then the driving term towards the point
``LOOKAHEAD_M`` ahead on its own path, the repulsion of the other pedestrians, of the ego
and every vehicle (closest point of their boxes) and of the primary rider (its disc),
capped, semi-implicit Euler. The compiled kernel does not run them: variants with
``peds_sfm`` run the NumPy step (:func:`vei.sim.engine.simulate`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.boxes import closest_point_on_box
from vei.models import pedestrian_core as core
from vei.models.drivable_path import dwell_mask, recorded_arc_length
from vei.models.ego import PathTable, build_path
from vei.sim.riders import repulsion

FloatArray = npt.NDArray[np.float64]
#: A pedestrian's goal lies this far ahead on its path [m].
LOOKAHEAD_M = 2.0
#: Weidmann's (1993) mean free walking speed [m/s], via Helbing & Molnar 1995: the
#: desired speed of a pedestrian whose recording never walks.
WALKING_SPEED_MPS = 1.34
#: SimState fields of the pedestrians ([B, P] floats).
PED_FIELDS = ("ped_x_m", "ped_y_m", "ped_vx_mps", "ped_vy_mps", "ped_prog_m")


@dataclass(frozen=True)
class Pedestrians:
    """The recorded pedestrians (P; P = 0: none).

    Attributes:
        idx: [P] their indices among the replayed others. paths: their PathTables.
        v0_mps: [P] desired speeds [m/s]. arc_m: [T, P] recorded arc length along the path
            at the engine steps [m].
    """

    idx: npt.NDArray[np.intp] = field(default_factory=lambda: np.zeros(0, dtype=np.intp))
    paths: tuple[PathTable, ...] = ()
    v0_mps: FloatArray = field(default_factory=lambda: np.zeros(0))
    arc_m: FloatArray = field(default_factory=lambda: np.zeros((1, 0)))

    @property
    def n(self) -> int:
        """P, the number of pedestrians."""
        return int(self.idx.shape[0])


def prepare_pedestrians(
    scenario: Any, others: list[Any], t_s: FloatArray, where: str
) -> Pedestrians:
    """The pedestrians among ``others`` (the replayed others' AgentInfo, engine order)."""
    idx, paths, v0s, arcs = [], [], [], []
    for j, a in enumerate(others):
        if a.category != "pedestrian":
            continue
        tr = scenario.track(a.agent_id)
        x = tr["x_m"].to_numpy(dtype=np.float64)
        y = tr["y_m"].to_numpy(dtype=np.float64)
        tt = tr["t_s"].to_numpy(dtype=np.float64)
        dwell = dwell_mask(x, y, tt, radius_m=0.5)
        keep = ~dwell | np.concatenate([[True], ~dwell[:-1]])
        path = build_path(
            x[keep], y[keep], yaw_hint_rad=float(tr["yaw_rad"].iloc[0]), extend_m=20.0,
            where=f"{where}: {a.agent_id}",
        )  # fmt: skip
        sp = tr["speed_mps"].to_numpy(dtype=np.float64)
        walking = sp[np.isfinite(sp) & (sp > 0.3)]
        idx.append(j)
        paths.append(path)
        v0s.append(float(np.median(walking)) if walking.size else WALKING_SPEED_MPS)
        arcs.append(np.interp(t_s, tt, recorded_arc_length(path, x, y)))
    if not idx:
        return Pedestrians()
    return Pedestrians(
        idx=np.asarray(idx, dtype=np.intp), paths=tuple(paths),
        v0_mps=np.asarray(v0s, dtype=np.float64), arc_m=np.column_stack(arcs),
    )  # fmt: skip


def initial_pedestrian_state(arrays: Any, b: int) -> dict[str, np.ndarray]:
    """The pedestrians' SimState fields at k = 0 ([B, P]): their recorded pose and velocity."""
    pd_ = arrays.peds
    out = {f: np.zeros((b, pd_.n)) for f in PED_FIELDS}
    if pd_.n:
        j = pd_.idx
        sp, yaw = arrays.other_speed_mps[0, j], arrays.other_yaw_rad[0, j]
        out["ped_x_m"][:] = arrays.other_x_m[0, j]
        out["ped_y_m"][:] = arrays.other_y_m[0, j]
        out["ped_vx_mps"][:] = sp * np.cos(yaw)
        out["ped_vy_mps"][:] = sp * np.sin(yaw)
        out["ped_prog_m"][:] = pd_.arc_m[0]
    return out


def pedestrian_step(
    st: Any, arrays: Any, p: Any, on: Any, dt: float, cars: dict[str, np.ndarray] | None
) -> dict[str, np.ndarray]:
    """Advance the pedestrians of one block by one step (forces from the state at step k).

    Args:
        st: SimState at step k. arrays: ScenarioArrays. p: the block's VariantParams
            (ped_* fields [b]). on: peds_sfm (True / mask [b]); elsewhere they replay.
        dt: step [s]. cars: the reacting cars' fields at step k where the block moves
            them (their poses), else None (their recording).
    Returns:
        The new PED_FIELDS ([b, P], fresh arrays).
    """
    pd_ = arrays.peds
    k = st.k
    kn = min(k + 1, arrays.n_steps - 1)
    out = {f: getattr(st, f).copy() for f in PED_FIELDS}
    b = st.ego_x_m.shape[0]
    n_o = arrays.other_x_m.shape[1]
    # every vehicle's box at step k (reacting cars where the engine moves them)
    vx_, vy_, vyaw = (np.broadcast_to(a[k], (b, n_o)).copy() for a in
                      (arrays.other_x_m, arrays.other_y_m, arrays.other_yaw_rad))  # fmt: skip
    tr = arrays.traffic
    if tr.n and cars is not None:
        vx_[:, tr.idx], vy_[:, tr.idx], vyaw[:, tr.idx] = (
            cars["car_x_m"], cars["car_y_m"], cars["car_yaw_rad"])  # fmt: skip
    vehicles = [j for j, c in enumerate(arrays.other_categories) if c == "vehicle"]
    lam, a_n, b_m, m = p.ped_lambda, p.ped_a_n, p.ped_b_m, p.ped_mass_kg
    r_i, b_v = p.ped_radius_m, p.ped_vehicle_range_m
    for i, j in enumerate(pd_.idx):
        present, was = bool(arrays.other_active[kn, j]), bool(arrays.other_active[k, j])
        if not present:
            continue
        if not was:  # it enters: its recorded pose and velocity
            sp, yaw = arrays.other_speed_mps[kn, j], arrays.other_yaw_rad[kn, j]
            out["ped_x_m"][:, i] = arrays.other_x_m[kn, j]
            out["ped_y_m"][:, i] = arrays.other_y_m[kn, j]
            out["ped_vx_mps"][:, i] = sp * np.cos(yaw)
            out["ped_vy_mps"][:, i] = sp * np.sin(yaw)
            out["ped_prog_m"][:, i] = pd_.arc_m[kn, i]
            continue
        x, y = st.ped_x_m[:, i], st.ped_y_m[:, i]
        vx, vy = st.ped_vx_mps[:, i], st.ped_vy_mps[:, i]
        path = pd_.paths[i]
        pi, pw = path.index(st.ped_prog_m[:, i])
        qx, qy, qc, qs = path.values_at(pi, pw, "x", "y", "cos", "sin")
        prog = np.maximum(st.ped_prog_m[:, i] + (x - qx) * qc + (y - qy) * qs, st.ped_prog_m[:, i])
        gx, gy = path.lookup(np.minimum(prog + LOOKAHEAD_M, path.length_m))[:2]
        ax, ay = core.drive_accel_core(x, y, gx, gy, vx, vy, pd_.v0_mps[i], p.ped_tau_s)
        for i2, j2 in enumerate(pd_.idx):  # the other pedestrians
            if i2 == i or not arrays.other_active[k, j2]:
                continue
            dx, dy = x - st.ped_x_m[:, i2], y - st.ped_y_m[:, i2]
            gap = np.sqrt(dx * dx + dy * dy) - 2.0 * r_i
            hx, hy = core.repulsion_accel_core(dx, dy, gap, a_n, b_m, m, vx, vy, lam)
            ax, ay = ax + hx, ay + hy
        boxes = [(st.ego_x_m, st.ego_y_m, st.ego_yaw_rad, arrays.ego_length_m, arrays.ego_width_m)]
        boxes += [
            (vx_[:, q], vy_[:, q], vyaw[:, q], arrays.other_length_m[q], arrays.other_width_m[q])
            for q in vehicles
            if arrays.other_active[k, q]
        ]
        for bx, by, byaw, bl, bw in boxes:
            cx, cy = closest_point_on_box(x, y, bx, by, byaw, bl, bw)
            dx, dy = x - cx, y - cy
            gap = np.sqrt(dx * dx + dy * dy) - r_i
            hx, hy = core.repulsion_accel_core(dx, dy, gap, a_n, b_v, m, vx, vy, lam)
            ax, ay = ax + hx, ay + hy
        ract = st.rider_active
        rr = 0.5 * max(arrays.rider_length_m, arrays.rider_width_m)
        dx, dy = x - st.rider_x_m, y - st.rider_y_m
        gap = np.sqrt(dx * dx + dy * dy) - r_i - rr
        hx, hy = core.repulsion_accel_core(dx, dy, gap, a_n, b_v, m, vx, vy, lam)
        ax, ay = ax + np.where(ract, hx, 0.0), ay + np.where(ract, hy, 0.0)
        ax, ay = core.accel_cap_core(ax, ay, core.MAX_ACCEL_MPS2)
        nvx, nvy = core.speed_cap_core(vx + ax * dt, vy + ay * dt, pd_.v0_mps[i])
        sim = np.asarray(on) & np.ones(b, dtype=bool)
        rec_sp, rec_yaw = arrays.other_speed_mps[kn, j], arrays.other_yaw_rad[kn, j]
        out["ped_vx_mps"][:, i] = np.where(sim, nvx, rec_sp * np.cos(rec_yaw))
        out["ped_vy_mps"][:, i] = np.where(sim, nvy, rec_sp * np.sin(rec_yaw))
        out["ped_x_m"][:, i] = np.where(sim, x + nvx * dt, arrays.other_x_m[kn, j])
        out["ped_y_m"][:, i] = np.where(sim, y + nvy * dt, arrays.other_y_m[kn, j])
        out["ped_prog_m"][:, i] = np.where(sim, prog, pd_.arc_m[kn, i])
    return out


def rider_from_pedestrians(
    st: Any,
    arrays: Any,
    blk: Any,
    sel: npt.NDArray[np.intp] | None,
    x0: FloatArray,
    y0: FloatArray,
    fx: FloatArray,
    fy: FloatArray,
) -> tuple[FloatArray, FloatArray]:
    """(fx, fy) [N] plus the riders' repulsion (sfm.a_rider_n, b_rider_per_m) from the
    present social-force pedestrians (vei.sim.pedestrians) of the variants ``sel``."""
    p = blk.params
    ps = p if sel is None else p.take(sel)
    on = np.asarray(_at(blk.peds, sel), dtype=bool)
    r_self = 0.5 * max(arrays.rider_length_m, arrays.rider_width_m)
    sources = [
        (
            _at(st.ped_x_m[:, i], sel), _at(st.ped_y_m[:, i], sel),
            np.logical_and(on, bool(arrays.other_active[st.k, j])), ps.ped_radius_m,
        )
        for i, j in enumerate(arrays.peds.idx)
    ]  # fmt: skip
    hx, hy = repulsion(x0, y0, r_self, ps, sources)
    return fx + hx, fy + hy


def _at(a: Any, idx: npt.NDArray[np.intp] | None) -> Any:
    """a[idx] for arrays, a for scalars; idx None = everything."""
    if idx is None or np.ndim(a) == 0:
        return a
    return np.asarray(a)[idx]
