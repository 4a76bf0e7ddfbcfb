"""The rider's conflicts with the ego and its yield / go decision in the NumPy step.

:func:`find_conflicts` (once per scenario, :func:`vei.sim.state.prepare_scenario`) finds
where the rider's path comes within the car's swept corridor (both PathTables, extensions
included: :func:`vei.models.crossings.corridor_zones`) and the conflict zones' extents;
:func:`decision_step` is one step of the decision of B social-force riders (the laws of
:mod:`vei.models.decision_core`; the compiled kernel runs the same on scalars,
:mod:`vei.sim.kernel.decision`).

The rider attends to one conflict at a time: the first along its path whose zone it has
not yet left (conflicts are sorted by the zone's exit along the rider's path). When its
progress passes that zone the decision starts afresh (FREE) for the next one.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from types import SimpleNamespace
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.models import decision_core as core
from vei.models.crossings import corridor_zones
from vei.models.ego import PathTable

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class Conflicts:
    """The crossings of the rider's path with the ego's (K of them; K = 0: none).

    Attributes:
        s_rider_m, s_ego_m: [K] arc lengths of the crossing along the rider's path
            (PathTable rider_path) and the ego's (ego_path) [m].
        hz_rider_m, hz_ego_m: [K] half-lengths of the conflict zone along each path [m].
        exit_m: [K] s_rider_m + hz_rider_m (increasing): where the rider has left the zone.
    """

    s_rider_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    s_ego_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    hz_rider_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    hz_ego_m: FloatArray = field(default_factory=lambda: np.zeros(0))
    exit_m: FloatArray = field(default_factory=lambda: np.zeros(0))

    @property
    def n(self) -> int:
        """K, the number of conflicts."""
        return int(self.s_rider_m.shape[0])


#: Clearance [m] the car's corridor adds on each side (the conflict zones': a yielding
#: rider stops this far, plus ``decision.stop_margin_m``, outside the strip the car sweeps).
CORRIDOR_MARGIN_M = 0.3


def find_conflicts(
    ego_path: PathTable,
    rider_path: PathTable,
    ego_length_m: float,
    ego_width_m: float,
    rider_length_m: float,
    rider_width_m: float,
) -> Conflicts:
    """The rider's conflicts with the ego (:class:`Conflicts`), sorted along the rider's
    path: every stretch of the rider's path inside the car's swept corridor (its path,
    its width, the rider's extent and :data:`CORRIDOR_MARGIN_M`;
    :func:`vei.models.crossings.corridor_zones`): crossings, a stretch shared with the
    car's lane, and passes within reach without crossing (a rider beside the car's path at
    a turn). A zone is entered at ``s_rider_m - hz_rider_m`` and left at ``exit_m`` along
    the rider's path; the car occupies it while its centre is within ``s_ego_m +-
    hz_ego_m`` along its own."""
    s_in, s_out, e_in, e_out = corridor_zones(
        rider_path, ego_path, ego_length_m, ego_width_m, rider_length_m, rider_width_m,
        CORRIDOR_MARGIN_M,
    )  # fmt: skip
    if s_in.size == 0:
        return Conflicts()
    return Conflicts(
        0.5 * (s_in + s_out),
        0.5 * (e_in + e_out),
        0.5 * (s_out - s_in),
        0.5 * (e_out - e_in),
        s_out,
    )


def current_conflict(conf: Conflicts, prog_m: FloatArray) -> npt.NDArray[np.intp]:
    """[B] index of the conflict the rider attends to at progress ``prog_m`` [B]: the first
    whose zone exit it has not passed (K = none left)."""
    return np.searchsorted(conf.exit_m, prog_m, side="left")


def decision_step(
    conf: Conflicts,
    state: npt.NDArray[np.int8],
    prog_prev_m: FloatArray,
    prog_m: FloatArray,
    v_rider_mps: FloatArray,
    s_ego_m: FloatArray,
    v_ego_mps: FloatArray,
    p: Any,
    v_ref_mps: FloatArray,
    tau_s: FloatArray,
) -> tuple[npt.NDArray[np.int8], FloatArray]:
    """One step of the decision of B riders (the NumPy form of the compiled kernel's).

    Args:
        conf: the scenario's conflicts (K >= 1).
        state: [B] decision states of the previous step (FREE / GO / YIELD).
        prog_prev_m: [B] the riders' progress [m] at the previous step (its conflict).
        prog_m: [B] progress now [m]. v_rider_mps: [B] speeds [m/s].
        s_ego_m, v_ego_mps: [B] the ego's arc length [m] and speed [m/s].
        p: per-variant parameters with [B] fields critical_gap_s, decision_horizon_s,
            yield_decel_mps2, stop_margin_m, clear_margin_m.
        v_ref_mps: [B] the riders' speed floor of their time to arrive (reference_speed_core).
        tau_s: [B] their relaxation time m / k_des [s].
    Returns:
        (new state [B] int8, speed cap [B] [m/s], +inf where none).
    """
    k = conf.n
    c_prev = current_conflict(conf, prog_prev_m)
    c = current_conflict(conf, prog_m)
    state = np.where(c != c_prev, core.FREE, state)
    has = c < k
    ci = np.minimum(c, k - 1)
    d_r, tta_r, dta, t_clear, live = core.conflict_times_core(
        prog_m, v_rider_mps, s_ego_m, v_ego_mps, conf.s_rider_m[ci], conf.s_ego_m[ci],
        conf.hz_rider_m[ci], conf.hz_ego_m[ci], p.clear_margin_m, v_ref_mps,
    )  # fmt: skip
    live = live & has
    new = core.decide_core(
        state, live, dta, tta_r, d_r, p.critical_gap_s, p.decision_horizon_s
    ).astype(np.int8)
    cap = core.yield_speed_core(
        new, d_r, v_rider_mps, tta_r, t_clear, p.stop_margin_m, p.yield_decel_mps2, tau_s
    )
    return new, np.asarray(cap, dtype=np.float64)


def _at(a: Any, idx: npt.NDArray[np.intp] | None) -> Any:
    """a[idx] for arrays, a for scalars; idx None = everything."""
    if idx is None or np.ndim(a) == 0:
        return a
    return np.asarray(a)[idx]


def decide_block(
    st: Any,
    arrays: Any,
    blk: Any,
    sel: npt.NDArray[np.intp] | None,
    prog0: FloatArray,
    prog: FloatArray,
    vdx: FloatArray,
    vdy: FloatArray,
    r_dec: npt.NDArray[np.int8],
) -> tuple[FloatArray, FloatArray]:
    """The yield / go decision of the moving social-force riders ``sel`` (None = all) of
    one engine block (vei.sim.batch.Block) at step k (state ``st``): writes their new
    decision state into ``r_dec`` [B] and returns their desired velocity (vdx, vdy) [b]
    [m/s] capped by it. ``prog0`` / ``prog``: their progress [m] at the previous step and
    now."""
    p = blk.params
    q = SimpleNamespace(
        critical_gap_s=_at(p.critical_gap_s, sel),
        decision_horizon_s=_at(p.decision_horizon_s, sel),
        yield_decel_mps2=_at(p.yield_decel_mps2, sel),
        stop_margin_m=_at(p.stop_margin_m, sel),
        clear_margin_m=_at(p.clear_margin_m, sel),
    )
    v_ref = core.reference_speed_core(
        _at(p.v0_mps, sel), _at(p.lookahead_m, sel), _at(p.sigma_m, sel)
    )
    tau = _at(p.mass_kg, sel) / _at(p.k_des_nspm, sel)
    old = _at(st.rider_decision, sel)
    new, cap = decision_step(
        arrays.conflicts, old, prog0, prog, _at(st.rider_speed_mps, sel),
        _at(st.ego_s_m, sel), _at(st.ego_v_mps, sel), q, v_ref, tau,
    )  # fmt: skip
    if blk.decide is not True:  # a mixed block: only the deciding variants
        on = np.asarray(_at(blk.decide, sel))
        new = np.where(on, new, old).astype(np.int8)
        cap = np.where(on, cap, np.inf)
    r_dec[slice(None) if sel is None else sel] = new
    vx, vy = core.capped_velocity_core(vdx, vdy, cap)
    return np.asarray(vx), np.asarray(vy)
