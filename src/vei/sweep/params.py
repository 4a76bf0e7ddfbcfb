"""Sweepable parameters: the catalogue (:data:`PARAMETERS`: kind, unit, bounds) and a
variant's run configuration (:func:`variant_config`).

A sweep parameter is named by its place in the run configuration (``vei run --config``):
the dotted path of the field under the configuration (``CaseConfig``), e.g.
``cap.t_safe_s``, ``sfm.k_des_nspm``, ``ego.policy``, and for a built-in policy's own
parameters ``ego.policy_params.<field of AEBConfig / IDMConfig>``. The same name is the
results' column. Two design parameters have no field of their own: ``time_shift_s`` (an
offset to the scenario's automatic shift, or the absolute shift, per the spec's
``time_shift_reference``; the run config's ``time_shift`` is the absolute value) and
``rider_model`` (replay / the SFM Normal / Aggressive preset: ``rider`` plus ``sfm``).
The spellings of earlier versions (:data:`RENAMED`) are refused with the new name.

Used by :mod:`vei.sweep.spec`, which re-exports these names.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol

import numpy as np

from vei.calibrate.columns import RIDER_PARAM_COLUMNS
from vei.config import CASE_PRESETS, SFM_PRESETS, RunConfig, validate_policy_spec
from vei.config.perception import PerceptionConfig
from vei.config.settings import SECTIONS, SETTINGS, Setting
from vei.config.v2x import V2XConfig
from vei.errors import ConfigError


class SpecLike(Protocol):
    """What :func:`variant_config` reads of a sweep spec (``SweepSpec`` has it)."""

    @property
    def base(self) -> str: ...

    @property
    def time_shift_reference(self) -> str: ...

    # Optional too: ``perception`` (a PerceptionConfig or None) and ``v2x`` (a V2XConfig
    # or None), read with getattr.


RIDER_MODELS: tuple[str, ...] = ("replay", "normal", "aggressive")


@dataclass(frozen=True)
class ParamDef:
    """What a sweepable parameter is: its kind and the values it may take.

    Attributes:
        name: dotted name: the field's path in the run configuration (e.g.
            ``sfm.k_des_nspm``), or a design parameter (``time_shift_s``, ``rider_model``).
        kind: 'float', 'bool', 'choice' (a string out of ``allowed``) or 'policy' (a
            built-in name out of ``allowed``, or a user policy 'package.module:Class' /
            'path/file.py:Class').
        lower, upper: open/closed physical bounds a float must respect (None = unbounded);
            ``lower_open`` / ``upper_open`` say whether the bound itself is excluded.
        allowed: the values a 'choice' parameter takes.
        unit: human-readable unit for documentation.
        doc: one line on what it is.
    """

    name: str
    kind: Literal["float", "bool", "choice", "policy"]
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
        if self.kind == "policy":
            if isinstance(value, str) and value in self.allowed:
                return value
            try:
                return validate_policy_spec(value)
            except ConfigError as exc:
                raise ConfigError(f"{where}: {self.name}: {exc}") from None
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


#: Run-config path of a policy's own parameters (``ego: {policy: aeb, policy_params: {..}}``).
POLICY_PARAMS_PREFIX = "ego.policy_params."

#: The sweep parameter that picks the ego's controller (a results column too).
POLICY_PARAM = "ego.policy"


def _param(s: Setting) -> ParamDef:
    """The sweep parameter of a sweepable setting: named by its run-config path, with its
    declared unit, bounds and description."""
    if s.field == "policy":
        from vei.config import BUILTIN_POLICIES

        return ParamDef(str(s.path), "policy", allowed=tuple(BUILTIN_POLICIES), doc=s.doc)
    if s.kind == "bool":
        return ParamDef(str(s.path), "bool", doc=s.doc)
    doc = f"{s.doc} ({s.policy} only)" if s.policy else s.doc
    return ParamDef(
        str(s.path), "float", lower=s.lower, upper=s.upper, lower_open=s.lower_open,
        upper_open=s.upper_open, unit=s.unit, doc=doc,
    )  # fmt: skip


#: Every parameter a sweep can vary, in the column order of the variants table: the two
#: design parameters, then the sweepable settings (vei.config.settings.SETTINGS) in their
#: declared order.
PARAMETERS: dict[str, ParamDef] = {
    p.name: p
    for p in (
        ParamDef(
            "time_shift_s",
            "float",
            unit="s",
            doc="design parameter: the run's `time_shift` is the automatic shift + this "
            "offset (`time_shift_reference: auto`) or this value (`zero`)",
        ),
        ParamDef(
            "rider_model",
            "choice",
            allowed=RIDER_MODELS,
            doc="design parameter: `rider: replay`, or `rider: sfm` with `sfm: normal` / "
            "`aggressive` (SFM_PRESETS, the calibrated riders; the paper's: `base: "
            "paper-normal-cap` without `rider_model`)",
        ),
        *(_param(s) for s in SETTINGS if s.sweep),
    )
}

#: Sweep parameter -> the VariantParams field its value sets (float parameters; the value
#: x k_des_factor for sfm.k_des_nspm, as the setting's conversion says).
SWEEP_FIELDS: dict[str, str] = {
    str(s.path): s.field for s in SETTINGS if s.sweep and s.kind == "float"
}

#: Sweep parameters of the built-in policies' configurations: name -> (policy, field).
POLICY_PARAMS: dict[str, tuple[str, str]] = {
    str(s.path): (str(s.policy), str(s.config_field))
    for s in SETTINGS
    if s.sweep and s.convert == "policy_param"
}

#: Sweep parameter -> (config section, field) of the run configuration's CaseConfig: the
#: name is the path (time shift, rider model and the policy aside).
CONFIG_FIELDS: dict[str, tuple[str, str]] = {
    str(s.path): (str(s.section), str(s.config_field))
    for s in SETTINGS
    if s.sweep and s.section in SECTIONS and s.convert != "policy_param" and s.kind != "object"
}

#: Spellings of earlier versions -> the parameter's name now (a spec using one is refused):
#: the settings' declared former names.
RENAMED: dict[str, str] = {old: str(s.path) for s in SETTINGS if s.sweep for old in s.former}
#: The markers around the generated parameter table of docs/sweeps.md.
TABLE_BEGIN = "<!-- parameters: generated by vei.sweep.params.parameter_table -->"
TABLE_END = "<!-- end of the generated parameter table -->"


def parameter_table() -> str:
    """The sweep parameters as a Markdown table (docs/sweeps.md holds it between
    :data:`TABLE_BEGIN` and :data:`TABLE_END`; a test checks that it is today's).

    One row per :data:`PARAMETERS` entry: name (= run-config path), unit, the values it
    takes (bounds or choices), the engine's VariantParams field and the description.
    """
    fields = {str(s.path): s for s in SETTINGS if s.sweep}
    lines = [
        "| parameter | unit | values | engine field | what it is |",
        "|---|---|---|---|---|",
    ]
    for name, p in PARAMETERS.items():
        s = fields.get(name)
        if p.kind == "float":
            values = s.bounds_text() if s is not None else "any"
        elif p.kind == "bool":
            values = "true / false"
        else:
            values = " / ".join(p.allowed) + (" / a user policy" if p.kind == "policy" else "")
        field = f"`{s.field}`" if s is not None else "(design parameter)"
        unit = p.unit or ("-" if p.kind != "bool" else "bool")
        lines.append(f"| `{name}` | {unit} | {values} | {field} | {p.doc} |")
    return "\n".join(lines) + "\n"


#: Earlier parameters whose setting is now another parameter: old name -> how to write it.
REPLACED: dict[str, str] = {
    "cap.enabled": "'ego.policy' (cap.enabled true = paper-cap, false = none)",
}


def parse_perception(raw: Any, where: str) -> PerceptionConfig | None:
    """A sweep spec's ``perception: {...}`` section -> PerceptionConfig (None when absent).

    The keys are those of the run configuration's ``case: {perception: ...}`` (the fields
    of :class:`vei.config.perception.PerceptionConfig`, same defaults: ``enabled: true``
    switches the model on).

    Raises:
        ConfigError: not a mapping, an unknown key or a bad value (naming ``where`` and
            the key).
    """
    from dataclasses import fields

    if raw is None:
        return None
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{where}: 'perception' must be a mapping like {{enabled: true, ...}}")
    known = [f.name for f in fields(PerceptionConfig)]
    unknown = sorted(set(map(str, raw)) - set(known))
    if unknown:
        raise ConfigError(
            f"{where}: perception: unknown key(s) {', '.join(unknown)}; expected some of "
            f"{', '.join(known)}"
        )
    vals = {
        k: float(v) if isinstance(v, int) and not isinstance(v, bool) and k != "seed" else v
        for k, v in raw.items()
    }
    try:
        return PerceptionConfig(**vals)
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None


def parse_v2x(raw: Any, where: str) -> V2XConfig | None:
    """A sweep spec's ``v2x: {...}`` section -> V2XConfig (None when absent).

    The keys are those of the run configuration's ``case: {v2x: ...}`` (the fields of
    :class:`vei.config.v2x.V2XConfig`, same defaults: ``enabled: true`` switches it on).

    Raises:
        ConfigError: not a mapping, an unknown key or a bad value (naming ``where`` and
            the key).
    """
    from vei.config.load import load_config

    if raw is None:
        return None
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{where}: 'v2x' must be a mapping like {{enabled: true, ...}}")
    try:
        return load_config(dict(raw), V2XConfig)
    except ConfigError as exc:
        raise ConfigError(f"{where}: v2x: {str(exc).removeprefix('config: ')}") from None


def parse_variation_section(raw: Any, where: str) -> tuple[tuple[str, Any], ...]:
    """A sweep spec's ``variation: {parameter: {dist: ...}}`` -> ((name,
    vei.config.distributions.Distribution), ...) in PARAMETERS order (float parameters
    whose distribution stays within their bounds; () when absent).

    Raises:
        ConfigError: not a mapping, an unknown or non-float parameter, an impossible
            distribution, one that leaves the parameter's bounds (naming ``where``).
    """
    from vei.config.distributions import parse_distribution

    if raw is None:
        return ()
    if not isinstance(raw, Mapping) or not raw:
        raise ConfigError(f"{where}: 'variation' must be a non-empty mapping of parameters")
    out = {}
    for key, val in raw.items():
        name = str(key)
        check_name(name, where)
        if name not in PARAMETERS or PARAMETERS[name].kind != "float":
            floats = [n for n, p in PARAMETERS.items() if p.kind == "float"]
            raise ConfigError(
                f"{where}: variation.{name}: expected a float parameter ({', '.join(floats)})"
            )
        dist = parse_distribution(val, f"{where}: variation.{name}")
        pdef = PARAMETERS[name]
        for v in (dist.low, dist.high) if not dist.is_fixed else (dist.value,):
            if np.isfinite(v):
                pdef.check(v, f"{where}: variation.{name}")
        for bound, v in ((pdef.lower, dist.low), (pdef.upper, dist.high)):
            if bound is not None and not np.isfinite(v) and not dist.is_fixed:
                raise ConfigError(
                    f"{where}: variation.{name} must stay within [{pdef.lower}, {pdef.upper}] "
                    f"[{pdef.unit}]: give the distribution min / max"
                )
        out[name] = dist
    order = list(PARAMETERS)
    return tuple(sorted(out.items(), key=lambda kv: order.index(kv[0])))


def parse_reconstruction(raw: Any, where: str) -> int | None:
    """``reconstruction: {samples: N}`` -> N (None when absent)."""
    if raw is None:
        return None
    if not isinstance(raw, Mapping):
        raise ConfigError(f"{where}: 'reconstruction' must be a mapping like {{samples: 200}}")
    unknown = set(map(str, raw)) - {"samples"}
    if unknown:
        raise ConfigError(
            f"{where}: reconstruction: unknown key(s) {', '.join(sorted(unknown))}; expected samples"
        )
    if "samples" not in raw:
        raise ConfigError(f"{where}: reconstruction: missing 'samples'")
    n = raw["samples"]
    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ConfigError(f"{where}: reconstruction.samples must be an integer >= 1, got {n!r}")
    return n


def check_v2x_spec(names: Any, v2x: Any, where: str) -> None:
    """A sweep spec's ``v2x`` is a V2XConfig or None, and swept ``v2x.*`` parameters need it
    enabled (they would change nothing otherwise).

    Raises:
        ConfigError: naming ``where`` and the parameters.
    """
    if v2x is not None and not isinstance(v2x, V2XConfig):
        raise ConfigError(f"{where}: v2x must be a V2XConfig or None")
    swept = [n for n in names if n.startswith("v2x.")]
    if swept and (v2x is None or not v2x.enabled):
        raise ConfigError(
            f"{where}: parameters {', '.join(swept)} need V2X: add 'v2x: {{enabled: true}}' "
            "to the spec"
        )


def resolve_policy(value: Any, where: str, base_dir: Path | None) -> Any:
    """A sweep's ``ego.policy`` value with a relative file path made absolute.

    ``path/file.py:Class`` with a relative path is taken relative to ``base_dir`` (the
    spec file's folder; the working directory when None) and written absolute, so the
    variants' run configurations find the file from anywhere. The class is loaded once
    here, so a missing file or class stops the spec before anything runs. Built-in names,
    ``package.module:Class`` and non-strings are returned as they are (checked later).

    Raises:
        ConfigError: the file or class cannot be loaded (naming ``where`` and the spec).
    """
    if not isinstance(value, str) or value in PARAMETERS[POLICY_PARAM].allowed:
        return value
    target, sep, cls = value.rpartition(":")
    if not sep or not target or not cls.isidentifier():
        return value  # ParamDef.check names the problem
    if target.endswith(".py") or "/" in target or "\\" in target:
        path = Path(target)
        if not path.is_absolute():
            path = (base_dir if base_dir is not None else Path.cwd()) / path
        value = f"{path.resolve()}:{cls}"
    from vei.policy.load import load_policy_class

    try:
        load_policy_class(value)
    except ConfigError as exc:
        raise ConfigError(f"{where}: parameters.{POLICY_PARAM}: {exc}") from None
    return value


def check_name(name: str, where: str) -> None:
    """Refuse a sweep parameter name of an earlier version, naming the new one.

    Raises:
        ConfigError: ``name`` is in :data:`RENAMED` or :data:`REPLACED`.
    """
    if name in RENAMED:
        raise ConfigError(f"{where}: sweep parameter '{name}' was renamed '{RENAMED[name]}'")
    if name in REPLACED:
        raise ConfigError(f"{where}: sweep parameter '{name}' was replaced by {REPLACED[name]}")


#: The sweep parameter whose largest value sets the continuations' reach (issue 22).
CRUISE_PARAM = "ego.cruise_speed_mps"
#: A drawn cruise speed's continuations reach for this quantile of its distribution (the
#: fast end of the sampled speeds, bar one sample in 1,000); vei risk uses it too.
REACH_QUANTILE = 0.999


def reach_speed_of(spec: SpecLike) -> float | None:
    """The largest cruise speed a sweep runs [m/s] (the range's max, the largest choice or
    the fixed value of ``ego.cruise_speed_mps``), None when the spec does not name it (the
    base configuration's 'median-moving'). Every road user's run-in and run-out reach
    beyond the car's reach at this speed (vei.config.ContinuationConfig.ego_speed_mps), in
    the sweep and in each variant's run configuration alike. A cruise speed drawn from a
    ``variation:`` distribution reaches for its 99.9 % quantile
    (:data:`REACH_QUANTILE`)."""
    if CRUISE_PARAM not in spec.names:
        return None
    drawn = dict(getattr(spec, "variation", ()) or ())
    if CRUISE_PARAM in drawn:
        dist = drawn[CRUISE_PARAM]
        return float(dist.ppf(REACH_QUANTILE)) if dist.resolved else None
    p = spec.param(CRUISE_PARAM)
    vals = [p.max] if p.is_range else (list(p.choices) if p.choices is not None else [p.value])
    nums = [float(v) for v in vals if isinstance(v, int | float) and not isinstance(v, bool)]
    return max(nums) if nums else None


def reach_sim(speed_mps: float | None) -> Any:
    """A SimConfig whose continuations reach for ``speed_mps`` (SimConfig() for None)."""
    from vei.config import ContinuationConfig, SimConfig

    if speed_mps is None:
        return SimConfig()
    return SimConfig(continuation=ContinuationConfig(ego_speed_mps=float(speed_mps)))


def variant_config(
    params: Mapping[str, Any],
    spec: SpecLike,
    *,
    auto_shift_s: float | None = None,
    name: str = "variant",
    reach_speed_mps: float | None = None,
) -> RunConfig:
    """The full run configuration of one variant (what ``vei run --config`` reads back).

    Starts from ``CASE_PRESETS[spec.base]`` (with the spec's ``perception`` and ``v2x``
    sections, if any, as its ``perception`` / ``v2x``; swept ``v2x.*`` set that section's
    fields); ``rider_model`` picks replay / the SFM Normal /
    Aggressive preset, then ``sfm.*``, ``ego.*`` and ``cap.*`` set the fields of those
    names (:data:`CONFIG_FIELDS`; ``sfm.k_des_nspm`` is the field k_des_nspm, so the
    configuration's ``k_des_factor``, 2 for the Aggressive presets, still multiplies it:
    the effective gain is value x factor); ``ego.policy`` picks the controller and the swept
    ``ego.policy_params.*`` of that policy go to its ``ego.policy_params`` (those of another
    policy are left out; a user policy ``module:Class`` / ``file.py:Class`` is built with
    its constructor's defaults). The time shift is ``auto_shift_s + time_shift_s`` (reference
    'auto') or ``time_shift_s`` (reference 'zero'), a missing ``time_shift_s`` counting as 0.

    Args:
        params: {dotted parameter name: value} of the variant.
        spec: the sweep spec (base and time-shift reference).
        auto_shift_s: the scenario's automatic shift [s] (required for reference 'auto').
        name: configuration name written into the result.
        reach_speed_mps: the speed its continuations reach for (the run configuration's
            ``sim.continuation.ego_speed_mps``); None = :func:`reach_speed_of` the spec.

    Raises:
        ConfigError: an invalid combination (e.g. a CAP braking beyond the car's brake).
    """
    from dataclasses import replace

    for key in params:
        check_name(key, name)
    base = CASE_PRESETS[spec.base]
    case = replace(base, name=name)
    perception = getattr(spec, "perception", None)
    if perception is not None:  # the spec's sensor model, for every variant
        case = replace(case, perception=perception)
    v2x = getattr(spec, "v2x", None)
    if v2x is not None:  # the spec's V2X, for every variant
        case = replace(case, v2x=v2x)
    rider = params.get("rider_model")
    if rider == "replay":
        case = replace(case, rider="replay")
    elif rider in ("normal", "aggressive"):
        case = replace(case, rider="sfm", sfm=SFM_PRESETS[str(rider)])
    sections: dict[str, dict[str, Any]] = {sec: {} for sec in SECTIONS}
    for key, (section, fname) in CONFIG_FIELDS.items():
        if key in params:
            v = params[key]
            sections[section][fname] = bool(v) if isinstance(v, bool | np.bool_) else float(v)
    if "v0_mps" in sections["sfm"]:  # a swept v0 is the rider's: not its recorded speed
        sections["sfm"]["speed_from_recording"] = False
    updates: dict[str, Any] = {
        sec: replace(getattr(case, sec), **vals) for sec, vals in sections.items() if vals
    }
    case = replace(case, **updates) if updates else case
    if POLICY_PARAM in params:  # the controller; its swept parameters go to policy_params
        pol = str(params[POLICY_PARAM])
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
    speed = reach_speed_mps if reach_speed_mps is not None else reach_speed_of(spec)
    return RunConfig(case=case, time_shift=shift, sim=reach_sim(speed))


def check_aeb_rows(variants: Any, base: str = "normal-cap") -> None:
    """Refuse variants whose AEB thresholds are out of order, as ``vei run`` does.

    Rows whose policy is 'aeb' (column ``ego.policy``, or else the base configuration's)
    take their swept ``ego.policy_params.*`` and the AEB defaults (or the base's
    policy_params) for the rest; :func:`vei.policy.aeb.check_aeb_order` checks them.

    Args:
        variants: [B] rows of a variants table (pandas; variant_id, variant_index and
            parameter columns).
        base: the spec's base configuration (CASE_PRESETS).
    Raises:
        ConfigError: naming the variant (id and row), the parameters and their values.
    """
    from vei.policy.aeb import AEB_PARAM_FIELDS, AEBConfig, check_aeb_order

    case = CASE_PRESETS[base]
    if POLICY_PARAM in variants.columns:
        rows = variants[variants[POLICY_PARAM].astype(str).to_numpy() == "aeb"]
    else:
        rows = variants if case.policy_name == "aeb" else variants.iloc[:0]
    if len(rows) == 0:
        return
    default = AEBConfig(**((case.ego.policy_params or {}) if case.policy_name == "aeb" else {}))
    values = {
        f: rows[c].to_numpy(np.float64)
        if (c := f"{POLICY_PARAMS_PREFIX}{f}") in rows
        else getattr(default, f)
        for f in AEB_PARAM_FIELDS
    }

    def label_of(i: int) -> str:
        row = rows.iloc[i]
        vid = row["variant_id"] if "variant_id" in row else "?"
        pos = row["variant_index"] if "variant_index" in row else rows.index[i]
        return f"variant {vid} (variant_index {pos})"

    check_aeb_order(values, len(rows), label_of, prefix=POLICY_PARAMS_PREFIX)
