"""Configuration files (YAML or JSON) into the frozen dataclasses of :mod:`vei.config`.

:func:`load_config` reads a file or a mapping into any configuration class; unknown keys are
an error, and a key ``preset`` selects a named preset as the base that the other keys
override. :func:`config_to_dict` writes one back as a plain dict.
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Mapping
from dataclasses import fields, replace
from pathlib import Path
from typing import Any, TypeVar

from vei.config.behaviour import DecisionConfig, TrafficConfig
from vei.config.continuation import ContinuationConfig
from vei.config.metrics import MetricsConfig
from vei.config.models import KERNEL_POLICIES, SFM_PRESETS, CAPConfig, EgoConfig, SFMConfig
from vei.config.perception import PerceptionConfig
from vei.config.run import CASE_PRESETS, CaseConfig, RiderPopulationConfig, RunConfig, SimConfig
from vei.config.v2x import V2XConfig
from vei.errors import ConfigError

T = TypeVar("T")


_PRESETS_OF: dict[type, Mapping[str, Any]] = {SFMConfig: SFM_PRESETS, CaseConfig: CASE_PRESETS}


# --------------------------------------------------------------------------------------
# Loading
# --------------------------------------------------------------------------------------
def _build(cls: type[T], raw: Any, where: str) -> T:
    if isinstance(raw, cls):
        return raw
    if isinstance(raw, str) and cls in _PRESETS_OF:
        raw = {"preset": raw}
    if not isinstance(raw, Mapping):
        raise ConfigError(
            f"{where}: expected a mapping for {cls.__name__}, got {type(raw).__name__}"
        )
    raw = dict(raw)
    base: Any = None
    if "preset" in raw:
        presets = _PRESETS_OF.get(cls)
        name = raw.pop("preset")
        if presets is None:
            raise ConfigError(f"{where}: {cls.__name__} has no presets (key 'preset')")
        if name not in presets:
            raise ConfigError(
                f"{where}: unknown preset {name!r} for {cls.__name__}; expected one of {', '.join(presets)}"
            )
        base = presets[name]
        _check_speed_override(base, raw, where)
    known = {f.name: f for f in fields(cls)}  # type: ignore[arg-type]
    unknown = sorted(set(raw) - set(known))
    if unknown:
        raise ConfigError(
            f"{where}: unknown key(s) {', '.join(unknown)} for {cls.__name__}; "
            f"expected some of {', '.join(known)}"
        )
    kwargs: dict[str, Any] = {}
    nested = {
        "sfm": SFMConfig,
        "ego": EgoConfig,
        "cap": CAPConfig,
        "case": CaseConfig,
        "sim": SimConfig,
        "metrics": MetricsConfig,
        "continuation": ContinuationConfig,
        "decision": DecisionConfig,
        "traffic": TrafficConfig,
    }
    if cls is RunConfig:  # CaseConfig.rider is a string; RunConfig.rider a population
        nested["rider"] = RiderPopulationConfig
    if cls is CaseConfig and raw.get("perception") is not None:
        nested["perception"] = PerceptionConfig
    if cls is CaseConfig:
        nested["v2x"] = V2XConfig
    for key, value in raw.items():
        sub = nested.get(key)
        if sub is RiderPopulationConfig and value is None:  # explicit "no population"
            kwargs[key] = None
            continue
        if sub is not None:
            if (
                base is not None
                and isinstance(value, Mapping)
                and "preset" not in value
                and getattr(base, key) is not None
            ):
                value = _override(getattr(base, key), value, f"{where}.{key}")
            kwargs[key] = _build(sub, value, f"{where}.{key}")
        else:
            if (
                isinstance(value, int)
                and not isinstance(value, bool)
                and key.endswith(
                    (
                        "_s",
                        "_m",
                        "_mps",
                        "_mps2",
                        "_n",
                        "_kg",
                        "_nspm",
                        "_per_m",
                        "factor",
                        "kp",
                        "ki",
                        "kd",
                        "limit",
                    )
                )
            ):
                value = float(value)
            kwargs[key] = value
    try:
        out = replace(base, **kwargs) if base is not None else cls(**kwargs)
    except TypeError as exc:  # missing required field
        raise ConfigError(f"{where}: {exc}") from None
    except ConfigError as exc:
        raise ConfigError(f"{where}: {exc}") from None
    if isinstance(out, CaseConfig) and "ego_mode" in raw:
        _check_ego_mode_agrees(out, raw["ego_mode"], where)
    return out


def _check_ego_mode_agrees(case: CaseConfig, given: Any, where: str) -> None:
    """An ego_mode written next to ego.policy must be the one the policy implies ('pid'
    for 'none', 'cap' for 'paper-cap', 'policy' for any other): else the policy would
    silently win."""
    pol = case.ego.policy
    if pol is None:
        return
    implied = KERNEL_POLICIES.get(pol, "policy")
    if given != implied:
        raise ConfigError(
            f"{where}: ego_mode {given!r} disagrees with ego.policy {pol!r} (which runs as "
            f"ego_mode {implied!r}); drop ego_mode (the policy decides) or make them agree"
        )


def _check_speed_override(base_obj: Any, overrides: Mapping[str, Any], where: str) -> None:
    """A speed given over a rider that takes its speeds from the recording would be ignored
    silently (the calibrated default rider): refuse it unless speed_from_recording is said."""
    if not isinstance(base_obj, SFMConfig) or not base_obj.speed_from_recording:
        return
    given = sorted({"v0_mps", "max_speed_mps"} & set(overrides))
    if given and "speed_from_recording" not in overrides:
        raise ConfigError(
            f"{where}: {', '.join(given)} would be ignored: this rider takes its speeds from "
            "the recording (speed_from_recording: true, the calibrated default); add "
            "'speed_from_recording: false' to use the given speed, 'true' to keep it as the "
            "fallback of a rider that never moves, or start from 'preset: paper'"
        )


def _override(base_obj: Any, overrides: Mapping[str, Any], where: str) -> Any:
    cls = type(base_obj)
    _check_speed_override(base_obj, overrides, where)
    known = {f.name for f in fields(cls)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise ConfigError(f"{where}: unknown key(s) {', '.join(unknown)} for {cls.__name__}")
    current = {f.name: getattr(base_obj, f.name) for f in fields(cls)}
    merged = {**current, **overrides}
    return _build(cls, merged, where)


def load_config(source: str | Path | Mapping[str, Any], cls: type[T]) -> T:
    """Load a configuration of class ``cls`` from a YAML/JSON file or a mapping.

    Unknown keys (at any nesting level) raise ConfigError naming the key and the file. A
    key ``preset`` (for SFMConfig and CaseConfig) starts from that named preset; the other
    keys override it, nested sections key by key. A bare string for a CaseConfig/SFMConfig
    section names a preset.

    Args:
        source: path to a .yaml/.yml/.json file, or an already parsed mapping.
        cls: SFMConfig, EgoConfig, CAPConfig, SimConfig, CaseConfig or RunConfig.
    Returns:
        The validated, frozen configuration.
    """
    where = "config"
    if isinstance(source, str | Path):
        path = Path(source)
        where = str(path)
        if not path.is_file():
            raise ConfigError(f"{path}: configuration file not found")
        text = path.read_text(encoding="utf-8")
        try:
            if path.suffix.lower() == ".json":
                raw = json.loads(text)
            else:
                import yaml

                raw = yaml.safe_load(text)
        except (ValueError, ImportError) as exc:  # yaml.YAMLError subclasses Exception
            raise ConfigError(f"{path}: cannot parse: {exc}") from None
        except Exception as exc:  # noqa: BLE001 - yaml errors
            raise ConfigError(f"{path}: cannot parse: {exc}") from None
    else:
        raw = source
    if not dataclasses.is_dataclass(cls):
        raise ConfigError(f"{cls!r} is not a configuration class")
    return _build(cls, raw, where)


def config_to_dict(cfg: Any) -> dict[str, Any]:
    """A configuration as a plain (JSON-serialisable) dict; ``load_config`` reads it back."""
    return dataclasses.asdict(cfg)
