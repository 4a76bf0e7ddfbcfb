"""The engine side of the policy API: observations from the state, policies called per block.

:class:`PolicyDriver` holds, for a batch laid out by :func:`vei.sim.batch.batch_flags`,
each policy block's bound policy, its memory and a ring buffer of the ground truth (for
the perception delay). Once per step, before :func:`vei.sim.step.step`::

    action = driver.act(state)          # PolicyAction [B] (None when no policy block)
    state = step(state, params, arrays, flags, action=action)

Road users of the observation (axis N): the primary rider, the extra SFM riders, the
replayed others (vei.policy.observation): reacting cars and walking pedestrians where the
engine put them (:func:`ground_truth`). With a perception delay of n steps the policy
sees every object's ground truth of step k - n (not perceived while k < n); with an
enabled ``CaseConfig.perception`` (vei.policy.perception: range, field of view,
occlusion, noise, detection probability, held tracks) it sees that sensor model's output
on the delayed truth.
"""

from __future__ import annotations

import inspect
import traceback
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from vei.errors import ConfigError, PolicyError
from vei.models import ego as ego_model
from vei.models import traffic_core
from vei.policy.base import PolicyAction, check_policy
from vei.policy.observation import (
    SOURCE_NONE,
    SOURCE_SENSOR,
    Observation,
    category_code,
    wrap_angle,
)
from vei.policy.perception_random import label_keys, variant_keys_u64
from vei.sim.batch import BatchFlags, Block
from vei.sim.state import ScenarioArrays, SimState, VariantParams

FloatArray = npt.NDArray[np.float64]
#: Ground-truth channels kept per object: x, y, yaw, vx, vy, active.
_TRUTH = 6


def ground_truth(st: SimState, arrays: ScenarioArrays, sl: slice, peds: Any = False) -> FloatArray:
    """Ground truth of every road user at the state's step for the variants ``sl``.

    The replayed others are where the engine put them (as vei.sim.contacts.others_now):
    a reacting car (vei.sim.traffic) that the engine drives (``car_mode`` > REACTING) at
    its engine pose (car_x_m, car_y_m, car_yaw_rad) with its engine speed along its heading
    (car_v_mps), a replaying one at its recording; the pedestrians at their engine poses
    where ``peds`` (vei.sim.pedestrians: ped_x_m, ped_y_m, velocity ped_vx_mps, ped_vy_mps,
    heading along it while faster than 0.05 m/s, else the recorded heading); every other
    at its recording. Presence (active) is the recording's.

    Args:
        st: SimState at step k; sl: the variants. peds: the block's ``peds_sfm``
            (vei.sim.batch.Block.peds: True / False / [b] mask): where the pedestrians walk
            (elsewhere their SimState fields are not their poses).
    Returns:
        [6, b, N] (x_m, y_m, yaw_rad, vx_mps, vy_mps, active as 0/1), N = 1 + R + n_o.
    """
    k = st.k
    prim = np.stack(
        [st.rider_x_m[sl], st.rider_y_m[sl], st.rider_yaw_rad[sl], st.rider_vx_mps[sl],
         st.rider_vy_mps[sl], st.rider_active[sl].astype(np.float64)]
    )[:, :, None]  # fmt: skip
    parts = [prim]
    b = prim.shape[1]
    if arrays.riders.n:
        parts.append(
            np.stack(
                [
                    st.extra_x_m[sl],
                    st.extra_y_m[sl],
                    st.extra_yaw_rad[sl],
                    st.extra_vx_mps[sl],
                    st.extra_vy_mps[sl],
                    st.extra_active[sl].astype(np.float64),
                ]
            )  # fmt: skip
        )
    no = len(arrays.other_ids)
    if no:
        yaw = arrays.other_yaw_rad[k]
        sp = arrays.other_speed_mps[k]
        rows = [
            arrays.other_x_m[k], arrays.other_y_m[k], yaw, sp * np.cos(yaw), sp * np.sin(yaw),
            arrays.other_active[k].astype(np.float64),
        ]  # fmt: skip
        others = np.stack([np.broadcast_to(r, (b, no)) for r in rows])
        _engine_others(others, st, arrays, sl, peds)
        parts.append(others)
    return np.concatenate(parts, axis=2)


def _engine_others(
    others: FloatArray, st: SimState, arrays: ScenarioArrays, sl: slice, peds: Any
) -> None:
    """Put the engine's reacting cars and walking pedestrians into ``others`` [6, b, n_o]
    (the recording at step st.k) in place (see :func:`ground_truth`)."""
    tr = arrays.traffic
    if tr.n:
        c = tr.n
        driven = st.car_mode[sl][:, :c] > traffic_core.REACTING  # [b, C]
        if driven.any():
            cyaw, cv = st.car_yaw_rad[sl][:, :c], st.car_v_mps[sl][:, :c]
            eng = (st.car_x_m[sl][:, :c], st.car_y_m[sl][:, :c], cyaw, cv * np.cos(cyaw),
                   cv * np.sin(cyaw))  # fmt: skip
            for r, val in enumerate(eng):
                others[r][:, tr.idx] = np.where(driven, val, others[r][:, tr.idx])
    pd_ = arrays.peds
    if pd_.n and peds is not False:
        on = np.asarray(peds, dtype=bool)
        on = np.broadcast_to(on[:, None] if on.ndim else on, (others.shape[1], pd_.n))
        if on.any():
            vx, vy = st.ped_vx_mps[sl][:, : pd_.n], st.ped_vy_mps[sl][:, : pd_.n]
            rec_yaw = others[2][:, pd_.idx]
            walking = on & (np.hypot(vx, vy) > 0.05)
            eng = (st.ped_x_m[sl][:, : pd_.n], st.ped_y_m[sl][:, : pd_.n],
                   np.where(walking, np.arctan2(vy, vx), rec_yaw), vx, vy)  # fmt: skip
            for r, val in enumerate(eng):
                others[r][:, pd_.idx] = np.where(on, val, others[r][:, pd_.idx])


def object_table(arrays: ScenarioArrays) -> tuple[FloatArray, FloatArray, npt.NDArray[np.int8]]:
    """[N] length_m, width_m and int8 category code of the observation's road users."""
    xr = arrays.riders
    length = np.concatenate([[arrays.rider_length_m], xr.length_m, arrays.other_length_m])
    width = np.concatenate([[arrays.rider_width_m], xr.width_m, arrays.other_width_m])
    cats = [arrays.rider_category, *xr.categories, *arrays.other_categories]
    return (
        length.astype(np.float64),
        width.astype(np.float64),
        np.array([category_code(c) for c in cats], dtype=np.int8),
    )


def path_lateral(
    path: ego_model.PathTable, ego_s_m: FloatArray, x: FloatArray, y: FloatArray
) -> FloatArray:
    """Signed lateral offset [m] (left +) of points (x, y) [b, N] from the ego path near
    ego_s_m [b] (the projection of :func:`vei.models.ego.corridor_check`)."""
    s_e = np.broadcast_to(ego_s_m[:, None], x.shape).reshape(-1)
    xf, yf = x.reshape(-1), y.reshape(-1)
    i, w = path.index(s_e)
    ex, ey, ec, es = path.values_at(i, w, "x", "y", "cos", "sin")
    s_q = s_e + (xf - ex) * ec + (yf - ey) * es
    i, w = path.index(s_q)
    px, py, pc, ps = path.values_at(i, w, "x", "y", "cos", "sin")
    ddx, ddy = xf - px, yf - py
    return (ddy * pc - ddx * ps).reshape(x.shape)


def build_observation(
    st: SimState,
    arrays: ScenarioArrays,
    blk: Block,
    truth: FloatArray,
    valid: npt.NDArray[np.bool_],
    age_s: FloatArray,
    table: tuple[FloatArray, FloatArray, npt.NDArray[np.int8]],
    source: npt.NDArray[np.int8] | None = None,
    position_std_m: FloatArray | None = None,
) -> Observation:
    """The Observation of one block from its state slice and the perceived truth.

    Args:
        st: the full SimState at step k. blk: the block. truth: [6, b, N] perceived ground
            truth (delayed). valid: [b, N] perceived. age_s: [b, N] age of the sample [s].
        table: :func:`object_table`.
        source: [b, N] int8 where each entry comes from (vei.policy.observation SOURCE_*);
            None = the sensor wherever valid.
        position_std_m: [b, N] 1-sigma position uncertainty [m]; None = the block's
            sensor noise (0 for ideal perception) wherever valid.
    """
    sl = slice(blk.start, blk.stop)
    p = blk.params
    b = blk.stop - blk.start
    ex, ey, eyaw = st.ego_x_m[sl], st.ego_y_m[sl], st.ego_yaw_rad[sl]
    v = st.ego_v_mps[sl]
    s_e = st.ego_s_m[sl]
    collided = st.collided[sl]
    c, s = np.cos(eyaw)[:, None], np.sin(eyaw)[:, None]
    ox, oy, oyaw, ovx, ovy = truth[0], truth[1], truth[2], truth[3], truth[4]
    dx, dy = ox - ex[:, None], oy - ey[:, None]
    dvx, dvy = ovx - (v * np.cos(eyaw))[:, None], ovy - (v * np.sin(eyaw))[:, None]
    length, width, cat = table
    n = truth.shape[2]
    path = arrays.ego_path
    gap = np.full((b, n), np.inf)
    # Object 0 (the primary rider): exactly the CAP's corridor test (vei.sim.step).
    seen = valid[:, 0] & ~collided
    sidx = np.flatnonzero(seen)
    L_e = arrays.ego_length_m
    if sidx.size == b:
        ahead, g0 = ego_model.corridor_check(
            path, s_e, L_e, ox[:, 0], oy[:, 0], oyaw[:, 0], length[0], width[0], True,
            p.corridor_half_width_m, p.detection_range_m,
        )  # fmt: skip
        gap[:, 0] = np.where(ahead, g0, np.inf)
    elif sidx.size:
        ahead, g0 = ego_model.corridor_check(
            path, s_e[sidx], L_e, ox[sidx, 0], oy[sidx, 0], oyaw[sidx, 0], length[0], width[0],
            True, p.corridor_half_width_m[sidx], p.detection_range_m[sidx],
        )  # fmt: skip
        gap[sidx, 0] = np.where(ahead, g0, np.inf)
    if n > 1:
        rest = valid[:, 1:] & ~collided[:, None]
        if rest.any():
            bi, oj = np.nonzero(rest)
            oj1 = oj + 1
            ahead, g = ego_model.corridor_check(
                path, s_e[bi], L_e, ox[bi, oj1], oy[bi, oj1], oyaw[bi, oj1], length[oj1],
                width[oj1], True, p.corridor_half_width_m[bi], p.detection_range_m[bi],
            )  # fmt: skip
            gap[bi, oj1] = np.where(ahead, g, np.inf)
    lat = np.where(valid, path_lateral(path, s_e, ox, oy), np.inf)
    z = np.zeros((b, n))
    if source is None:
        source = np.where(valid, SOURCE_SENSOR, SOURCE_NONE).astype(np.int8)
    if position_std_m is None:
        noise = blk.perception.position_noise_std_m if blk.perception is not None else 0.0
        position_std_m = np.where(valid, float(noise), np.inf)
    return Observation(
        t_s=np.full(b, st.k * arrays.dt_s),
        dt_s=arrays.dt_s,
        ego_speed_mps=v,
        ego_accel_mps2=st.ego_a_mps2[sl],
        ego_s_m=s_e,
        path_length_m=np.full(b, float(arrays.ego_track.data[-1, arrays.ego_track.col("s_m")])),
        cruise_speed_mps=p.cruise_speed_mps,
        max_accel_mps2=p.max_accel_mps2_ego,
        max_decel_mps2=p.max_decel_mps2_ego,
        ego_length_m=float(arrays.ego_length_m),
        ego_width_m=float(arrays.ego_width_m),
        collided=collided,
        valid=valid,
        rel_x_m=np.where(valid, dx * c + dy * s, z),
        rel_y_m=np.where(valid, -dx * s + dy * c, z),
        rel_yaw_rad=np.where(valid, wrap_angle(oyaw - eyaw[:, None]), z),
        rel_vx_mps=np.where(valid, dvx * c + dvy * s, z),
        rel_vy_mps=np.where(valid, -dvx * s + dvy * c, z),
        length_m=np.broadcast_to(length, (b, n)),
        width_m=np.broadcast_to(width, (b, n)),
        age_s=np.where(valid, age_s, np.inf),
        category=np.broadcast_to(cat, (b, n)),
        path_gap_m=gap,
        path_lateral_m=lat,
        source=source,
        position_std_m=position_std_m,
    )


def policy_label(policy: Any) -> str:
    """How a policy is named in messages: 'path/to/file.py:Class' for a class loaded from a
    file, else 'module:Class' (the spec the user wrote, up to the path's spelling)."""
    cls = type(policy)
    name = getattr(policy, "name", None)
    if isinstance(name, str) and cls.__module__.startswith("vei.policy."):
        return name
    if cls.__module__.startswith("vei_user_policy_"):
        try:
            return f"{inspect.getsourcefile(cls)}:{cls.__qualname__}"
        except (TypeError, OSError):
            pass
    return f"{cls.__module__}:{cls.__qualname__}"


#: Frames of a policy's traceback shown in a PolicyError.
_FRAMES = 3


def _guarded(policy: Any, what: str, fn: Callable[..., Any], *args: Any, when: str = "") -> Any:
    """``fn(*args)``; an exception raised by it becomes a PolicyError naming the policy,
    the call (and step / time), the exception and the last frames of the policy's file."""
    try:
        return fn(*args)
    except Exception as exc:  # noqa: BLE001 - a user's code: report it as a vei error
        frames = traceback.extract_tb(exc.__traceback__)[1:]  # drop this frame
        try:
            own = inspect.getsourcefile(type(policy))
        except (TypeError, OSError):
            own = None
        mine = [f for f in frames if own is not None and f.filename == own]
        shown = (mine or frames)[-_FRAMES:]
        where = "".join(
            f"\n  {f.filename}:{f.lineno} in {f.name}" + (f": {f.line}" if f.line else "")
            for f in shown
        )
        at = f" at {when}" if when else ""
        raise PolicyError(
            f"policy {policy_label(policy)}: {what}(){at} raised {type(exc).__name__}: {exc}{where}"
        ) from None


class Demand(NamedTuple):
    """The policies' demands for the whole batch [B] (engine order), input of step().

    Attributes:
        accel_mps2: [B] demanded acceleration [m/s^2] (used where command is NaN).
        command: [B] command u in [-1, 1], NaN where the policy gave an acceleration.
        fsm_state: [B] int8 recorded as cap_state.
    """

    accel_mps2: FloatArray
    command: FloatArray
    fsm_state: npt.NDArray[np.int8]


class PolicyDriver:
    """Calls each policy block's policy once per step (see the module docstring).

    Args:
        arrays: the scenario. params: the batch (engine order). flags: its BatchFlags.
        variant_keys: [B] integer keys of the perception's random numbers (engine order);
            default :func:`vei.policy.perception_random.label_keys` of ``params.labels``
            (a variant's draws follow its label, not its position in the batch).
    """

    def __init__(
        self,
        arrays: ScenarioArrays,
        params: VariantParams,
        flags: BatchFlags,
        variant_keys: npt.ArrayLike | None = None,
    ) -> None:
        self.arrays = arrays
        b_all = params.batch_size
        self.variant_keys = (
            label_keys(params.labels) if variant_keys is None else variant_keys_u64(variant_keys)
        )
        if self.variant_keys.shape != (b_all,):
            raise ConfigError(f"variant_keys must have shape ({b_all},)")
        self.batch_size = params.batch_size
        self.blocks = [blk for blk in flags.blocks if blk.policy is not None]
        self.table = object_table(arrays)
        self.policies = []
        self.states = []
        for blk in self.blocks:
            pol = blk.policy
            bind = getattr(pol, "bind", None)
            bound = _guarded(pol, "bind", bind, blk.params) if callable(bind) else pol
            bound = check_policy(bound, type(pol).__name__)
            self.policies.append(bound)
            self.states.append(_guarded(pol, "init_state", bound.init_state, blk.stop - blk.start))
        self.delay = [blk.delay_steps.astype(np.int64) for blk in self.blocks]
        h = max((int(d.max()) for d in self.delay), default=0) + 1
        self.hist_len = h
        self._ring: list[FloatArray | None] = [None] * len(self.blocks)
        self._pstates: list[Any] = [None] * len(self.blocks)
        self.v2x_states: list[Any] = [None] * len(self.blocks)
        # what V2X did, per block (vei.policy.v2x.report)
        self.v2x_logs: list[Any] = [None] * len(self.blocks)

    def act(self, st: SimState) -> Demand | None:
        """The PolicyAction [B] of step k (accel_mps2 for every variant: the command of
        command-giving policies is mapped to its acceleration) or None without policies."""
        if not self.blocks:
            return None
        b_all = self.batch_size
        acc = np.zeros(b_all)
        cmd = np.full(b_all, np.nan)
        fsm = np.zeros(b_all, dtype=np.int8)
        for i, blk in enumerate(self.blocks):
            sl = slice(blk.start, blk.stop)
            b = blk.stop - blk.start
            truth = ground_truth(st, self.arrays, sl, blk.peds)
            ring = self._ring[i]
            if self.hist_len > 1:
                if ring is None:
                    ring = np.zeros((self.hist_len,) + truth.shape)
                    self._ring[i] = ring
                ring[st.k % self.hist_len] = truth
                lag_k = st.k - self.delay[i]
                slot = np.mod(lag_k, self.hist_len)
                seen = ring[slot, :, np.arange(b), :].transpose(1, 0, 2)  # [6, b, N]
                ok = (lag_k >= 0)[:, None]
            else:
                seen = truth
                ok = np.ones((b, 1), dtype=bool)
            valid = (seen[5] > 0.5) & ok
            age = np.broadcast_to((self.delay[i] * self.arrays.dt_s)[:, None], valid.shape)
            if blk.perception is not None:
                seen, valid, age = self._perceive(i, st, blk, seen, valid, age)
            source = std = None
            if blk.v2x is not None:
                seen, valid, age, source, std = self._v2x(i, st, blk, truth, seen, valid, age)
            obs = build_observation(st, self.arrays, blk, seen, valid, age, self.table, source, std)
            if blk.v2x is not None and not blk.v2x.policies_use_v2x and _builtin(blk.policy):
                obs = obs.sensor_view()
            when = f"step {st.k} (t = {st.k * self.arrays.dt_s:.3f} s)"
            out = _guarded(
                self.policies[i], "act", self.policies[i].act, obs, self.states[i], when=when
            )
            # every complaint about what act() returned names the policy (its file), the step
            where = f"policy {policy_label(self.policies[i])}: act() at {when}"
            if not (isinstance(out, tuple) and len(out) == 2):
                raise PolicyError(
                    f"{where} must return (PolicyAction, state), got {type(out).__name__}"
                )
            action, self.states[i] = out
            if not isinstance(action, PolicyAction):
                raise PolicyError(
                    f"{where} must return (PolicyAction, state), got {type(action).__name__}"
                )
            try:
                action = action.checked(b, where)
            except ConfigError as exc:
                raise PolicyError(str(exc)) from None
            if blk.v2x is not None:
                self._log_v2x(i, st.k * self.arrays.dt_s, source, valid, truth[5] > 0.5,
                              action, obs.max_decel_mps2)  # fmt: skip
            if action.command is not None:
                cmd[sl] = action.command
            else:
                acc[sl] = action.accel_mps2
            if action.fsm_state is not None:
                fsm[sl] = action.fsm_state
        return Demand(accel_mps2=acc, command=cmd, fsm_state=fsm)

    def _log_v2x(self, i: int, t_s: float, source: Any, valid: Any, present: Any,
                 action: PolicyAction, max_decel_mps2: Any) -> None:  # fmt: skip
        """Block i's V2X log (vei.policy.v2x.report) after the policy acted at t_s
        (``present``: [b, N] the road users in the scene)."""
        from vei.policy.v2x import report

        if self.v2x_logs[i] is None:
            self.v2x_logs[i] = report.V2XLog.start(self.blocks[i].stop - self.blocks[i].start)
        brakes = report.braking(action.accel_mps2, action.command, max_decel_mps2)
        self.v2x_logs[i].update(t_s, source, valid, present, brakes)

    def v2x_report(self) -> dict[str, np.ndarray] | None:
        """What V2X did in each variant of the batch ({field: [B]}, the fields of
        vei.policy.v2x.report, NaN where V2X was off), or None when no block ran V2X."""
        from vei.policy.v2x import report

        if all(log is None for log in self.v2x_logs):
            return None
        out = report.empty(self.batch_size)
        for blk, log, state in zip(self.blocks, self.v2x_logs, self.v2x_states, strict=True):
            if log is None:
                continue
            part = report.finish(log, state, self.arrays.dt_s)
            for name, values in part.items():
                out[name][blk.start : blk.stop] = values
        return out

    def _perceive(
        self, i: int, st: SimState, blk: Block, truth: FloatArray, valid: Any, age: Any
    ) -> tuple[FloatArray, Any, FloatArray]:
        """The sensor model (vei.policy.perception) on the delayed truth of block i.

        Every present road user may occlude the others; the ego's own pose is the
        current one (it knows it exactly). Returns the perceived objects in the world
        frame ([6, b, N] like the truth), tracked mask [b, N] and age [b, N] (the
        track's age since its last detection plus the engine's latency).
        """
        from vei.policy import perception as perc

        sl = slice(blk.start, blk.stop)
        b = blk.stop - blk.start
        n = truth.shape[2]
        ex, ey, eyaw, v = st.ego_x_m[sl], st.ego_y_m[sl], st.ego_yaw_rad[sl], st.ego_v_mps[sl]
        c, s = np.cos(eyaw), np.sin(eyaw)
        length, width, _ = self.table
        gt = perc.GroundTruth(
            x_m=truth[0], y_m=truth[1], yaw_rad=truth[2], vx_mps=truth[3], vy_mps=truth[4],
            length_m=np.broadcast_to(length, (b, n)).copy(),
            width_m=np.broadcast_to(width, (b, n)).copy(),
            valid=np.asarray(valid, dtype=bool).copy(), can_occlude=np.asarray(valid, dtype=bool).copy(),
            ego_x_m=ex, ego_y_m=ey, ego_yaw_rad=eyaw, ego_vx_mps=v * c, ego_vy_mps=v * s,
        )  # fmt: skip
        pstate = self._pstates[i]
        if pstate is None:
            pstate = perc.init_state(b, n)
        po, self._pstates[i] = perc.perceive(
            blk.perception, pstate, gt, st.k, self.arrays.dt_s, self.variant_keys[sl]
        )
        tracked = po.tracked

        def z(a: FloatArray) -> FloatArray:
            return np.where(tracked, a, 0.0)

        cc, ss = c[:, None], s[:, None]
        px, py, pvx, pvy = z(po.x_m), z(po.y_m), z(po.vx_mps), z(po.vy_mps)
        world = np.stack(
            [
                ex[:, None] + cc * px - ss * py,
                ey[:, None] + ss * px + cc * py,
                eyaw[:, None] + z(po.yaw_rad),
                cc * pvx - ss * pvy + (v * c)[:, None],
                ss * pvx + cc * pvy + (v * s)[:, None],
                tracked.astype(np.float64),
            ]
        )
        return world, tracked, np.where(tracked, z(po.age_s) + age, np.inf)

    def _v2x(
        self,
        i: int,
        st: SimState,
        blk: Block,
        now: FloatArray,
        seen: FloatArray,
        valid: Any,
        age: Any,
    ) -> tuple[FloatArray, Any, FloatArray, npt.NDArray[np.int8], FloatArray]:
        """V2X of block i (vei.policy.v2x): the riders' messages of the current truth
        ``now`` [6, b, N] into the car's tracks, fused with the perceived ``seen``.

        Returns the fused world [6, b, N], valid, age [s], source and position sigma [m]
        ([b, N]); the block's V2X state is kept in ``v2x_states[i]``.
        """
        from vei.policy.v2x import fusion
        from vei.policy.v2x import model as v2x_model

        cfg = blk.v2x
        sl = slice(blk.start, blk.stop)
        length, width, cats = self.table
        codes = [category_code(c) for c in cfg.sender_categories]
        cols = np.flatnonzero(np.isin(cats, codes))
        keys = self.variant_keys[sl]
        vparams = v2x_model.V2XParams.of(blk.params)
        state = self.v2x_states[i]
        if state is None:
            state = v2x_model.init_state(cfg, vparams, keys, cols)
        world = v2x_model.World(
            x_m=now[0], y_m=now[1], yaw_rad=now[2], vx_mps=now[3], vy_mps=now[4],
            valid=now[5] > 0.5, length_m=length, width_m=width,
            is_vehicle=cats == category_code("vehicle"), ego_x_m=st.ego_x_m[sl],
            ego_y_m=st.ego_y_m[sl], buildings=self.arrays.buildings,
        )  # fmt: skip
        objs, self.v2x_states[i], _ = v2x_model.step(
            cfg, vparams, state, world, cols, st.k, self.arrays.dt_s, keys
        )
        noise = blk.perception.position_noise_std_m if blk.perception is not None else 0.0
        return fusion.fuse(seen, np.asarray(valid, dtype=bool), np.asarray(age, dtype=np.float64),
                           noise, objs, cols)  # fmt: skip


def _builtin(policy: Any) -> bool:
    """The policy is one of vei's own (vei.policy.*), not a user's."""
    return type(policy).__module__.startswith("vei.policy.")


__all__ = [
    "Demand",
    "PolicyDriver",
    "build_observation",
    "ground_truth",
    "object_table",
    "path_lateral",
]
