"""Sweepable parameters: the catalogue (:data:`PARAMETERS`: kind, unit, bounds) and a
variant's run configuration (:func:`variant_config`).

Used by :mod:`vei.experiments.sweep_spec`, which re-exports these names.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from vei.calibrate.population import RIDER_PARAM_COLUMNS
from vei.config import CASE_PRESETS, SFM_PRESETS, RunConfig
from vei.errors import ConfigError

if TYPE_CHECKING:
    from vei.experiments.sweep_spec import SweepSpec

RIDER_MODELS: tuple[str, ...] = ("replay", "normal", "aggressive")


@dataclass(frozen=True)
class ParamDef:
    """What a sweepable parameter is: its kind and the values it may take.

    Attributes:
        name: dotted name (e.g. ``sfm.k_des``).
        kind: 'float', 'bool' or 'choice' (a string out of ``allowed``).
        lower, upper: open/closed physical bounds a float must respect (None = unbounded);
            ``lower_open`` / ``upper_open`` say whether the bound itself is excluded.
        allowed: the values a 'choice' parameter takes.
        unit: human-readable unit for documentation.
        doc: one line on what it is.
    """

    name: str
    kind: Literal["float", "bool", "choice"]
    lower: float | None = None
    upper: float | None = None
    lower_open: bool = False
    upper_open: bool = False
    allowed: tuple[str, ...] = ()
    unit: str = ""
    doc: str = ""

    def check(self, value: Any, where: str) -> Any:
        """Validate one value and return it normalised (float / bool / str)."""
        if self.kind == "bool":
            if not isinstance(value, bool | np.bool_):
                raise ConfigError(f"{where}: {self.name} expects true or false, got {value!r}")
            return bool(value)
        if self.kind == "choice":
            if not isinstance(value, str) or value not in self.allowed:
                raise ConfigError(
                    f"{where}: {self.name} expects one of {', '.join(self.allowed)}, got {value!r}"
                )
            return value
        if isinstance(value, bool) or not isinstance(value, int | float | np.integer | np.floating):
            raise ConfigError(f"{where}: {self.name} expects a number [{self.unit}], got {value!r}")
        v = float(value)
        if not math.isfinite(v):
            raise ConfigError(f"{where}: {self.name} must be finite, got {value!r}")
        if self.lower is not None and (v < self.lower or (self.lower_open and v == self.lower)):
            op = ">" if self.lower_open else ">="
            raise ConfigError(f"{where}: {self.name} must be {op} {self.lower:g}, got {v:g}")
        if self.upper is not None and (v > self.upper or (self.upper_open and v == self.upper)):
            op = "<" if self.upper_open else "<="
            raise ConfigError(f"{where}: {self.name} must be {op} {self.upper:g}, got {v:g}")
        return v


def _f(name: str, unit: str, doc: str, **kw: Any) -> ParamDef:
    return ParamDef(name=name, kind="float", unit=unit, doc=doc, **kw)


#: Every parameter a sweep can vary, in the column order of the variants table.
PARAMETERS: dict[str, ParamDef] = {
    p.name: p
    for p in (
        _f("time_shift_s", "s", "time shift of the primary rider (see time_shift_reference)"),
        ParamDef(
            "rider_model",
            "choice",
            allowed=RIDER_MODELS,
            doc="primary rider: kinematic replay, SFM normal or SFM aggressive",
        ),
        _f("sfm.k_des", "N s/m", "desired-velocity gain", lower=0.0, lower_open=True),
        _f("sfm.A", "N", "vehicle repulsion amplitude", lower=0.0),
        _f("sfm.b", "1/m", "vehicle repulsion decay rate", lower=0.0, lower_open=True),
        _f("sfm.v0", "m/s", "rider's nominal desired speed", lower=0.0, lower_open=True),
        _f("sfm.mass", "kg", "rider + e-scooter mass", lower=0.0, lower_open=True),
        ParamDef("sfm.vehicle_force", "bool", doc="apply the vehicle repulsion force f_veh"),
        _f("ego.cruise_speed_mps", "m/s", "ego PID cruise speed v_d", lower=0.0, lower_open=True),
        ParamDef("cap.enabled", "bool", doc="collision-avoidance planner on (else PID cruise)"),
        _f("cap.T_safe_s", "s", "CAP time headway T_safe", lower=0.0, lower_open=True),
        _f("cap.d_buf_m", "m", "CAP standstill buffer d_buf", lower=0.0),
        _f("cap.a_min_mps2", "m/s^2", "CAP maximum braking (negative)", upper=0.0, upper_open=True),
        _f("perception_delay_s", "s", "delay before the CAP sees the rider", lower=0.0),
        ParamDef(
            "policy",
            "choice",
            allowed=("none", "paper-cap", "aeb", "idm"),
            doc="ego policy (vei.policy; replaces cap.enabled: none = PID, paper-cap = CAP)",
        ),
        _f(
            "aeb.ttc_warning_s",
            "s",
            "AEB forward collision warning TTC",
            lower=0.0,
            lower_open=True,
        ),
        _f("aeb.ttc_partial_s", "s", "AEB partial braking TTC", lower=0.0, lower_open=True),
        _f("aeb.ttc_full_s", "s", "AEB full braking TTC", lower=0.0, lower_open=True),
        _f(
            "aeb.partial_decel_mps2",
            "m/s^2",
            "AEB partial braking deceleration",
            lower=0.0,
            lower_open=True,
        ),
        _f(
            "aeb.full_decel_mps2",
            "m/s^2",
            "AEB full braking deceleration",
            lower=0.0,
            lower_open=True,
        ),
        _f("idm.max_accel_mps2", "m/s^2", "IDM maximum acceleration a", lower=0.0, lower_open=True),
        _f(
            "idm.comfort_decel_mps2",
            "m/s^2",
            "IDM comfortable deceleration b",
            lower=0.0,
            lower_open=True,
        ),
        _f("idm.time_headway_s", "s", "IDM desired time headway T", lower=0.0),
        _f("idm.min_gap_m", "m", "IDM jam distance s0", lower=0.0),
    )
}

#: Sweep parameters of the built-in policies' configurations: name -> (policy, field).
POLICY_PARAMS: dict[str, tuple[str, str]] = {
    name: (name.split(".")[0], name.split(".", 1)[1])
    for name in PARAMETERS
    if name.startswith(("aeb.", "idm."))
}


#: Sweep parameter -> (config section, field) of vei.config (time shift and rider model aside).
CONFIG_FIELDS: dict[str, tuple[str, str]] = {
    "sfm.k_des": ("sfm", "k_des_nspm"),
    "sfm.A": ("sfm", "a_veh_n"),
    "sfm.b": ("sfm", "b_veh_per_m"),
    "sfm.v0": ("sfm", "v0_mps"),
    "sfm.mass": ("sfm", "mass_kg"),
    "sfm.vehicle_force": ("sfm", "use_vehicle_force"),
    "ego.cruise_speed_mps": ("ego", "cruise_speed_mps"),
    "cap.T_safe_s": ("cap", "t_safe_s"),
    "cap.d_buf_m": ("cap", "d_buf_m"),
    "cap.a_min_mps2": ("cap", "a_min_mps2"),
    "perception_delay_s": ("cap", "perception_delay_s"),
}


def variant_config(
    params: Mapping[str, Any],
    spec: SweepSpec,
    *,
    auto_shift_s: float | None = None,
    name: str = "variant",
) -> RunConfig:
    """The full run configuration of one variant (what ``vei run --config`` reads back).

    Starts from ``CASE_PRESETS[spec.base]``; ``rider_model`` picks replay / the SFM Normal /
    Aggressive preset, then ``sfm.*`` override its fields (``sfm.k_des`` is k_des_nspm:
    the Aggressive preset's k_des_factor still multiplies it); ``cap.enabled`` picks ego mode
    'cap' or 'pid'; ``policy`` picks the ego policy (the swept ``aeb.*`` / ``idm.*`` of that
    policy go to ``ego.policy_params``); the other parameters map by :data:`CONFIG_FIELDS`. The time shift is
    ``auto_shift_s + time_shift_s`` (reference 'auto') or ``time_shift_s`` (reference 'zero'),
    a missing ``time_shift_s`` counting as 0.

    Args:
        params: {dotted parameter name: value} of the variant.
        spec: the sweep spec (base and time-shift reference).
        auto_shift_s: the scenario's automatic shift [s] (required for reference 'auto').
        name: configuration name written into the result.

    Raises:
        ConfigError: an invalid combination (e.g. a CAP braking beyond the car's brake).
    """
    from dataclasses import replace

    base = CASE_PRESETS[spec.base]
    case = replace(base, name=name)
    rider = params.get("rider_model")
    if rider == "replay":
        case = replace(case, rider="replay")
    elif rider in ("normal", "aggressive"):
        case = replace(case, rider="sfm", sfm=SFM_PRESETS[str(rider)])
    sections: dict[str, dict[str, Any]] = {"sfm": {}, "ego": {}, "cap": {}}
    for key, (section, fname) in CONFIG_FIELDS.items():
        if key in params:
            v = params[key]
            sections[section][fname] = bool(v) if isinstance(v, bool | np.bool_) else float(v)
    if "v0_mps" in sections["sfm"]:  # a swept v0 is the rider's: not its recorded speed
        sections["sfm"]["speed_from_recording"] = False
    updates: dict[str, Any] = {
        sec: replace(getattr(case, sec), **vals) for sec, vals in sections.items() if vals
    }
    if "cap.enabled" in params:
        if "policy" in params:
            raise ConfigError(
                "a sweep gives cap.enabled or policy, not both (policy: none | paper-cap | ...)"
            )
        updates["ego_mode"] = "cap" if bool(params["cap.enabled"]) else "pid"
    case = replace(case, **updates) if updates else case
    if "policy" in params:  # the controller; its swept parameters go to policy_params
        pol = str(params["policy"])
        pp = {
            f: float(params[k])
            for k, (owner, f) in POLICY_PARAMS.items()
            if owner == pol and k in params
        }
        ego_mode = "pid" if case.ego_mode in ("policy", "replay-speed") else case.ego_mode
        case = replace(
            case, ego_mode=ego_mode, ego=replace(case.ego, policy=pol, policy_params=pp or None)
        )
    rider_vals = {f: float(params[c]) for c, f in RIDER_PARAM_COLUMNS.items() if c in params}
    if rider_vals and case.rider == "sfm":  # a population rider: its own SFM parameters
        case = replace(case, sfm=replace(case.sfm, speed_from_recording=False, **rider_vals))
    offset = float(params.get("time_shift_s", 0.0))
    if spec.time_shift_reference == "auto":
        if auto_shift_s is None:
            raise ConfigError("time_shift_reference 'auto' needs the scenario's automatic shift")
        shift = float(auto_shift_s) + offset
    else:
        shift = offset
    return RunConfig(case=case, time_shift=shift)
