"""The ego policy interface: a pure, batched map from an Observation to a demand.

A policy decides the ego's longitudinal motion (the ego always follows its recorded path;
the engine steers). Each engine step the engine builds an
:class:`~vei.policy.observation.Observation` of the B variants the policy drives and calls::

    action, state = policy.act(obs, state)

``state`` is the policy's own memory (anything: ``None``, an array ``[B]``, a dict of
arrays ``[B]``), created by ``policy.init_state(B)`` and threaded through by the engine;
``act`` must not mutate it (return a new one). The demand is applied through the ego's
actuator: clipped to ``[-max_decel, max_accel]``, first-order lag ``actuator_lag_s``,
``v' = max(0, v + a dt)``. After a collision the engine freezes the variant whatever the
demand is.

Optional: ``bind(params) -> Policy``. The engine calls it once per block of variants
with that block's :class:`vei.sim.params.VariantParams` (every field an array ``[b]``)
before ``init_state``; built-in policies take their (sweepable) per-variant parameters
from it. A policy without ``bind`` is used as is.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np
import numpy.typing as npt

from vei.errors import ConfigError
from vei.policy.observation import Observation

FloatArray = npt.NDArray[np.float64]
PolicyState = Any


@dataclass(frozen=True)
class PolicyAction:
    """A policy's demand for B variants: exactly one of ``accel_mps2`` and ``command``.

    Attributes:
        accel_mps2: [B] demanded longitudinal acceleration [m/s^2] (clipped by the engine
            to [-max_decel_mps2, max_accel_mps2]).
        command: [B] throttle / brake command u in [-1, 1] like CARLA's VehicleControl
            (u >= 0: throttle u -> u * max_accel; u < 0: brake -> u * max_decel).
        fsm_state: optional [B] int8 state of the policy (recorded in the results'
            ``cap_state`` series, for the figures); None records 0.
    """

    accel_mps2: FloatArray | None = None
    command: FloatArray | None = None
    fsm_state: npt.NDArray[np.int8] | None = None

    def __post_init__(self) -> None:
        if (self.accel_mps2 is None) == (self.command is None):
            raise ConfigError("PolicyAction needs exactly one of accel_mps2 and command")

    def checked(self, batch_size: int, where: str) -> PolicyAction:
        """This action with float64 [B] arrays; ConfigError naming ``where`` if malformed."""
        out: dict[str, Any] = {}
        for name in ("accel_mps2", "command", "fsm_state"):
            v = getattr(self, name)
            if v is None:
                out[name] = None
                continue
            arr = np.asarray(v, dtype=np.int8 if name == "fsm_state" else np.float64)
            if arr.ndim == 0:
                arr = np.full(batch_size, arr)
            if arr.shape != (batch_size,):
                raise ConfigError(
                    f"{where}: action.{name} has shape {arr.shape}, expected ({batch_size},)"
                )
            if name != "fsm_state" and not np.all(np.isfinite(arr)):
                bad = np.flatnonzero(~np.isfinite(arr))
                shown = ", ".join(f"{j} ({arr[j]})" for j in bad[:5])
                more = f" and {bad.size - 5} more" if bad.size > 5 else ""
                raise ConfigError(
                    f"{where}: action.{name} has NaN or infinite values in variant(s) "
                    f"{shown}{more} of the block's {batch_size}"
                )
            out[name] = arr
        return PolicyAction(**out)


@runtime_checkable
class Policy(Protocol):
    """A batched ego policy (see the module docstring)."""

    def init_state(self, batch_size: int) -> PolicyState:
        """The policy's memory for ``batch_size`` variants at t = 0."""
        ...

    def act(self, obs: Observation, state: PolicyState) -> tuple[PolicyAction, PolicyState]:
        """The demand for the B variants of ``obs`` and the new memory (pure)."""
        ...


class PerVariantPolicy:
    """Adapter: write ``act_one(obs_i) -> accel [m/s^2]`` as plain per-variant Python.

    Subclass it and implement :meth:`act_one`; ``obs_i`` is :meth:`Observation.variant`
    (scalars and [N] arrays). Optionally override :meth:`init_one` for a per-variant
    memory, then ``act_one(obs_i, memory)`` returns ``(accel, new_memory)``. A Python
    loop over the variants: fine for a few variants, slow for large batches (write a
    vectorised :class:`Policy` there).
    """

    #: True when act_one takes and returns a per-variant memory.
    stateful: bool = False

    def init_one(self) -> Any:
        """Per-variant memory at t = 0 (stateful policies)."""
        return None

    def act_one(self, obs: Any, *memory: Any) -> Any:  # pragma: no cover - interface
        """Demanded acceleration [m/s^2] of one variant (and the new memory if stateful)."""
        raise NotImplementedError

    def init_state(self, batch_size: int) -> list[Any]:
        """One per-variant memory per variant."""
        return [self.init_one() for _ in range(batch_size)]

    def act(self, obs: Observation, state: list[Any]) -> tuple[PolicyAction, list[Any]]:
        """Loops :meth:`act_one` over the variants."""
        b = obs.batch_size
        acc = np.empty(b)
        new = list(state)
        for i in range(b):
            if self.stateful:
                a, new[i] = self.act_one(obs.variant(i), state[i])
            else:
                a = self.act_one(obs.variant(i))
            acc[i] = float(a)
        return PolicyAction(accel_mps2=acc), new


def check_policy(obj: Any, spec: str) -> Policy:
    """``obj`` if it implements the Policy interface, else a ConfigError naming ``spec``."""
    missing = [m for m in ("init_state", "act") if not callable(getattr(obj, m, None))]
    if missing:
        raise ConfigError(
            f"policy {spec!r}: {type(obj).__name__} does not implement the policy interface "
            f"(missing {', '.join(missing)}; see vei.policy.base.Policy)"
        )
    return obj


__all__ = ["PerVariantPolicy", "Policy", "PolicyAction", "PolicyState", "check_policy"]
