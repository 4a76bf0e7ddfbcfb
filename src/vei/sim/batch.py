"""Batch layout of the built-in engine: homogeneous blocks of variants.

:func:`vei.sim.engine.simulate` sorts the variants into contiguous blocks of equal (ego
mode, rider model) so that each block runs only its own branches (no per-variant mode
masks); :class:`BatchFlags` is that static structure, computed once outside the loop.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.sim.state import EGO_CAP, EGO_PID, EGO_POLICY, EGO_REPLAY_SPEED, VariantParams


# --------------------------------------------------------------------------------------
# Batch structure (computed once, outside the loop)
# --------------------------------------------------------------------------------------
def _switch(mask: npt.NDArray[np.bool_]) -> bool | npt.NDArray[np.bool_]:
    """True / False where the mask is uniform (lets the models skip a branch), else the mask."""
    if mask.all():
        return True
    if not mask.any():
        return False
    return mask


@dataclass(frozen=True)
class Block:
    """A contiguous run of variants with the same ego mode and rider model.

    Attributes:
        start, stop: the batch slice [start, stop).
        ego_mode: 0 replay-speed, 1 pid, 2 cap. rider_sfm: social-force rider (else replay).
        params: the VariantParams of the slice (views).
        delay_steps: [b] perception delay in steps (CAP blocks).
        paper_vdes, vehicle_force, front_bumper, paper_per_step: True / False if uniform in
            the block, else the [b] mask.
        rider_limits: some variant has a finite rider speed / acceleration cap.
        policy: the block's ego policy instance (ego_mode 3), unbound, else None.
        perception: the block's enabled PerceptionConfig, else None.
        decide: the rider's yield / go decision (VariantParams.decide): True / False if
            uniform in the block (False for replay blocks), else the [b] mask.
        obstacle: the rider brakes for a standing or slow car in its way
            (VariantParams.obstacle_braking), alike.
        traffic: the recorded cars react (VariantParams.cars_react): True / False if
            uniform in the block, else the [b] mask. peds: the recorded pedestrians walk by
            the social force (VariantParams.peds_sfm), alike.
        v2x: the block's enabled V2XConfig, else None.
    """

    start: int
    stop: int
    ego_mode: int
    rider_sfm: bool
    params: VariantParams
    delay_steps: npt.NDArray[np.intp]
    paper_vdes: bool | npt.NDArray[np.bool_]
    vehicle_force: bool | npt.NDArray[np.bool_]
    front_bumper: bool | npt.NDArray[np.bool_]
    paper_per_step: bool | npt.NDArray[np.bool_]
    rider_limits: bool
    policy: Any = None
    perception: Any = None
    decide: bool | npt.NDArray[np.bool_] = False
    obstacle: bool | npt.NDArray[np.bool_] = False
    traffic: bool | npt.NDArray[np.bool_] = False
    peds: bool | npt.NDArray[np.bool_] = False
    v2x: Any = None


@dataclass(frozen=True)
class BatchFlags:
    """Static structure of a parameter batch: which branches run, on which slices.

    Attributes:
        any_sfm, any_replay: rider models present. any_cap, any_pid, any_replay_speed:
            ego modes present.
        delay_steps: [B] perception delay in steps. hist_len: H = max(delay) + 1 (1 when
            no CAP variant has a delay).
        is_sfm, is_cap, is_replay_speed, is_ctrl: [B] masks (ctrl = pid or cap).
        blocks: the maximal runs of variants with equal (ego mode, rider model, policy
            instance), in batch order. :func:`simulate` sorts the batch so that there
            are at most six plus two per policy instance.
        any_policy: some variant runs a policy on the API (ego_mode 3).
    """

    any_sfm: bool
    any_replay: bool
    any_cap: bool
    any_pid: bool
    any_replay_speed: bool
    delay_steps: npt.NDArray[np.intp]
    hist_len: int
    is_sfm: npt.NDArray[np.bool_]
    is_cap: npt.NDArray[np.bool_]
    is_replay_speed: npt.NDArray[np.bool_]
    is_ctrl: npt.NDArray[np.bool_]
    blocks: tuple[Block, ...]
    any_policy: bool = False


def group_keys(params: VariantParams) -> npt.NDArray[np.int64]:
    """[B] group key 2 * ego_mode + rider_sfm + 8 * r (variants with equal keys share a
    block); r = 0 without a policy, else 1 + the rank of the variant's policy instance in
    order of first appearance (one block per policy instance)."""
    key = 2 * params.ego_mode.astype(np.int64) + params.rider_sfm.astype(np.int64)
    is_pol = params.ego_mode == EGO_POLICY
    if is_pol.any():
        ranks: dict[int, int] = {}
        rank = np.zeros(key.shape, dtype=np.int64)
        for i in np.flatnonzero(is_pol):
            ident = (id(params.policy[i]), id(params.perception[i]), id(params.v2x[i]))
            rank[i] = ranks.setdefault(ident, len(ranks) + 1)
        key = key + 8 * rank
    return key


def batch_flags(params: VariantParams, dt_s: float) -> BatchFlags:
    """The static BatchFlags of a parameter batch at step dt_s."""
    delay = params.delay_steps(dt_s)
    is_sfm = params.rider_sfm.copy()
    is_cap = params.ego_mode == EGO_CAP
    is_rs = params.ego_mode == EGO_REPLAY_SPEED
    keys = group_keys(params)
    cuts = np.concatenate([[0], np.flatnonzero(np.diff(keys)) + 1, [keys.size]])
    blocks = []
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        a, b = int(a), int(b)
        bp = params.take(slice(a, b)) if (a, b) != (0, keys.size) else params
        sfm = bool(bp.rider_sfm[0])
        cap = int(bp.ego_mode[0]) == EGO_CAP
        blocks.append(
            Block(
                start=a,
                stop=b,
                ego_mode=int(bp.ego_mode[0]),
                rider_sfm=sfm,
                params=bp,
                delay_steps=delay[a:b],
                paper_vdes=_switch(bp.paper_vdes) if sfm else False,
                vehicle_force=_switch(bp.use_vehicle_force) if sfm else False,
                front_bumper=_switch(bp.front_bumper) if sfm else False,
                paper_per_step=_switch(bp.paper_per_step) if cap else False,
                rider_limits=sfm
                and bool((np.isfinite(bp.max_speed_mps) | np.isfinite(bp.max_accel_mps2)).any()),
                policy=bp.policy[0] if int(bp.ego_mode[0]) == EGO_POLICY else None,
                perception=bp.perception[0] if int(bp.ego_mode[0]) == EGO_POLICY else None,
                decide=_switch(bp.decide) if sfm else False,
                obstacle=_switch(bp.obstacle_braking) if sfm else False,
                traffic=_switch(bp.cars_react),
                peds=_switch(bp.peds_sfm),
                v2x=bp.v2x[0] if int(bp.ego_mode[0]) == EGO_POLICY else None,
            )
        )
    return BatchFlags(
        any_sfm=bool(is_sfm.any()),
        any_replay=bool((~is_sfm).any()),
        any_cap=bool(is_cap.any()),
        any_pid=bool((params.ego_mode == EGO_PID).any()),
        any_replay_speed=bool(is_rs.any()),
        delay_steps=delay,
        hist_len=int(delay.max()) + 1 if bool((delay[is_cap] > 0).any()) else 1,
        any_policy=bool((params.ego_mode == EGO_POLICY).any()),
        is_sfm=is_sfm,
        is_cap=is_cap,
        is_replay_speed=is_rs,
        is_ctrl=~is_rs,
        blocks=tuple(blocks),
    )
