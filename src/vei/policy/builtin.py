"""Built-in policies on the API: ``none`` (PID cruise) and ``paper-cap`` (the paper's CAP).

Both are vectorised numpy and take their per-variant parameters from the engine's
VariantParams at :meth:`bind` (so that sweeps vary them). In a run configuration the
names ``none`` and ``paper-cap`` run the engine's own compiled branches (ego_mode 'pid' /
'cap', numba kernel); these classes are the same controllers on the policy API (the
reference a user policy is compared with; a test shows ``PaperCAP`` through the API equals
the engine's CAP bit for bit on the NumPy path). Spell them ``vei.policy.builtin:PIDCruise``
/ ``vei.policy.builtin:PaperCAP`` to run them through the API.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt

from vei.models import ego as ego_model
from vei.policy.base import PolicyAction
from vei.policy.observation import Observation

FloatArray = npt.NDArray[np.float64]

#: VariantParams fields of the PID (EgoConfig).
PID_FIELDS = ("kp", "ki", "kd", "integral_limit", "integral_window_s")
#: VariantParams fields of the CAP (CAPConfig).
CAP_FIELDS = ("t_safe_s", "d_buf_m", "a_min_mps2", "release_margin_m", "recover_tolerance_mps")


def _pick(params: Any, names: tuple[str, ...]) -> dict[str, Any]:
    return {n: np.asarray(getattr(params, n)) for n in names}


def same_params(a: Any, b: Any) -> bool:
    """Equality of two policies' parameter dicts / values (arrays compared elementwise)."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(same_params(a[k], b[k]) for k in a)
    if isinstance(a, PIDCruise | PaperCAP) or isinstance(b, PIDCruise | PaperCAP):
        return a == b
    return bool(np.array_equal(np.asarray(a), np.asarray(b)))


def _frozen(value: Any) -> Any:
    """A hashable image of a parameter value: dicts as sorted (key, value) tuples, arrays
    as (shape, values) (so that equal parameters - :func:`same_params` - hash equal)."""
    if isinstance(value, dict):
        return tuple(sorted((k, _frozen(v)) for k, v in value.items()))
    if isinstance(value, _ParamEq):
        return value._key()
    arr = np.asarray(value)
    return (arr.shape, tuple(arr.ravel().tolist()))


class _ParamEq:
    """Built-in policies compare equal when of the same class with equal parameters, and
    equal ones hash equal (class + frozen parameters; the parameters are not changed after
    construction / bind). The engine does not rely on either: it groups variants into
    blocks by the identity of their policy instance (vei.sim.batch)."""

    _EQ_FIELDS: tuple[str, ...] = ()

    def _key(self) -> tuple[Any, ...]:
        return (type(self), tuple(_frozen(getattr(self, f)) for f in self._EQ_FIELDS))

    def __eq__(self, other: object) -> bool:
        if type(other) is not type(self):
            return NotImplemented
        return all(same_params(getattr(self, f), getattr(other, f)) for f in self._EQ_FIELDS)

    def __hash__(self) -> int:
        return hash(self._key())


class ConfiguredPolicy(_ParamEq):
    """Base of the built-in policies with a frozen parameter dataclass (``aeb``, ``idm``):
    built from that dataclass or its fields as keyword arguments; :meth:`bind` takes the
    per-variant values of the same fields from the engine's VariantParams (so that sweeps
    vary them).

    Subclasses set ``name``, ``CONFIG`` (the dataclass) and ``PARAM_FIELDS`` (dataclass
    field -> VariantParams field). ``self.p`` maps each dataclass field to its value
    (a scalar array; [b] after bind).

    Args:
        config: an instance of ``CONFIG``, or its fields as keyword arguments.
    """

    name = ""
    CONFIG: type = object
    PARAM_FIELDS: dict[str, str] = {}
    _EQ_FIELDS = ("p",)

    def __init__(self, config: Any = None, **params: float) -> None:
        from vei.errors import ConfigError

        kind = self.CONFIG.__name__
        if config is not None and params:
            raise ConfigError(
                f"{type(self).__name__}: give an {kind} or keyword parameters, not both"
            )
        if config is not None and not isinstance(config, self.CONFIG):
            raise ConfigError(f"{type(self).__name__}: config must be an {kind}")
        try:
            cfg = config or self.CONFIG(**params)
        except TypeError as exc:
            raise ConfigError(f"{self.name}: {exc}") from None
        self.config = cfg
        self.p = {f: np.asarray(getattr(cfg, f), dtype=np.float64) for f in self.PARAM_FIELDS}

    def bind(self, params: Any) -> Any:
        """A copy with the per-variant parameters of ``params`` (VariantParams [b])."""
        out = type(self).__new__(type(self))
        out.config = self.config
        out.p = {f: np.asarray(getattr(params, vp)) for f, vp in self.PARAM_FIELDS.items()}
        return out


class PIDCruise(_ParamEq):
    """PID speed control to the cruise speed v_d, no avoidance (the ``none`` policy).

    The paper's PID (EgoConfig: kp = ki = kd = 0.05, leaky integral) on e = v_d - v,
    producing a command u in [-1, 1]. State: ``(integral_m [B], prev_error_mps [B])``;
    the previous error starts at 0 like the engine's.

    Args:
        gains: optional mapping of PID_FIELDS to scalars ([B] arrays after bind); unset
            fields default to EgoConfig's.
    """

    name = "none"
    _EQ_FIELDS = ("p",)

    def __init__(self, **gains: float) -> None:
        from vei.config import EgoConfig

        d = EgoConfig()
        base = {
            "kp": d.kp, "ki": d.ki, "kd": d.kd, "integral_limit": d.integral_limit,
            "integral_window_s": np.inf if d.integral_window_s is None else d.integral_window_s,
        }  # fmt: skip
        unknown = set(gains) - set(base)
        if unknown:
            from vei.errors import ConfigError

            raise ConfigError(f"PIDCruise: unknown parameter(s) {', '.join(sorted(unknown))}")
        base.update(gains)
        self.p = {k: np.asarray(v, dtype=np.float64) for k, v in base.items()}

    def bind(self, params: Any) -> PIDCruise:
        """A copy with the per-variant PID gains of ``params`` (VariantParams [b])."""
        out = PIDCruise.__new__(PIDCruise)
        out.p = _pick(params, PID_FIELDS)
        return out

    def init_state(self, batch_size: int) -> None:
        """None: the first step starts the PID with zero integral and previous error =
        the first error (no derivative kick), like the engine's initial state."""
        return None

    def command(
        self, obs: Observation, pid: ego_model.PIDState | None
    ) -> tuple[FloatArray, ego_model.PIDState]:
        """One PID step: (u [B], new PIDState)."""
        p = self.p
        err = obs.cruise_speed_mps - obs.ego_speed_mps
        if pid is None:
            pid = ego_model.PIDState.initial(err)
        return ego_model.pid_step(
            pid,
            err,
            obs.dt_s,
            p["kp"],
            p["ki"],
            p["kd"],
            p["integral_limit"],
            p["integral_window_s"],
        )

    def act(
        self, obs: Observation, state: ego_model.PIDState | None
    ) -> tuple[PolicyAction, ego_model.PIDState]:
        """PID command to the cruise speed."""
        u, new = self.command(obs, state)
        return PolicyAction(command=u), new


class PaperCAP(_ParamEq):
    """The paper's collision-avoidance planner (CRUISE / BRAKE / RECOVER) on the API.

    The same formulas and order as the engine's CAP branch (vei.sim.step): trigger when
    object 0 (the primary rider) is ahead in the path corridor (``path_gap_m`` finite) and
    its gap d < d_safe(v) (:func:`vei.models.ego.cap_step`); BRAKE demands the gap law
    ``-v^2 / (2 (d - d_buf))`` saturated at a_min (or the paper's per-step law); PID to
    v_d otherwise, reset when BRAKE -> RECOVER. fsm_state = the CAP state (0, 1, 2).

    Args:
        paper_per_step: the braking law 'paper_per_step' instead of 'gap'.
    """

    name = "paper-cap"
    _EQ_FIELDS = ("cap", "paper_per_step", "pid")

    def __init__(self, paper_per_step: bool = False) -> None:
        from vei.config import CAPConfig

        c = CAPConfig()
        self.cap = {n: np.asarray(getattr(c, n)) for n in CAP_FIELDS}
        self.paper_per_step: Any = bool(paper_per_step)
        self.pid = PIDCruise()

    def bind(self, params: Any) -> PaperCAP:
        """A copy with the per-variant CAP and PID parameters of ``params``."""
        out = PaperCAP.__new__(PaperCAP)
        out.cap = _pick(params, CAP_FIELDS)
        pps = np.asarray(params.paper_per_step, dtype=bool)
        out.paper_per_step = bool(pps[0]) if pps.all() or not pps.any() else pps
        out.pid = self.pid.bind(params)
        return out

    def init_state(self, batch_size: int) -> dict[str, Any]:
        """CRUISE, fresh PID."""
        return {"cap": np.zeros(batch_size, dtype=np.int8), "pid": self.pid.init_state(batch_size)}

    def act(self, obs: Observation, state: dict[str, Any]) -> tuple[PolicyAction, dict[str, Any]]:
        """One CAP tick and the PID; returns the command u and the CAP state."""
        c = self.cap
        v = obs.ego_speed_mps
        vd = obs.cruise_speed_mps
        err = vd - v
        gap = obs.path_gap_m[:, 0]
        ahead = np.isfinite(gap)
        cap_state = state["cap"]
        pid = state["pid"]
        new_cap, a_brake, braking, entered = ego_model.cap_step(
            cap_state, v, vd, ahead, gap,
            t_safe_s=c["t_safe_s"], d_buf_m=c["d_buf_m"], a_min_mps2=c["a_min_mps2"],
            release_margin_m=c["release_margin_m"], recover_tolerance_mps=c["recover_tolerance_mps"],
            paper_per_step=self.paper_per_step,
        )  # fmt: skip
        coll = obs.collided
        cap_state = np.where(coll, cap_state, new_cap) if coll.any() else new_cap
        if pid is None:
            pid = ego_model.PIDState.initial(err)
        if entered.any():
            pid = ego_model.pid_reset_where(pid, entered, err)
        u, pid = self.pid.command(obs, pid)
        if braking.any():
            u = np.where(
                braking,
                ego_model.accel_to_command(a_brake, obs.max_accel_mps2, obs.max_decel_mps2),
                u,
            )
        return PolicyAction(command=u, fsm_state=cap_state), {"cap": cap_state, "pid": pid}


__all__ = [
    "CAP_FIELDS",
    "PID_FIELDS",
    "ConfiguredPolicy",
    "PIDCruise",
    "PaperCAP",
    "same_params",
]
