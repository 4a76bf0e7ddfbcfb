"""Outputs of the built-in engine: :class:`SimResult` (time series, summaries, frames)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pandas as pd

from vei.continuation.where import Route
from vei.errors import ConfigError
from vei.sim.state import EGO_CAP, SimState, VariantParams
from vei.types import EGO_CATEGORY, EGO_ID, TIMESERIES_COLUMNS, Trace

FloatArray = npt.NDArray[np.float64]


# --------------------------------------------------------------------------------------
# Result
# --------------------------------------------------------------------------------------
@dataclass(frozen=True)
class SimResult:
    """Outputs of a batched run. Time series are ``[B, T]`` (transposed views of the
    engine's time-major buffers); ``None`` when the run used ``record="none"``.

    Attributes:
        t_s: [T] step times [s].
        labels: [B] configuration name of each variant.
        params: the VariantParams that ran.
        scenario_id, rider_id, rider_category: identities.
        ego_length_m, ego_width_m, rider_length_m, rider_width_m: footprints [m].
        ego_s_m, ego_x_m, ego_y_m, ego_yaw_rad, ego_speed_mps: [B, T] ego path position
            [m], pose [m, rad], speed [m/s].
        ego_accel_mps2: [B, T] longitudinal acceleration (actuator; 0 standing / after a
            collision: the crash itself shows as the speed drop, not as an acceleration).
        ego_command: [B, T] the command u in [-1, 1] applied during the step that ended
            here (0 at k = 0). cap_state: [B, T] int8 (0 CRUISE, 1 BRAKE, 2 RECOVER; 0 for
            non-CAP variants).
        rider_x_m, rider_y_m, rider_yaw_rad, rider_speed_mps, rider_vx_mps, rider_vy_mps,
            rider_accel_mps2: [B, T] the primary rider (finite while inactive: first /
            last pose, speed 0). rider_active: [B, T] bool.
        collided: [B, T] bool latch of the ego / rider collision.
        hit_other: [B, T, n_o] bool latch, the ego touched replayed other j.
        collision_time_s: [B] first collision time [s] (NaN if none) (always present).
        min_center_distance_m: [B] minimum ego-rider centre distance while the rider is
            active [m] (inf if never active) (always present).
        other_ids, other_categories, other_length_m, other_width_m: replayed others.
        other_x_m, other_y_m, other_yaw_rad, other_speed_mps, other_active: [T, n_o]
            (the same for every variant).
        final_state: the SimState at the last step.
        extra_ids, extra_categories, extra_length_m, extra_width_m: the extra
            social-force riders (vei.sim.riders; R = 0 unless sim.sfm_riders selects them).
        extra_x_m, extra_y_m, extra_yaw_rad, extra_speed_mps, extra_accel_mps2:
            [B, T, R] their simulated poses (replayed in replay variants); extra_active
            [B, T, R] presence; extra_hit [B, T, R] the ego-contact latch. None without
            time series.
        rider_decision: [B, T] int8 the social-force rider's decision (vei.models.
            decision_core: 0 FREE, 1 GO, 2 YIELD; 0 throughout without decisions); None
            without time series.
        car_ids: the reacting cars (vei.sim.traffic; their ids among other_ids).
        car_x_m, car_y_m, car_yaw_rad, car_speed_mps: [B, T, C] their poses [m, rad] and
            speeds [m/s] (their recording while they replay) in the variants with
            ``cars_react`` (elsewhere not advanced: use the others' recording); car_mode
            [B, T, C] int8 (0 replay, 1 reacting, 2 IDM, 3 stopped). None without time series. The secondary
            collisions of each run are in ``final_state`` (sec_*, rear_end).
        ped_ids: the recorded pedestrians (vei.sim.pedestrians). ped_x_m, ped_y_m,
            ped_vx_mps, ped_vy_mps: [B, T, P] their engine poses and velocities where
            ``peds_sfm`` (NumPy step; None from the compiled kernel).
        routes: the scenario's labelled routes (ScenarioArrays.routes): where each run's
            contacts happened (:meth:`where`).
        v2x: what V2X did in each run ({field: [B]}, vei.policy.v2x.report: messages sent
            and delivered, the first V2X track, the first time a road user was known from
            V2X alone, when the car braked on it; NaN where V2X was off), None when no
            variant ran V2X.
    """

    t_s: FloatArray
    labels: npt.NDArray[np.object_]
    params: VariantParams
    scenario_id: str
    rider_id: str
    rider_category: str
    ego_length_m: float
    ego_width_m: float
    rider_length_m: float
    rider_width_m: float
    ego_s_m: FloatArray | None
    ego_x_m: FloatArray | None
    ego_y_m: FloatArray | None
    ego_yaw_rad: FloatArray | None
    ego_speed_mps: FloatArray | None
    ego_accel_mps2: FloatArray | None
    ego_command: FloatArray | None
    cap_state: npt.NDArray[np.int8] | None
    rider_x_m: FloatArray | None
    rider_y_m: FloatArray | None
    rider_yaw_rad: FloatArray | None
    rider_speed_mps: FloatArray | None
    rider_vx_mps: FloatArray | None
    rider_vy_mps: FloatArray | None
    rider_accel_mps2: FloatArray | None
    rider_active: npt.NDArray[np.bool_] | None
    collided: npt.NDArray[np.bool_] | None
    hit_other: npt.NDArray[np.bool_] | None
    collision_time_s: FloatArray
    min_center_distance_m: FloatArray
    other_ids: tuple[str, ...]
    other_categories: tuple[str, ...]
    other_length_m: FloatArray
    other_width_m: FloatArray
    other_x_m: FloatArray
    other_y_m: FloatArray
    other_yaw_rad: FloatArray
    other_speed_mps: FloatArray
    other_active: npt.NDArray[np.bool_]
    final_state: SimState
    extra_ids: tuple[str, ...] = ()
    extra_categories: tuple[str, ...] = ()
    extra_length_m: FloatArray | None = None
    extra_width_m: FloatArray | None = None
    extra_x_m: FloatArray | None = None
    extra_y_m: FloatArray | None = None
    extra_yaw_rad: FloatArray | None = None
    extra_speed_mps: FloatArray | None = None
    extra_accel_mps2: FloatArray | None = None
    extra_active: npt.NDArray[np.bool_] | None = None
    extra_hit: npt.NDArray[np.bool_] | None = None
    rider_decision: npt.NDArray[np.int8] | None = None
    car_ids: tuple[str, ...] = ()
    car_x_m: FloatArray | None = None
    car_y_m: FloatArray | None = None
    car_yaw_rad: FloatArray | None = None
    car_speed_mps: FloatArray | None = None
    car_mode: npt.NDArray[np.int8] | None = None
    ped_ids: tuple[str, ...] = ()
    ped_x_m: FloatArray | None = None
    ped_y_m: FloatArray | None = None
    ped_vx_mps: FloatArray | None = None
    ped_vy_mps: FloatArray | None = None
    routes: Mapping[str, Route] | None = None
    v2x: Mapping[str, FloatArray] | None = None

    @property
    def secondary_count(self) -> npt.NDArray[np.int32]:
        """[B] secondary collisions (every contact but the ego's with the primary rider,
        vei.sim.contacts)."""
        return np.asarray(self.final_state.sec_count)

    @property
    def batch_size(self) -> int:
        """B."""
        return int(self.labels.shape[0])

    @property
    def collision(self) -> npt.NDArray[np.bool_]:
        """[B] bool: the ego and the primary rider collided at some step."""
        return np.isfinite(self.collision_time_s)

    def _require(self) -> None:
        if self.ego_x_m is None:
            raise ConfigError("this SimResult was run with record='none': no time series")

    def to_trace(self, variant_slice: slice | Sequence[int] | int | None = None) -> Trace:
        """Ego vs primary rider as a :class:`vei.types.Trace` (copies, C-contiguous).

        Args:
            variant_slice: which variants (slice, index list or int); None = all.
        Returns:
            Trace with B' = the selected variants.
        """
        self._require()
        sel: slice | npt.NDArray[np.intp]
        if variant_slice is None:
            sel = slice(None)
        elif isinstance(variant_slice, slice):
            sel = variant_slice
        else:
            sel = np.atleast_1d(np.asarray(variant_slice, dtype=np.intp))

        def c(a: np.ndarray) -> np.ndarray:
            return np.ascontiguousarray(a[sel])

        return Trace(
            t_s=self.t_s.copy(),
            ego_xy_m=np.stack([c(self.ego_x_m), c(self.ego_y_m)], axis=-1),
            ego_yaw_rad=c(self.ego_yaw_rad),
            ego_speed_mps=c(self.ego_speed_mps),
            ego_accel_mps2=c(self.ego_accel_mps2),
            other_xy_m=np.stack([c(self.rider_x_m), c(self.rider_y_m)], axis=-1),
            other_yaw_rad=c(self.rider_yaw_rad),
            other_speed_mps=c(self.rider_speed_mps),
            other_vel_mps=np.stack([c(self.rider_vx_mps), c(self.rider_vy_mps)], axis=-1),
            other_active=c(self.rider_active),
            collided=c(self.collided),
            ego_length_m=self.ego_length_m,
            ego_width_m=self.ego_width_m,
            other_length_m=self.rider_length_m,
            other_width_m=self.rider_width_m,
            secondary=self.secondary(sel),
            where=self.where(sel),
        )

    def secondary(self, sel: slice | npt.NDArray[np.intp] = slice(None)) -> dict[str, np.ndarray]:
        """The secondary collisions of the variants ``sel`` (vei.metrics.secondary.
        secondary_record, from the engine's contact latches in ``final_state``)."""
        from vei.metrics.secondary import secondary_record
        from vei.sim.contacts import agent_name

        fs = self.final_state

        def names(codes: np.ndarray) -> list[str]:
            ids = (self.rider_id, self.other_ids, self.extra_ids)
            return [agent_name(int(c), *ids) for c in np.asarray(codes)[sel]]

        return secondary_record(
            np.asarray(fs.sec_count)[sel], np.asarray(fs.sec_first_t_s)[sel],
            names(fs.sec_striker), names(fs.sec_struck),
            np.asarray(fs.sec_max_speed_mps)[sel], np.asarray(fs.rear_end)[sel],
        )  # fmt: skip

    def where(self, sel: slice | npt.NDArray[np.intp] = slice(None)) -> dict[str, np.ndarray]:
        """Where the contacts of the variants ``sel`` happened
        (vei.continuation.where.run_where: 'contact' the primary rider at its first contact
        with the ego, 'secondary' the other road user of the first secondary contact; each
        'recorded', 'run-in', 'run-out' or ''), from the state at the end of the run (a
        collided rider stands where it touched)."""
        from vei.continuation.where import run_where

        sec = self.secondary(sel)
        fs = self.final_state
        xy = np.stack([np.asarray(fs.rider_x_m)[sel], np.asarray(fs.rider_y_m)[sel]], axis=-1)
        return run_where(
            dict(self.routes or {}), self.rider_id,
            collision_time_s=self.collision_time_s[sel],
            time_shift_s=np.asarray(self.params.time_shift_s)[sel],
            rider_xy_m=xy, rider_sfm=np.asarray(self.params.rider_sfm, dtype=bool)[sel],
            secondary_time_s=sec["first_t_s"], secondary_striker=list(sec["striker"]),
            secondary_struck=list(sec["struck"]),
        )  # fmt: skip

    def to_frame(
        self,
        config_name: str | Sequence[str] | None = None,
        variant_slice: slice | Sequence[int] | int | None = None,
        *,
        include_others: bool = True,
    ) -> pd.DataFrame:
        """Long-format time series with columns ``vei.types.TIMESERIES_COLUMNS``.

        One row per agent per step per variant: the ego, the primary rider (all steps,
        ``active`` telling presence), each extra social-force rider over the steps where it
        is present (its simulated pose, ``collided`` its ego-contact latch) and, if ``include_others``, each replayed road user
        over the steps where it is present. ``collided`` is the ego/rider latch for both
        of them and the ego-contact latch for the others. ``accel_mps2`` of the others is
        the finite difference of their speed. ``cap_state`` is set on ego rows of CAP
        variants only.

        Args:
            config_name: name written in the ``config`` column: one string for all the
                selected variants, one per variant, or None = the variants' labels.
            variant_slice: which variants (None = all); ``variant`` keeps the batch index.
            include_others: add the replayed other road users.
        Returns:
            DataFrame sorted by (variant, t_s, agent order: ego, rider, others).
        """
        self._require()
        b, t = self.batch_size, self.t_s.shape[0]
        if variant_slice is None:
            idx = np.arange(b)
        elif isinstance(variant_slice, slice):
            idx = np.arange(b)[variant_slice]
        else:
            idx = np.atleast_1d(np.asarray(variant_slice, dtype=np.intp))
        nb = idx.size
        if config_name is None:
            names = np.asarray(self.labels[idx], dtype=object)
        elif isinstance(config_name, str):
            names = np.full(nb, config_name, dtype=object)
        else:
            names = np.asarray(list(config_name), dtype=object)
            if names.size != nb:
                raise ConfigError(f"config_name has {names.size} names for {nb} variants")
        cap_names = np.array(["CRUISE", "BRAKE", "RECOVER"], dtype=object)
        is_cap = self.params.ego_mode[idx] == EGO_CAP
        tt = np.broadcast_to(self.t_s, (nb, t))
        var = np.broadcast_to(idx[:, None], (nb, t))
        cfg = np.broadcast_to(names[:, None], (nb, t))
        # (policy variants record their own fsm_state codes in cap_state: not CAP names)
        ego_cap = np.where(
            is_cap[:, None], cap_names[np.where(is_cap[:, None], self.cap_state[idx], 0)], ""
        )
        parts = [
            {
                "config": cfg, "variant": var, "t_s": tt, "agent_id": EGO_ID, "category": EGO_CATEGORY,
                "x_m": self.ego_x_m[idx], "y_m": self.ego_y_m[idx], "yaw_rad": self.ego_yaw_rad[idx],
                "speed_mps": self.ego_speed_mps[idx], "accel_mps2": self.ego_accel_mps2[idx],
                "active": np.ones((nb, t), dtype=bool), "collided": self.collided[idx], "cap_state": ego_cap,
            },
            {
                "config": cfg, "variant": var, "t_s": tt, "agent_id": self.rider_id,
                "category": self.rider_category, "x_m": self.rider_x_m[idx], "y_m": self.rider_y_m[idx],
                "yaw_rad": self.rider_yaw_rad[idx], "speed_mps": self.rider_speed_mps[idx],
                "accel_mps2": self.rider_accel_mps2[idx], "active": self.rider_active[idx],
                "collided": self.collided[idx], "cap_state": "",
            },
        ]  # fmt: skip
        frames = []
        for order, part in enumerate(parts):
            frames.append(_flatten(part, nb, t, order))
        n_x = len(self.extra_ids)
        if n_x and self.extra_x_m is not None:
            for j, xid in enumerate(self.extra_ids):
                act = self.extra_active[idx, :, j]
                part = {
                    "config": cfg, "variant": var, "t_s": tt, "agent_id": xid,
                    "category": self.extra_categories[j],
                    "x_m": self.extra_x_m[idx, :, j], "y_m": self.extra_y_m[idx, :, j],
                    "yaw_rad": self.extra_yaw_rad[idx, :, j],
                    "speed_mps": self.extra_speed_mps[idx, :, j],
                    "accel_mps2": self.extra_accel_mps2[idx, :, j], "active": act,
                    "collided": self.extra_hit[idx, :, j], "cap_state": "",
                }  # fmt: skip
                df = _flatten(part, nb, t, 2 + n_x + j)
                frames.append(df[act.ravel()])
        if include_others:
            cars = (
                {cid: c for c, cid in enumerate(self.car_ids)} if self.car_x_m is not None else {}
            )
            peds = (
                {pid: q for q, pid in enumerate(self.ped_ids)} if self.ped_x_m is not None else {}
            )
            for j, oid in enumerate(self.other_ids):
                act = self.other_active[:, j]
                if oid in peds:  # a social-force pedestrian where the variant simulates it
                    q = peds[oid]
                    on = np.asarray(self.params.peds_sfm)[idx][:, None]
                    vx, vy = self.ped_vx_mps[idx, :, q], self.ped_vy_mps[idx, :, q]
                    xs = np.where(on, self.ped_x_m[idx, :, q], self.other_x_m[:, j])
                    ys = np.where(on, self.ped_y_m[idx, :, q], self.other_y_m[:, j])
                    sp_ = np.hypot(vx, vy)
                    yaws = np.where(on & (sp_ > 0.05), np.arctan2(vy, vx), self.other_yaw_rad[:, j])
                    sps = np.where(on, sp_, self.other_speed_mps[:, j])
                elif (
                    oid in cars
                ):  # a reacting car: the engine's pose (its recording while replayed)
                    c = cars[oid]
                    on = np.asarray(self.params.cars_react)[idx][:, None]  # else replayed
                    xs = np.where(on, self.car_x_m[idx, :, c], self.other_x_m[:, j])
                    ys = np.where(on, self.car_y_m[idx, :, c], self.other_y_m[:, j])
                    yaws = np.where(on, self.car_yaw_rad[idx, :, c], self.other_yaw_rad[:, j])
                    driven = on & (self.car_mode[idx, :, c] > 1)  # replayed: the recorded speed
                    sps = np.where(
                        driven, self.car_speed_mps[idx, :, c], self.other_speed_mps[:, j]
                    )
                else:
                    xs = np.broadcast_to(self.other_x_m[:, j], (nb, t))
                    ys = np.broadcast_to(self.other_y_m[:, j], (nb, t))
                    yaws = np.broadcast_to(self.other_yaw_rad[:, j], (nb, t))
                    sps = np.broadcast_to(self.other_speed_mps[:, j], (nb, t))
                acc = np.zeros((nb, t))
                if t > 1:
                    acc[:, 1:] = np.diff(sps, axis=1) / (self.t_s[1] - self.t_s[0])
                part = {
                    "config": cfg, "variant": var, "t_s": tt, "agent_id": oid,
                    "category": self.other_categories[j],
                    "x_m": xs, "y_m": ys, "yaw_rad": yaws, "speed_mps": sps, "accel_mps2": acc,
                    "active": np.broadcast_to(act, (nb, t)),
                    "collided": self.hit_other[idx, :, j], "cap_state": "",
                }  # fmt: skip
                df = _flatten(part, nb, t, 2 + j)
                frames.append(df[np.broadcast_to(act, (nb, t)).ravel()])
        out = pd.concat(frames, ignore_index=True)
        out = out.sort_values(["variant", "t_s", "_order"], kind="stable").drop(columns="_order")
        out = out.reset_index(drop=True)
        out["variant"] = out["variant"].astype(np.int64)
        for col in ("config", "agent_id", "category", "cap_state"):
            out[col] = out[col].astype(str)
        return out[list(TIMESERIES_COLUMNS)]


def _flatten(part: dict, nb: int, t: int, order: int) -> pd.DataFrame:
    cols = {}
    for key, val in part.items():
        if isinstance(val, str):
            cols[key] = np.full(nb * t, val, dtype=object)
        else:
            cols[key] = np.asarray(val).reshape(nb * t)
    cols["_order"] = np.full(nb * t, order, dtype=np.int16)
    return pd.DataFrame(cols)


# --------------------------------------------------------------------------------------
# Simulation loop
# --------------------------------------------------------------------------------------
_RECORDED = (
    ("ego_s_m", "ego_s_m", np.float64),
    ("ego_x_m", "ego_x_m", np.float64),
    ("ego_y_m", "ego_y_m", np.float64),
    ("ego_yaw_rad", "ego_yaw_rad", np.float64),
    ("ego_speed_mps", "ego_v_mps", np.float64),
    ("ego_accel_mps2", "ego_a_mps2", np.float64),
    ("ego_command", "ego_cmd", np.float64),
    ("cap_state", "cap_state", np.int8),
    ("rider_x_m", "rider_x_m", np.float64),
    ("rider_y_m", "rider_y_m", np.float64),
    ("rider_yaw_rad", "rider_yaw_rad", np.float64),
    ("rider_speed_mps", "rider_speed_mps", np.float64),
    ("rider_vx_mps", "rider_vx_mps", np.float64),
    ("rider_vy_mps", "rider_vy_mps", np.float64),
    ("rider_accel_mps2", "rider_a_mps2", np.float64),
    ("rider_active", "rider_active", np.bool_),
    ("collided", "collided", np.bool_),
)

#: (SimResult field, SimState field, dtype) of the extra riders' [B, T, R] series.
_RECORDED_EXTRA = (
    ("extra_x_m", "extra_x_m", np.float64),
    ("extra_y_m", "extra_y_m", np.float64),
    ("extra_yaw_rad", "extra_yaw_rad", np.float64),
    ("extra_speed_mps", "extra_speed_mps", np.float64),
    ("extra_accel_mps2", "extra_a_mps2", np.float64),
    ("extra_active", "extra_active", np.bool_),
    ("extra_hit", "extra_hit", np.bool_),
)

#: (SimResult field, SimState field, dtype) of the [B, T] series of the road users'
#: behaviour (issue 24), recorded beside :data:`_RECORDED` (whose arrays the kernel's
#: regression digests hash).
_RECORDED_BEHAVIOUR = (("rider_decision", "rider_decision", np.int8),)
#: (SimResult field, SimState field, dtype) of the reacting cars' [B, T, C] series.
_RECORDED_CARS = (
    ("car_x_m", "car_x_m", np.float64),
    ("car_y_m", "car_y_m", np.float64),
    ("car_yaw_rad", "car_yaw_rad", np.float64),
    ("car_speed_mps", "car_v_mps", np.float64),
    ("car_mode", "car_mode", np.int8),
)
#: (SimResult field, SimState field, dtype) of the pedestrians' [B, T, P] series (the NumPy
#: step only: the compiled kernel does not simulate pedestrians).
_RECORDED_PEDS = (
    ("ped_x_m", "ped_x_m", np.float64),
    ("ped_y_m", "ped_y_m", np.float64),
    ("ped_vx_mps", "ped_vx_mps", np.float64),
    ("ped_vy_mps", "ped_vy_mps", np.float64),
)
