"""Configuration of the safety metrics (TTC zone thresholds and the TTC's scope).

The paper (Section III-E) partitions the time-to-collision series by the "two-second
rule": safe TTC > 2 s, attention 1 < TTC <= 2 s, alert 0 < TTC <= 1 s, collision. Those
are the defaults here.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Literal

from vei.errors import ConfigError

TtcScope = Literal["ahead", "all"]


@dataclass(frozen=True)
class MetricsConfig:
    """Thresholds and choices of the metrics.

    Attributes:
        safe_ttc_s: TTC above which a step is in the safe zone [s] (paper: 2 s).
        alert_ttc_s: TTC at or below which a step is in the alert zone [s] (paper: 1 s);
            between the two thresholds lies the attention zone.
        ttc_scope: 'ahead' (default): the paper's TTC = D / v_veh is defined only while the
            other road user's centre is ahead of the ego's centre along the ego's heading
            (the ego, driving forward, cannot run into a road user behind it; behind -> TTC
            = inf, safe); 'all': the literal formula at every step, whatever the bearing.
        min_speed_mps: ego speeds at or below this count as standing [m/s]: TTC = inf.
    """

    safe_ttc_s: float = 2.0
    alert_ttc_s: float = 1.0
    ttc_scope: TtcScope = "ahead"
    min_speed_mps: float = 1e-3

    def __post_init__(self) -> None:
        for name in ("safe_ttc_s", "alert_ttc_s", "min_speed_mps"):
            value = getattr(self, name)
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not math.isfinite(value)
            ):
                raise ConfigError(f"MetricsConfig.{name} must be a finite number, got {value!r}")
        if self.alert_ttc_s <= 0:
            raise ConfigError(f"MetricsConfig.alert_ttc_s must be > 0 s, got {self.alert_ttc_s}")
        if self.safe_ttc_s <= self.alert_ttc_s:
            raise ConfigError(
                f"MetricsConfig.safe_ttc_s ({self.safe_ttc_s} s) must exceed alert_ttc_s "
                f"({self.alert_ttc_s} s)"
            )
        if self.min_speed_mps < 0:
            raise ConfigError(f"MetricsConfig.min_speed_mps must be >= 0, got {self.min_speed_mps}")
        if self.ttc_scope not in ("ahead", "all"):
            raise ConfigError(
                f"MetricsConfig.ttc_scope must be 'ahead' or 'all', got {self.ttc_scope!r}"
            )

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> MetricsConfig:
        """Build from a mapping (e.g. a YAML/JSON section); unknown keys are a ConfigError."""
        if not isinstance(data, dict):
            raise ConfigError(f"metrics configuration must be a mapping, got {type(data).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(data) - known)
        if unknown:
            raise ConfigError(
                f"unknown metrics key(s): {', '.join(unknown)}; known: {', '.join(sorted(known))}"
            )
        return cls(**data)


#: The paper's zones (the defaults).
PAPER_METRICS = MetricsConfig()
