"""One V2X step: riders' VAMs over the channel into the car's V2X tracks (pure, batched).

Per engine step k (time t = k dt), for the B variants of a block and its S senders (the
road users of the observation whose category may carry a device):

1. rider side (:mod:`.vam`): the GNSS error advances; equipped, present riders generate
   VAMs by the rules of TS 103 300-3 from their GNSS estimates; a VAM carries the
   position, speed, heading, the stated 95 % position accuracy (:data:`.vam.R95_PER_SIGMA`
   times the configured sigma, as a circle) and its time stamp (generation time + the
   device's clock offset);
2. channel (:mod:`.channel`, :mod:`.links`): each link is LOS, NLOSv (a vehicle's box
   crosses it) or NLOS (a building of the map does); each VAM is delivered or lost (its
   link budget, or a given delivery table, and ``pdr_factor``) and, if delivered, arrives
   after its latency;
3. car side: the VAMs that have arrived by t update the car's track of their sender (the
   newest generation wins; an older one arriving late is ignored); a track is predicted to
   t at constant velocity over its age ``t - time stamp`` (clipped at 0) and dropped once
   older than ``max_track_age_s``.

Messages in flight are kept in a ring of Q slots per sender (Q > the longest latency over
T_GenVamMin, so that a slot is only reused after its message arrived). Random numbers are
functions of (seed, variant key, step, road user, stream) (:mod:`vei.policy.perception_random`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.policy.perception_random import counter_normal_pair, counter_uniform
from vei.policy.v2x import channel as ch
from vei.policy.v2x import links, vam

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Rows of the stacked message array ``V2XState.msgs`` [8, b, S, Q] (the track fields are
#: its rows 1.. : ``V2XState.tracks`` [7, b, S]).
MSG_FIELDS = ("arrive_s", "gen_s", "stamp_s", "x_m", "y_m", "speed_mps", "heading_rad", "std_m")
TRACK_FIELDS = MSG_FIELDS[1:]
_M = {f: i for i, f in enumerate(MSG_FIELDS)}
_T = {f: i for i, f in enumerate(TRACK_FIELDS)}


@dataclass(frozen=True)
class V2XParams:
    """The per-variant (sweepable) V2X settings of a block, each ``[b]``.

    Attributes:
        penetration_rate [-], latency_s [s], latency_jitter_s [s], pdr_factor [-],
        position_error_std_m [m], clock_offset_s [s] (vei.config.v2x.V2XConfig).
    """

    penetration_rate: FloatArray
    latency_s: FloatArray
    latency_jitter_s: FloatArray
    pdr_factor: FloatArray
    position_error_std_m: FloatArray
    clock_offset_s: FloatArray

    @classmethod
    def of(cls, params: Any) -> V2XParams:
        """From a VariantParams (its v2x_* fields)."""
        return cls(
            params.v2x_penetration_rate, params.v2x_latency_s, params.v2x_latency_jitter_s,
            params.v2x_pdr_factor, params.v2x_position_error_std_m, params.v2x_clock_offset_s,
        )  # fmt: skip

    @classmethod
    def from_config(cls, cfg: Any, batch_size: int) -> V2XParams:
        """B copies of a V2XConfig's values."""
        fixed, jitter, _ = cfg.latency
        vals = (cfg.penetration_rate, fixed, jitter, cfg.pdr_factor, cfg.position_error_std_m,
                cfg.clock_offset_s)  # fmt: skip
        return cls(*(np.full(batch_size, float(v)) for v in vals))


@dataclass(frozen=True)
class World:
    """The truth V2X needs at one step.

    Attributes:
        x_m, y_m, yaw_rad, vx_mps, vy_mps: [b, N] road users (world frame) [m, rad, m/s].
        valid: [b, N] present. length_m, width_m: [N] boxes [m].
        is_vehicle: [N] bool, the road user's box can block a link.
        ego_x_m, ego_y_m: [b] the car's box centre (its antenna) [m].
        buildings: the map's building outlines near the scene
            (:class:`vei.policy.v2x.links.Buildings`) or None (no NLOS link).
    """

    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    vx_mps: FloatArray
    vy_mps: FloatArray
    valid: BoolArray
    length_m: FloatArray
    width_m: FloatArray
    is_vehicle: BoolArray
    ego_x_m: FloatArray
    ego_y_m: FloatArray
    buildings: Any = None


@dataclass(frozen=True)
class V2XState:
    """Everything V2X carries from step to step.

    Attributes:
        senders: the riders' services (:class:`.vam.SenderState`, [b, S]).
        msgs: messages in flight, [8, b, S, Q], rows :data:`MSG_FIELDS` (NaN = empty slot).
        slot: [b, S] the next slot to fill.
        tracks: the car's tracks, [7, b, S], rows :data:`TRACK_FIELDS` (NaN = no track).
        first_rx_s: [b, S] when the car first received a VAM of that rider [s] (NaN: not yet).
        n_sent, n_delivered: [b, S] VAMs generated / delivered so far.
    """

    senders: vam.SenderState
    msgs: FloatArray
    slot: npt.NDArray[np.int64]
    tracks: FloatArray
    first_rx_s: FloatArray
    n_sent: npt.NDArray[np.int64] | None = None
    n_delivered: npt.NDArray[np.int64] | None = None


@dataclass(frozen=True)
class V2XObjects:
    """What the car knows from V2X at a step, ``[b, S]`` (world frame, predicted to now).

    Attributes:
        valid: a track exists. x_m, y_m [m], vx_mps, vy_mps [m/s], yaw_rad [rad]: the
        predicted state. age_s: now minus the message's time stamp, >= 0 [s]. std_m: the
        stated 1-sigma position error [m].
    """

    valid: BoolArray
    x_m: FloatArray
    y_m: FloatArray
    vx_mps: FloatArray
    vy_mps: FloatArray
    yaw_rad: FloatArray
    age_s: FloatArray
    std_m: FloatArray


def slots_needed(cfg: Any, params: V2XParams) -> int:
    """Q: slots per sender so that a slot is reused only after its message arrived."""
    _, _, dist = cfg.latency
    worst = max(
        ch.latency_bound(float(f), float(j), dist)
        for f, j in zip(params.latency_s, params.latency_jitter_s, strict=True)
    )
    return int(math.floor(worst / cfg.t_gen_vam_min_s)) + 2


def init_state(
    cfg: Any, params: V2XParams, keys: npt.ArrayLike, columns: npt.ArrayLike
) -> V2XState:
    """The state before the first step (no service running, nothing in flight, no track).

    Args:
        cfg: the V2XConfig. params: [b] settings. keys: [b] variant keys.
        columns: [S] the senders' indices among the road users.
    """
    senders = vam.init_senders(cfg.seed, keys, columns, params.penetration_rate)
    b, s = senders.equipped.shape
    q = slots_needed(cfg, params)
    return V2XState(
        senders=senders,
        msgs=np.full((len(MSG_FIELDS), b, s, q), np.nan),
        slot=np.zeros((b, s), dtype=np.int64),
        tracks=np.full((len(TRACK_FIELDS), b, s), np.nan),
        first_rx_s=np.full((b, s), np.nan),
        n_sent=np.zeros((b, s), dtype=np.int64),
        n_delivered=np.zeros((b, s), dtype=np.int64),
    )


def _deliver(
    cfg: Any,
    params: V2XParams,
    gen: vam.Generated,
    world: World,
    columns: npt.NDArray[np.intp],
    keys: npt.ArrayLike,
    k: int,
) -> dict[str, Any]:
    """This step's VAMs over the channel, [b, S] each (NaN / False / -1 where none was
    sent): 'delivered', 'latency_s', 'blocked' (a vehicle's box crosses the link), 'nlos'
    (a building does), 'link' (int8 state: channel.LOS / NLOSV / NLOS), 'loss_db' (the
    vehicle blockage loss drawn), 'pdr' (the delivery probability)."""
    shape = gen.sent.shape
    ev: dict[str, Any] = {
        "delivered": np.zeros(shape, dtype=bool), "latency_s": np.full(shape, np.nan),
        "blocked": np.zeros(shape, dtype=bool), "nlos": np.zeros(shape, dtype=bool),
        "link": np.full(shape, -1, dtype=np.int8), "loss_db": np.full(shape, np.nan),
        "pdr": np.full(shape, np.nan),
    }  # fmt: skip
    bi, si = np.nonzero(gen.sent)
    if bi.size == 0:
        return ev
    n = world.x_m.shape[1]
    cols = columns[si]
    sx, sy = world.x_m[bi, cols], world.y_m[bi, cols]
    rx, ry = world.ego_x_m[bi], world.ego_y_m[bi]
    dist = np.hypot(sx - rx, sy - ry)
    blocker_h = np.zeros(bi.size)
    if cfg.nlos and world.is_vehicle.any():
        veh = np.flatnonzero(world.is_vehicle)
        blk = world.valid[bi][:, veh] & (veh[None, :] != cols[:, None])
        shp = blk.shape
        heights = links.blocker_heights_m(world.length_m[veh], cfg.truck_min_length_m)
        blocker_h = links.tallest_blocker_m(
            sx, sy, rx, ry, world.x_m[bi][:, veh], world.y_m[bi][:, veh],
            world.yaw_rad[bi][:, veh], np.broadcast_to(world.length_m[veh], shp),
            np.broadcast_to(world.width_m[veh], shp), np.broadcast_to(heights, shp), blk,
        )  # fmt: skip
    vehicle = blocker_h > 0.0
    building = np.zeros(bi.size, dtype=bool)
    if cfg.buildings and world.buildings is not None:
        building = world.buildings.blocks(sx, sy, rx, ry)
    state = np.where(building, ch.NLOS, np.where(vehicle, ch.NLOSV, ch.LOS)).astype(np.int8)
    dh = cfg.car_antenna_height_m - cfg.rider_antenna_height_m
    d3 = ch.distance_3d_m(dist, dh)
    loss = np.zeros(bi.size)
    nlosv = state == ch.NLOSV
    if nlosv.any():
        z, _ = counter_normal_pair(cfg.seed, keys, k, n, vam.STREAM_BLOCKAGE)
        if cfg.nlos_loss_db is not None:
            mean, std = cfg.nlos_loss_db, cfg.nlos_loss_std_db
        else:
            mean, std = ch.blockage_stats_db(d3, cfg.rider_antenna_height_m,
                                             cfg.car_antenna_height_m, blocker_h)  # fmt: skip
        loss = np.where(nlosv, ch.blockage_loss(mean, std, z[bi, cols]), 0.0)
    table = cfg.pdr_table
    if table is None:
        snr = ch.mean_snr_db(ch.path_loss_db(d3, state, cfg.environment, loss), cfg.technology)
        sigma = np.asarray(ch.SHADOWING_STD_DB)[state]
        p_link = ch.delivery_ratio(snr, cfg.technology, sigma)
    else:
        extra = np.where(state == ch.NLOS, ch.pathloss_nlos_db(d3)
                         - ch.pathloss_los_db(d3, cfg.environment), loss)  # fmt: skip
        slope = cfg.pdr_slope_db_per_decade or ch.los_slope_db_per_decade(cfg.environment)
        p_link = ch.pdr_at(ch.effective_distance(dist, extra, slope), *table)
    p = params.pdr_factor[bi] * p_link
    u = counter_uniform(cfg.seed, keys, k, n, vam.STREAM_DELIVERY)[bi, cols]
    _, _, dist_kind = cfg.latency
    ul = counter_uniform(cfg.seed, keys, k, n, vam.STREAM_LATENCY)[bi, cols]
    ev["pdr"][bi, si] = p
    ev["delivered"][bi, si] = u < p
    ev["blocked"][bi, si] = vehicle
    ev["nlos"][bi, si] = building
    ev["link"][bi, si] = state
    ev["loss_db"][bi, si] = loss
    ev["latency_s"][bi, si] = ch.latency(ul, params.latency_s[bi], params.latency_jitter_s[bi],
                                         dist_kind)  # fmt: skip
    return ev


def step(
    cfg: Any,
    params: V2XParams,
    state: V2XState,
    world: World,
    columns: npt.ArrayLike,
    k: int,
    dt_s: float,
    keys: npt.ArrayLike,
) -> tuple[V2XObjects, V2XState, dict[str, Any]]:
    """One V2X step at t = k dt (see the module docstring). Pure: nothing is mutated.

    Args:
        cfg: the V2XConfig. params: [b] settings. state: after step k - 1.
        world: the truth now. columns: [S] the senders' indices among world's road users.
        k: step index. dt_s: engine step [s]. keys: [b] variant keys.
    Returns:
        (the car's V2X objects [b, S] predicted to now, the new state, this step's events
        {'sent', 'delivered', 'blocked', 'nlos', 'link', 'loss_db', 'latency_s', 'pdr'
        (the delivery probability)}: [b, S] arrays; see :func:`_deliver`).
    """
    cols = np.asarray(columns, dtype=np.intp)
    t = k * dt_s
    x, y = world.x_m[:, cols], world.y_m[:, cols]
    vx, vy = world.vx_mps[:, cols], world.vy_mps[:, cols]
    ex, ey, fix = vam.gnss_error(state.senders, cfg.seed, keys, cols, t, cfg.t_check_vam_gen_s,
                                 params.position_error_std_m, cfg.position_error_tau_s)  # fmt: skip
    gen, senders = vam.generate(
        vam.VamRules.of(cfg), state.senders, t, world.valid[:, cols], x, y, np.hypot(vx, vy),
        world.yaw_rad[:, cols], ex, ey, fix,
    )  # fmt: skip

    ev = _deliver(cfg, params, gen, world, cols, keys, k)
    delivered, lat = ev["delivered"], ev["latency_s"]
    # Messages into their slots (a copy only when one is written: state stays untouched).
    msgs = state.msgs
    slot = state.slot
    bi, si = np.nonzero(delivered)
    if bi.size:
        msgs = msgs.copy()
        slot = slot.copy()
        q = slot[bi, si] % msgs.shape[3]
        vals = (t + lat[bi, si], np.full(bi.size, t), t + params.clock_offset_s[bi],
                gen.x_m[bi, si], gen.y_m[bi, si], gen.speed_mps[bi, si],
                gen.heading_rad[bi, si], params.position_error_std_m[bi])  # fmt: skip
        msgs[:, bi, si, q] = np.stack(vals)
        slot[bi, si] += 1
    # Arrivals: the newest generation among them updates the track.
    with np.errstate(invalid="ignore"):
        arrived = msgs[_M["arrive_s"]] <= t + vam.TOL
    tracks = state.tracks
    first_rx = state.first_rx_s
    if arrived.any():
        gen_key = np.where(arrived, msgs[_M["gen_s"]], -np.inf)
        best = np.argmax(gen_key, axis=2)
        newest = np.take_along_axis(gen_key, best[..., None], axis=2)[..., 0]
        older = np.nan_to_num(tracks[_T["gen_s"]], nan=-np.inf)
        take = np.isfinite(newest) & (newest > older)
        got = np.take_along_axis(msgs[1:], best[None, ..., None], axis=3)[..., 0]
        tracks = np.where(take[None], got, tracks)
        first_rx = np.where(take & np.isnan(first_rx), t, first_rx)
        msgs = np.where(arrived[None], np.nan, msgs)
    # Prediction to now; stale tracks dropped.
    has = ~np.isnan(tracks[_T["gen_s"]])
    age = np.where(has, np.maximum(0.0, t - tracks[_T["stamp_s"]]), np.nan)
    stale = has & (age > cfg.max_track_age_s + vam.TOL)
    if stale.any():
        tracks = np.where(stale[None], np.nan, tracks)
        has &= ~stale
        age = np.where(has, age, np.nan)
    heading, speed = tracks[_T["heading_rad"]], tracks[_T["speed_mps"]]
    vxt, vyt = speed * np.cos(heading), speed * np.sin(heading)
    objs = V2XObjects(
        valid=has, x_m=tracks[_T["x_m"]] + vxt * age, y_m=tracks[_T["y_m"]] + vyt * age,
        vx_mps=vxt, vy_mps=vyt, yaw_rad=heading, age_s=age, std_m=tracks[_T["std_m"]],
    )  # fmt: skip
    n_sent = state.n_sent if state.n_sent is not None else np.zeros(gen.sent.shape, np.int64)
    n_del = state.n_delivered if state.n_delivered is not None else np.zeros_like(n_sent)
    new = replace(state, senders=senders, msgs=msgs, slot=slot, tracks=tracks,
                  first_rx_s=first_rx, n_sent=n_sent + gen.sent,
                  n_delivered=n_del + delivered)  # fmt: skip
    return objs, new, {"sent": gen.sent, **ev}


__all__ = [
    "MSG_FIELDS",
    "TRACK_FIELDS",
    "V2XObjects",
    "V2XParams",
    "V2XState",
    "World",
    "init_state",
    "slots_needed",
    "step",
]
