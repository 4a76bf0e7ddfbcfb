"""vei: vehicle-e-scooter interactions, from naturalistic recordings to risky closed-loop scenarios.

Public API (explicit, no star imports). Subpackages: io, datasets, geo, maps, recon,
models, sim, metrics, experiments, export, report, cli.
"""

from vei.errors import ConfigError, DependencyError, InputError, VeiError
from vei.geo.frame import Bounds, LocalFrame
from vei.types import AgentInfo, Interaction, InteractionMeta, Scenario

__version__ = "0.1.0"

__all__ = [
    "AgentInfo",
    "Bounds",
    "ConfigError",
    "DependencyError",
    "InputError",
    "Interaction",
    "InteractionMeta",
    "LocalFrame",
    "Scenario",
    "VeiError",
    "__version__",
]
