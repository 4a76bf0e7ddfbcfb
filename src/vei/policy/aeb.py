"""``aeb``: a TTC-based automatic emergency brake with forward collision warning (FCW).

Staged like production AEB systems and the Euro NCAP AEB protocols (warning first, then
partial braking, then full braking as the time to collision shrinks):

    TTC = path_gap / closing speed   over the objects ahead in the ego's path corridor
    stage 1 FCW           when TTC <= ttc_warning_s   (no braking; recorded)
    stage 2 partial brake when TTC <= ttc_partial_s   (demand -partial_decel_mps2)
    stage 3 full brake    when TTC <= ttc_full_s      (demand -full_decel_mps2)

Once braking (stage >= 2) the stage does not drop while an object in the path corridor
still closes in (finite TTC) or the car is (nearly) stopped (v < HOLD_SPEED_MPS) behind
one, so the car brakes to a standstill and holds there (as AEB systems do); when the path
clears, or every object in it moves away (TTC = inf, e.g. a rider pulling away ahead)
while the car still rolls, the brake releases and the ego returns to PID cruise.
Otherwise the ego drives the ``none`` PID.
fsm_state records the stage (0 off, 1 FCW, 2 partial, 3 full).

Defaults and sources (see docs/policy.md):
- Hulshof, W., Knight, I., Edwards, A., Avery, M., Grover, C.: "Autonomous Emergency
  Braking Test Results", 23rd ESV Conference, Seoul 2013, paper 13-0168 (the Thatcham /
  TRL test programme behind the Euro NCAP AEB protocols): production systems warn first
  (FCW), then brake partially, then fully within the last second or so before impact.
- Euro NCAP, "Test Protocol - AEB VRU systems" (cyclist / pedestrian targets; TTC
  defined as the remaining time before impact at constant speeds).
- UN ECE Regulation No. 152 (AEBS for M1/N1): the emergency braking phase decelerates
  the car by at least 5 m/s^2 (as summarised in Wikipedia, "Collision avoidance system").
Our defaults: FCW at TTC 2.6 s, partial braking at 1.6 s with 4 m/s^2 (~0.4 g), full
braking at 0.9 s with 8 m/s^2 (~0.8 g, the ego's full brake on dry asphalt). They are
our choice within that literature (the exact thresholds are manufacturer-specific and
not public) and every one is a sweepable parameter.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.errors import ConfigError
from vei.models import ego as ego_model
from vei.policy.base import PolicyAction
from vei.policy.builtin import ConfiguredPolicy, PIDCruise
from vei.policy.observation import Observation

FloatArray = npt.NDArray[np.float64]
#: AEB stages (fsm_state codes).
AEB_OFF, AEB_FCW, AEB_PARTIAL, AEB_FULL = 0, 1, 2, 3
#: Closing speeds below this [m/s] give TTC = +inf (nothing approaches).
MIN_CLOSING_SPEED_MPS = 0.1
#: Below this ego speed [m/s] a braking stage holds behind an object in the path even
#: though nothing closes in (the car has stopped; stand-still hold).
HOLD_SPEED_MPS = 0.5


@dataclass(frozen=True)
class AEBConfig:
    """Parameters of the ``aeb`` policy (all sweepable as ``ego.policy_params.<name>``).

    Attributes:
        ttc_warning_s: forward collision warning at TTC <= this [s].
        ttc_partial_s: partial braking at TTC <= this [s].
        ttc_full_s: full braking at TTC <= this [s]. Need warning >= partial >= full > 0.
        partial_decel_mps2: deceleration of partial braking [m/s^2] (> 0).
        full_decel_mps2: deceleration of full braking [m/s^2] (>= partial; the engine
            clips demands at the ego's ``max_decel_mps2``).
    """

    ttc_warning_s: float = 2.6
    ttc_partial_s: float = 1.6
    ttc_full_s: float = 0.9
    partial_decel_mps2: float = 4.0
    full_decel_mps2: float = 8.0

    def __post_init__(self) -> None:
        for name in (
            "ttc_warning_s", "ttc_partial_s", "ttc_full_s", "partial_decel_mps2", "full_decel_mps2"
        ):  # fmt: skip
            v = getattr(self, name)
            if (
                isinstance(v, bool)
                or not isinstance(v, int | float)
                or not math.isfinite(v)
                or v <= 0
            ):
                raise ConfigError(f"aeb.{name} must be a finite number > 0, got {v!r}")
        if not self.ttc_warning_s >= self.ttc_partial_s >= self.ttc_full_s:
            raise ConfigError(
                "aeb: need ttc_warning_s >= ttc_partial_s >= ttc_full_s, got "
                f"{self.ttc_warning_s}, {self.ttc_partial_s}, {self.ttc_full_s}"
            )
        if self.full_decel_mps2 < self.partial_decel_mps2:
            raise ConfigError("aeb.full_decel_mps2 must be >= aeb.partial_decel_mps2")


#: AEBConfig field -> VariantParams field.
AEB_PARAM_FIELDS: dict[str, str] = {
    "ttc_warning_s": "aeb_ttc_warning_s",
    "ttc_partial_s": "aeb_ttc_partial_s",
    "ttc_full_s": "aeb_ttc_full_s",
    "partial_decel_mps2": "aeb_partial_decel_mps2",
    "full_decel_mps2": "aeb_full_decel_mps2",
}


#: The order AEBConfig requires: (larger, smaller) field pairs.
AEB_ORDER: tuple[tuple[str, str], ...] = (
    ("ttc_warning_s", "ttc_partial_s"),
    ("ttc_partial_s", "ttc_full_s"),
    ("full_decel_mps2", "partial_decel_mps2"),
)


def check_aeb_order(
    values: Mapping[str, Any],
    n: int,
    label_of: Callable[[int], str] = lambda i: f"variant {i}",
    *,
    prefix: str = "aeb.",
) -> None:
    """The rule of :class:`AEBConfig` (warning >= partial >= full TTC, full >= partial
    deceleration) over a batch of variants, so that a sweep refuses what ``vei run`` does.

    Args:
        values: AEBConfig field -> [n] array or scalar (a fixed value for every variant).
        n: number of variants B.
        label_of: variant position -> its name in the message (only the first bad one
            is named).
        prefix: how the message spells a field (a sweep: 'ego.policy_params.').

    Raises:
        ConfigError: naming the first variant out of order, the two parameters and their
            values (and how many variants are).
    """
    v = {k: np.broadcast_to(np.asarray(values[k], dtype=np.float64), (n,)) for k in values}
    for hi, lo in AEB_ORDER:
        if hi not in v or lo not in v:
            continue
        bad = np.flatnonzero(v[hi] < v[lo])
        if bad.size:
            i = int(bad[0])
            more = f" (and {bad.size - 1} more variants)" if bad.size > 1 else ""
            raise ConfigError(
                f"{label_of(i)}: aeb needs {prefix}{hi} >= {prefix}{lo}, got "
                f"{v[hi][i]:g} < {v[lo][i]:g}{more}"
            )


def path_ttc(gap_m: FloatArray, rel_vx_mps: FloatArray, valid: npt.NDArray[np.bool_]) -> FloatArray:
    """Smallest time to collision [s] over the objects ahead in the path, [B].

    Per object ``gap / (-rel_vx)`` where the gap is finite, the object valid and it
    closes in (-rel_vx > MIN_CLOSING_SPEED_MPS), else +inf; gap 0 and closing gives 0.

    Args:
        gap_m, rel_vx_mps, valid: [B, N] (Observation.path_gap_m, rel_vx_mps, valid).
    """
    closing = -rel_vx_mps
    ok = valid & np.isfinite(gap_m) & (closing > MIN_CLOSING_SPEED_MPS)
    ttc = np.where(ok, np.where(ok, gap_m, 0.0) / np.where(ok, closing, 1.0), np.inf)
    return ttc.min(axis=1) if ttc.shape[1] else np.full(ttc.shape[0], np.inf)


def aeb_stage(
    prev_stage: npt.NDArray[np.int8],
    ttc_s: FloatArray,
    in_path: npt.NDArray[np.bool_],
    ttc_warning_s: Any,
    ttc_partial_s: Any,
    ttc_full_s: Any,
    v_mps: Any = 0.0,
) -> npt.NDArray[np.int8]:
    """The new AEB stage [B] (pure): thresholds on TTC; a braking stage holds while an
    object is in the path and either closes in (finite TTC) or the ego is (nearly)
    stopped (``v_mps < HOLD_SPEED_MPS``).

    Args:
        prev_stage: [B] int8 stage of the previous step. ttc_s: [B] from :func:`path_ttc`.
        in_path: [B] some valid object ahead in the corridor. ttc_*: [B] or scalars [s].
        v_mps: [B] or scalar ego speed [m/s].
    """
    raw = np.where(
        ttc_s <= ttc_full_s,
        AEB_FULL,
        np.where(
            ttc_s <= ttc_partial_s, AEB_PARTIAL, np.where(ttc_s <= ttc_warning_s, AEB_FCW, AEB_OFF)
        ),
    ).astype(np.int8)
    hold = (
        (prev_stage >= AEB_PARTIAL)
        & in_path
        & (np.isfinite(ttc_s) | (np.asarray(v_mps) < HOLD_SPEED_MPS))
    )
    return np.where(hold, np.maximum(prev_stage, raw), raw).astype(np.int8)


def aeb_decel(
    stage: npt.NDArray[np.int8], partial_decel_mps2: Any, full_decel_mps2: Any
) -> FloatArray:
    """Demanded acceleration [m/s^2] of a stage (0 where not braking)."""
    return np.where(
        stage == AEB_FULL,
        -np.asarray(full_decel_mps2, dtype=np.float64),
        np.where(stage == AEB_PARTIAL, -np.asarray(partial_decel_mps2, dtype=np.float64), 0.0),
    )


class AEB(ConfiguredPolicy):
    """TTC-based AEB with FCW and staged braking over PID cruise (see the module docstring).

    Args:
        config: AEBConfig, or its fields as keyword arguments (run config
            ``ego: {policy: aeb, policy_params: {ttc_full_s: 1.0}}``).
    """

    name = "aeb"
    CONFIG = AEBConfig
    PARAM_FIELDS = AEB_PARAM_FIELDS
    _EQ_FIELDS = ("p", "pid")

    def __init__(self, config: AEBConfig | None = None, **params: float) -> None:
        super().__init__(config, **params)
        self.pid = PIDCruise()

    def bind(self, params: Any) -> AEB:
        """A copy with the per-variant AEB / PID parameters of ``params`` (VariantParams)."""
        out = super().bind(params)
        out.pid = self.pid.bind(params)
        return out

    def init_state(self, batch_size: int) -> dict[str, Any]:
        """Stage 0, fresh PID."""
        return {"stage": np.zeros(batch_size, dtype=np.int8), "pid": None}

    def act(self, obs: Observation, state: dict[str, Any]) -> tuple[PolicyAction, dict[str, Any]]:
        """Stage from the TTC; braking demand or the PID command."""
        p = self.p
        ttc = path_ttc(obs.path_gap_m, obs.rel_vx_mps, obs.valid)
        in_path = (obs.valid & np.isfinite(obs.path_gap_m)).any(axis=1)
        prev = state["stage"]
        stage = aeb_stage(
            prev, ttc, in_path, p["ttc_warning_s"], p["ttc_partial_s"], p["ttc_full_s"],
            obs.ego_speed_mps,
        )  # fmt: skip
        u, pid = self.pid.command(obs, state["pid"])
        released = (prev >= AEB_PARTIAL) & (stage < AEB_PARTIAL)
        if released.any():  # back to cruise: restart the PID from the current error
            err = obs.cruise_speed_mps - obs.ego_speed_mps
            pid = ego_model.pid_reset_where(pid, released, err)
        braking = stage >= AEB_PARTIAL
        a_pid = ego_model.command_to_accel(u, obs.max_accel_mps2, obs.max_decel_mps2)
        acc = np.where(
            braking, aeb_decel(stage, p["partial_decel_mps2"], p["full_decel_mps2"]), a_pid
        )
        return PolicyAction(accel_mps2=acc, fsm_state=stage), {"stage": stage, "pid": pid}


__all__ = [
    "AEB",
    "AEBConfig",
    "AEB_FCW",
    "AEB_FULL",
    "AEB_OFF",
    "AEB_PARAM_FIELDS",
    "HOLD_SPEED_MPS",
    "AEB_ORDER",
    "AEB_PARTIAL",
    "check_aeb_order",
    "aeb_decel",
    "aeb_stage",
    "path_ttc",
]
