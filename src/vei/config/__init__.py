"""Every setting of vei, declared once: frozen dataclasses validated on construction, named
presets, the settings table, and files read into them.

- :mod:`vei.config.models`: the rider (social forces), the ego (path, PID, actuator,
  policy) and the collision-avoidance planner; the paper's values as defaults.
- :mod:`vei.config.run`: the engine (:class:`SimConfig`), the named configurations
  (:class:`CaseConfig`, :data:`CASE_PRESETS`), rider populations, :class:`RunConfig`.
- :mod:`vei.config.metrics`, :mod:`vei.config.perception`: the metrics' and the sensor
  model's settings; :mod:`vei.config.v2x`: V2X (riders' messages, channel, the car's
  tracks).
- :mod:`vei.config.settings`: the table of every sweepable setting (unit, bounds, path).
- :mod:`vei.config.load`: YAML/JSON files into any of them (unknown keys are errors).

``from vei.config import X`` is the public place of every name below. The package imports
nothing of vei but vei.errors and vei.types (DESIGN.md, dependency direction).
"""

from vei.config.behaviour import DecisionConfig, TrafficConfig
from vei.config.continuation import ContinuationConfig
from vei.config.load import config_to_dict, load_config
from vei.config.metrics import MetricsConfig
from vei.config.models import (
    AGGRESSIVE_K_DES_FACTOR,
    AUTO,
    BUILTIN_POLICIES,
    CALIBRATED_SFM,
    KERNEL_POLICIES,
    MAX_RUN_UP_M,
    MEDIAN_MOVING,
    PAPER_CRUISE_SPEED_MPS,
    PAPER_SFM,
    SFM_PRESETS,
    BrakingLaw,
    CAPConfig,
    DesiredVelocityForm,
    EgoConfig,
    EgoMode,
    InfluentialPoint,
    RiderModel,
    SFMConfig,
    validate_policy_spec,
)
from vei.config.perception import PerceptionConfig
from vei.config.run import (
    CASE_PRESETS,
    PAPER_CASES,
    CaseConfig,
    RiderPopulationConfig,
    RunConfig,
    SimConfig,
    case_preset,
)
from vei.config.v2x import V2XConfig

__all__ = [
    "AGGRESSIVE_K_DES_FACTOR",
    "AUTO",
    "BUILTIN_POLICIES",
    "CALIBRATED_SFM",
    "CASE_PRESETS",
    "KERNEL_POLICIES",
    "MAX_RUN_UP_M",
    "MEDIAN_MOVING",
    "PAPER_CASES",
    "PAPER_CRUISE_SPEED_MPS",
    "PAPER_SFM",
    "SFM_PRESETS",
    "BrakingLaw",
    "CAPConfig",
    "CaseConfig",
    "ContinuationConfig",
    "DecisionConfig",
    "DesiredVelocityForm",
    "EgoConfig",
    "EgoMode",
    "InfluentialPoint",
    "MetricsConfig",
    "PerceptionConfig",
    "RiderModel",
    "RiderPopulationConfig",
    "RunConfig",
    "SFMConfig",
    "SimConfig",
    "TrafficConfig",
    "V2XConfig",
    "case_preset",
    "config_to_dict",
    "load_config",
    "validate_policy_spec",
]
