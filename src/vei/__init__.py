"""vei: vehicle-e-scooter interactions, from naturalistic recordings to risky closed-loop scenarios.

Public API (explicit, no star imports). Subpackages: io, datasets, geo, maps, recon,
config, models, policy, sim, metrics, sweep, experiments, calibrate, catalogue, export,
report, cli.
"""

from vei import _moved
from vei.errors import ConfigError, DependencyError, InputError, VeiError
from vei.geo.frame import Bounds, LocalFrame
from vei.types import AgentInfo, Interaction, InteractionMeta, Scenario

__version__ = "0.1.0"

_moved.install()  # old module names of round 3's moves, for one release

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
