"""Rider side: when an equipped rider sends a VRU awareness message (VAM), and what it says.

The generation rules of ETSI TS 103 300-3 (V2.2.1, clause 6.4.1, "Individual VAM
transmission management by VBS at VRU ITS-S"; parameters of clause 6.2 Table 16 and
clause 6.4 Table 17), batched over variants ``[b]`` and senders ``[b, S]``:

- the first VAM is generated at once when the VRU basic service starts: here when the
  rider enters the scene (an equipped rider that leaves and comes back starts again);
- the service checks every ``T_CheckVamGen`` (<= T_GenVamMin) from its start; generation
  events are at least ``T_GenVam`` apart (no congestion control: T_GenVam = T_GenVamMin);
- at a check a VAM is generated when one of these holds, comparing the *current
  estimates* with the values *lastly included in a VAM*: the time since the last VAM
  exceeds T_GenVamMax; the reference position moved more than
  minReferencePointPositionChangeThreshold; the ground speed changed by more than
  minGroundSpeedChangeThreshold; the heading changed by more than
  minGroundVelocityOrientationChangeThreshold ("exceeds": strict, with a 1e-9 tolerance
  against the summed steps). The clause's other triggers (trajectory interception
  probability, clusters, safe distances) are not modelled, nor redundancy mitigation.

Estimates: the position is the latest GNSS fix (one every T_CheckVamGen, 10 Hz by
default), truth plus a time-correlated error (first-order Gauss-Markov per axis from fix to
fix, stationary sigma ``position_error_std_m``, correlation time ``position_error_tau_s``,
the same for every variant of a seed and key); speed and heading
are the rider's own (a Doppler speed is far more accurate than a position fix; the heading
is the rider's yaw, so that a standing rider keeps one). The engine steps at ``dt``; a
check falls on the first step at or after its instant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.policy.perception_random import counter_bits, counter_uniform

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: Random streams of V2X (perception uses 0-4; each effect its own stream).
STREAM_EQUIPPED = 20
STREAM_GNSS = 21
STREAM_DELIVERY = 23
STREAM_LATENCY = 24
STREAM_BLOCKAGE = 25  # and 26
#: Tolerance of the strict "exceeds" comparisons and the check instants [s, m, m/s, rad].
TOL = 1e-9
_TWO_M32 = 2.0**-32
#: 95 % radius of a circular 2-D Gaussian in sigmas: sqrt(-2 ln 0.05).
R95_PER_SIGMA = math.sqrt(-2.0 * math.log(0.05))


@dataclass(frozen=True)
class VamRules:
    """The generation rules' parameters (from :class:`vei.config.v2x.V2XConfig`).

    Attributes:
        t_gen_min_s, t_gen_max_s, t_check_s: T_GenVamMin, T_GenVamMax, T_CheckVamGen [s].
        position_m, speed_mps, heading_rad: the change thresholds [m, m/s, rad].
    """

    t_gen_min_s: float = 0.1
    t_gen_max_s: float = 5.0
    t_check_s: float = 0.1
    position_m: float = 4.0
    speed_mps: float = 0.5
    heading_rad: float = math.radians(4.0)

    @classmethod
    def of(cls, cfg: Any) -> VamRules:
        """The rules of a V2XConfig."""
        return cls(
            cfg.t_gen_vam_min_s, cfg.t_gen_vam_max_s, cfg.t_check_vam_gen_s,
            cfg.position_threshold_m, cfg.speed_threshold_mps,
            math.radians(cfg.heading_threshold_deg),
        )  # fmt: skip


@dataclass(frozen=True)
class SenderState:
    """Each sender's VRU basic service, ``[b, S]``.

    Attributes:
        equipped: the rider carries a device (drawn once per rider and variant).
        running: the service ran at the previous step (the rider was in the scene).
        start_s: when the service last started [s] (NaN: never).
        n_checks: checks done since then (the next is at start_s + (n + 1) T_check).
        last_tx_s: generation time of the last VAM [s] (NaN: none yet).
        sent_x_m, sent_y_m, sent_speed_mps, sent_heading_rad: the values lastly included.
        err_x_m, err_y_m: the GNSS error of the latest fix [m].
        fix_index: the latest fix's index m (fixes at m T_check; -1 before the first), a
            0-d int array.
    """

    equipped: BoolArray
    running: BoolArray
    start_s: FloatArray
    n_checks: npt.NDArray[np.int64]
    last_tx_s: FloatArray
    sent_x_m: FloatArray
    sent_y_m: FloatArray
    sent_speed_mps: FloatArray
    sent_heading_rad: FloatArray
    err_x_m: FloatArray
    err_y_m: FloatArray
    fix_index: npt.NDArray[np.int64] = field(default_factory=lambda: np.array(-1))


def equipped_riders(
    seed: int, keys: npt.ArrayLike, columns: npt.ArrayLike, penetration: FloatArray
) -> BoolArray:
    """Which senders carry a device: u < penetration rate, one draw per rider and variant.

    Args:
        seed: V2X seed. keys: [b] variant keys. columns: [S] the senders' object indices.
        penetration: [b] share equipped, in [0, 1].
    Returns:
        [b, S] bool (for a given key the set only grows with the rate).
    """
    cols = np.asarray(columns, dtype=np.intp)
    n = int(cols.max()) + 1 if cols.size else 0
    u = counter_uniform(seed, keys, 0, n, STREAM_EQUIPPED)[:, cols]
    return u < np.asarray(penetration, dtype=np.float64)[:, None]


def init_senders(
    seed: int, keys: npt.ArrayLike, columns: npt.ArrayLike, penetration: FloatArray
) -> SenderState:
    """The senders before the first step: equipped or not, no service running."""
    eq = equipped_riders(seed, keys, columns, penetration)
    nan = np.full(eq.shape, np.nan)
    return SenderState(
        equipped=eq, running=np.zeros(eq.shape, dtype=bool), start_s=nan.copy(),
        n_checks=np.zeros(eq.shape, dtype=np.int64), last_tx_s=nan.copy(),
        sent_x_m=nan.copy(), sent_y_m=nan.copy(), sent_speed_mps=nan.copy(),
        sent_heading_rad=nan.copy(), err_x_m=nan.copy(), err_y_m=nan.copy(),
    )  # fmt: skip


def gnss_error(
    state: SenderState,
    seed: int,
    keys: npt.ArrayLike,
    columns: npt.ArrayLike,
    t_s: float,
    fix_period_s: float,
    std_m: FloatArray,
    tau_s: float,
) -> tuple[FloatArray, FloatArray, int]:
    """The GNSS error of the latest fix at time t: a first-order Gauss-Markov process per axis.

    The device has a fix every ``fix_period_s`` (at m * period, m = 0, 1, ...; the VAM
    generation checks read the latest); the error advances from fix to fix,
    ``e_0 = sigma z_0`` (stationary start), ``e_m = phi e_(m-1) + sigma sqrt(1 - phi^2) z_m``
    with ``phi = exp(-period / tau)`` (over a gap of several periods, phi of the gap), z
    standard normals of (seed, key, m, rider): Box-Muller on the two 32-bit halves of one
    counter-based 64-bit draw. Between fixes it holds.

    Args:
        state: the senders (err_* and fix_index of the previous call).
        seed, keys, columns: as :func:`equipped_riders`. t_s: now [s].
        fix_period_s: time between fixes [s]. std_m: [b] stationary sigma per axis [m].
        tau_s: correlation time [s].
    Returns:
        (err_x_m, err_y_m) [b, S], the fix index m.
    """
    m = int(math.floor(t_s / fix_period_s + TOL))
    last = int(state.fix_index)
    if m == last:
        return state.err_x_m, state.err_y_m, m
    cols = np.asarray(columns, dtype=np.intp)
    sig = np.asarray(std_m, dtype=np.float64)[:, None]
    if not np.any(sig > 0.0):
        z = np.zeros(state.equipped.shape)
        return z, z.copy(), m
    n = int(cols.max()) + 1
    # One 64-bit draw per rider and fix: its two 32-bit halves are the Box-Muller pair.
    bits = counter_bits(seed, keys, m, n, STREAM_GNSS)[:, cols]
    u1 = ((bits >> np.uint64(32)).astype(np.float64) + 0.5) * _TWO_M32  # (0, 1)
    u2 = (bits & np.uint64(0xFFFFFFFF)).astype(np.float64) * _TWO_M32  # [0, 1)
    r = np.sqrt(-2.0 * np.log(u1))
    zx, zy = r * np.cos(2.0 * np.pi * u2), r * np.sin(2.0 * np.pi * u2)
    if last < 0:
        return sig * zx, sig * zy, m
    phi = math.exp(-(m - last) * fix_period_s / tau_s)
    gain = math.sqrt(max(0.0, 1.0 - phi * phi))
    ex = phi * state.err_x_m + sig * gain * zx
    ey = phi * state.err_y_m + sig * gain * zy
    return ex, ey, m


def _angle_diff(a: FloatArray, b: FloatArray) -> FloatArray:
    """|a - b| wrapped to [0, pi] [rad]."""
    d = np.mod(a - b + np.pi, 2.0 * np.pi) - np.pi
    return np.abs(d)


@dataclass(frozen=True)
class Generated:
    """The VAMs generated at one step, ``[b, S]`` (fields valid where ``sent``).

    Attributes:
        sent: a VAM is generated now.
        x_m, y_m: the reported position (GNSS estimate) [m].
        speed_mps, heading_rad: the reported ground speed [m/s] and heading [rad].
        first: it is the first VAM of the service (carries the low-frequency container).
    """

    sent: BoolArray
    x_m: FloatArray
    y_m: FloatArray
    speed_mps: FloatArray
    heading_rad: FloatArray
    first: BoolArray


def generate(
    rules: VamRules,
    state: SenderState,
    t_s: float,
    present: BoolArray,
    x_m: FloatArray,
    y_m: FloatArray,
    speed_mps: FloatArray,
    heading_rad: FloatArray,
    err_x_m: FloatArray,
    err_y_m: FloatArray,
    fix_index: int = -1,
) -> tuple[Generated, SenderState]:
    """One step of the VRU basic service of every sender (pure).

    Args:
        rules: the generation rules. state: after the previous step. t_s: now [s].
        present: [b, S] the rider is in the scene. x_m, y_m, speed_mps, heading_rad:
            [b, S] its true position [m], ground speed [m/s] and yaw [rad].
        err_x_m, err_y_m: [b, S] the GNSS error of the latest fix [m] (:func:`gnss_error`).
        fix_index: that fix's index (kept in the state).
    Returns:
        (the VAMs generated now, the new state).
    """
    on = state.equipped & present
    starting = on & ~state.running
    start = np.where(starting, t_s, state.start_s)
    n_chk = np.where(starting, 0, state.n_checks)
    next_check = start + (n_chk + 1) * rules.t_check_s
    check = on & ~starting & (t_s >= next_check - TOL)
    # Checks passed by this step (several when dt > T_check): the next one lies after t.
    with np.errstate(invalid="ignore"):
        passed = np.floor(np.nan_to_num((t_s - start) / rules.t_check_s) + TOL).astype(np.int64)
    n_chk = np.where(check, np.maximum(passed, n_chk + 1), n_chk)
    ex = x_m + err_x_m
    ey = y_m + err_y_m
    elapsed = t_s - state.last_tx_s
    due = check & (elapsed >= rules.t_gen_min_s - TOL)
    with np.errstate(invalid="ignore"):
        trig = (
            (elapsed > rules.t_gen_max_s + TOL)
            | (np.hypot(ex - state.sent_x_m, ey - state.sent_y_m) > rules.position_m + TOL)
            | (np.abs(speed_mps - state.sent_speed_mps) > rules.speed_mps + TOL)
            | (_angle_diff(heading_rad, state.sent_heading_rad) > rules.heading_rad + TOL)
        )
    sent = starting | (due & trig)

    def keep(new: FloatArray, old: FloatArray) -> FloatArray:
        return np.where(sent, new, old)

    out = Generated(sent, ex, ey, speed_mps, heading_rad, starting.copy())
    new = replace(
        state,
        running=on,
        start_s=start,
        n_checks=n_chk,
        last_tx_s=keep(np.full(sent.shape, float(t_s)), state.last_tx_s),
        sent_x_m=keep(ex, state.sent_x_m),
        sent_y_m=keep(ey, state.sent_y_m),
        sent_speed_mps=keep(speed_mps, state.sent_speed_mps),
        sent_heading_rad=keep(heading_rad, state.sent_heading_rad),
        err_x_m=err_x_m,
        err_y_m=err_y_m,
        fix_index=np.array(fix_index),
    )
    return out, new


__all__ = [
    "R95_PER_SIGMA",
    "STREAM_BLOCKAGE",
    "STREAM_DELIVERY",
    "STREAM_EQUIPPED",
    "STREAM_GNSS",
    "STREAM_LATENCY",
    "Generated",
    "SenderState",
    "VamRules",
    "equipped_riders",
    "generate",
    "gnss_error",
    "init_senders",
]
