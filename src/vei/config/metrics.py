"""Configuration of the safety metrics, at the config layer so that a run configuration
can carry it (``RunConfig.metrics``; a YAML/JSON ``metrics:`` section). Imports only
vei.errors (tests/test_layering.py). Re-exported by :mod:`vei.metrics.config`.

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
        drac_ceiling_mps2: the car's full brake [m/s^2]: DRAC values above it are
            unreachable by this car's braking, reported capped at it and flagged by
            ``drac_unavoidable``. None (default) = the run's own ``ego.max_decel_mps2``
            (8.0 m/s^2 unless configured; the value the engine's full brake applies), so
            the flag and the braking the car can do agree; a number overrides it for every
            run. See docs/metrics.md.
        reaction_time_s: the DRAC's maximum and ``drac_unavoidable`` are taken only over
            steps at least this long before contact (time to contact = gap / closing speed)
            [s]. Default 0.5 s: the actuation delay of an automatic brake (brake pressure
            build-up ~0.2-0.3 s plus a detection/decision cycle; far below a human's
            ~1-1.5 s, which would make nearly every late conflict "unavoidable"). Without
            it every collision is "unavoidable": on the step before contact the gap is
            below v dt, so DRAC > v / (2 dt) = 10 v at 20 Hz.
        car_mass_kg: mass of the ego car for the impact's delta-v [kg]. Assumption: 1,500 kg,
            a mid-size sedan's curb weight (~1,400-1,550 kg) plus a driver, matching the
            default 4.7 x 1.85 m footprint.
        rider_mass_kg: rider + e-scooter mass for the delta-v [kg]. None (default) = each
            run's own rider mass: the case's ``sfm.mass_kg`` (95 kg unless configured; a
            replayed rider, which has no SFM, uses the case's ``sfm.mass_kg`` too), so a
            sweep over ``sfm.mass_kg`` changes the delta-v as well; a number overrides it.
        injury_intercept: b0 of the rider's injury risk P = 1 / (1 + exp(b0 - b1 v_kmh)).
        injury_slope_per_kmh: b1 [1/(km/h)]. Defaults b0 = 6.9, b1 = 0.090: Rosen & Sander
            (2009), "Pedestrian fatality risk as a function of car impact speed", Accid.
            Anal. Prev. 41(3):536-542 (GIDAS, adults hit by a car front): P = probability of
            a fatal injury. See vei.metrics.severity for why this curve.
        injury_outcome: what the risk is the probability of (a label for tables and plots).
        mitigation_share: a collision counts as 'mitigated' when its impact speed is at
            least this share below the no-avoidance run's (default 0.2 = 20 %).
    """

    safe_ttc_s: float = 2.0
    alert_ttc_s: float = 1.0
    ttc_scope: TtcScope = "ahead"
    min_speed_mps: float = 1e-3
    drac_ceiling_mps2: float | None = None
    reaction_time_s: float = 0.5
    car_mass_kg: float = 1500.0
    rider_mass_kg: float | None = None
    injury_intercept: float = 6.9
    injury_slope_per_kmh: float = 0.090
    injury_outcome: str = "fatal injury (Rosen & Sander 2009, pedestrian)"
    mitigation_share: float = 0.2

    def __post_init__(self) -> None:
        for name in (
            "safe_ttc_s",
            "alert_ttc_s",
            "min_speed_mps",
            "drac_ceiling_mps2",
            "reaction_time_s",
            "car_mass_kg",
            "rider_mass_kg",
            "injury_intercept",
            "injury_slope_per_kmh",
            "mitigation_share",
        ):
            value = getattr(self, name)
            if value is None and name in ("drac_ceiling_mps2", "rider_mass_kg"):
                continue
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
        if self.reaction_time_s < 0:
            raise ConfigError(
                f"MetricsConfig.reaction_time_s must be >= 0 s, got {self.reaction_time_s}"
            )
        for name in ("drac_ceiling_mps2", "car_mass_kg", "rider_mass_kg", "injury_slope_per_kmh"):
            value = getattr(self, name)
            if value is not None and value <= 0:
                raise ConfigError(f"MetricsConfig.{name} must be > 0, got {getattr(self, name)}")
        if not 0.0 < self.mitigation_share < 1.0:
            raise ConfigError(
                f"MetricsConfig.mitigation_share must lie in (0, 1), got {self.mitigation_share}"
            )
        if not isinstance(self.injury_outcome, str) or not self.injury_outcome:
            raise ConfigError("MetricsConfig.injury_outcome must be a non-empty string")
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
