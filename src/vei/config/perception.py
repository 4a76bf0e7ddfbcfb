"""Configuration of the ego's sensor model (vei.policy.perception), on the config layer.

:class:`PerceptionConfig` lives here, below the policy layer, so that
:class:`vei.config.CaseConfig` can hold and check it without importing upward;
:mod:`vei.policy.perception` (the model) imports and re-exports it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from vei.errors import ConfigError


def _number(
    name: str,
    value: Any,
    *,
    lo: float | None = None,
    lo_open: bool = False,
    hi: float | None = None,
) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ConfigError(f"perception.{name} must be a number, got {value!r}")
    value = float(value)
    if not math.isfinite(value):
        raise ConfigError(f"perception.{name} must be finite, got {value!r}")
    if lo is not None and (value <= lo if lo_open else value < lo):
        raise ConfigError(
            f"perception.{name} must be {'>' if lo_open else '>='} {lo:g}, got {value!r}"
        )
    if hi is not None and value > hi:
        raise ConfigError(f"perception.{name} must be <= {hi:g}, got {value!r}")
    return value


@dataclass(frozen=True)
class PerceptionConfig:
    """The ego's sensor, as the policy experiences it (frozen, validated on construction).

    Defaults describe an illustrative forward sensor, not a particular product: set them
    from your sensor's data sheet. ``enabled=False`` (default) means ideal perception.
    Latency is ``CAPConfig.perception_delay_s`` (the engine feeds delayed truth).

    Attributes:
        enabled: apply this model; False = ideal perception (every present object, exact).
        range_m: maximum distance from the sensor to a sample point [m] (> 0). Default 50.
        fov_deg: horizontal field of view [deg], centred on the ego's heading, in (0, 360].
            Default 90 (+-45 deg).
        sensor_x_m: mounting point forward of the ego box centre [m]. Default 1.0 (about
            the windscreen of a 4.7 m sedan: a camera behind the rear-view mirror).
        sensor_y_m: mounting point left of the ego box centre [m]. Default 0.
        position_noise_std_m: standard deviation of the white noise on each of x, y [m]
            (>= 0). Default 0.
        velocity_noise_std_mps: standard deviation of the white noise on each of vx, vy
            [m/s] (>= 0). Default 0.
        detection_probability: chance that a visible object is detected in a step, in
            [0, 1]. Default 1.
        occlusion: other present road users' boxes (``GroundTruth.can_occlude``) hide
            what lies behind them. Default True.
        min_visible_fraction: an object is visible when at least this share of its 5
            sample points (centre, 4 corners) is in range, in the field of view and (with
            occlusion) in clear line of sight, in (0, 1]. Default 0.4 (2 of 5 points).
        max_hold_s: a missed object's last detection is held (predicted at constant
            velocity) for at most this long [s] (>= 0). Default 0.5.
        seed: seed of the detection draws and the noise (integer, taken modulo 2^64).
    """

    enabled: bool = False
    range_m: float = 50.0
    fov_deg: float = 90.0
    sensor_x_m: float = 1.0
    sensor_y_m: float = 0.0
    position_noise_std_m: float = 0.0
    velocity_noise_std_mps: float = 0.0
    detection_probability: float = 1.0
    occlusion: bool = True
    min_visible_fraction: float = 0.4
    max_hold_s: float = 0.5
    seed: int = 0

    def __post_init__(self) -> None:
        for name in ("enabled", "occlusion"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(
                    f"perception.{name} must be true or false, got {getattr(self, name)!r}"
                )
        checked = {
            "range_m": _number("range_m", self.range_m, lo=0.0, lo_open=True),
            "fov_deg": _number("fov_deg", self.fov_deg, lo=0.0, lo_open=True, hi=360.0),
            "sensor_x_m": _number("sensor_x_m", self.sensor_x_m),
            "sensor_y_m": _number("sensor_y_m", self.sensor_y_m),
            "position_noise_std_m": _number(
                "position_noise_std_m", self.position_noise_std_m, lo=0.0
            ),
            "velocity_noise_std_mps": _number(
                "velocity_noise_std_mps", self.velocity_noise_std_mps, lo=0.0
            ),
            "detection_probability": _number(
                "detection_probability", self.detection_probability, lo=0.0, hi=1.0
            ),
            "min_visible_fraction": _number(
                "min_visible_fraction", self.min_visible_fraction, lo=0.0, lo_open=True, hi=1.0
            ),
            "max_hold_s": _number("max_hold_s", self.max_hold_s, lo=0.0),
        }
        for name, value in checked.items():
            object.__setattr__(self, name, value)
        seed = self.seed
        if isinstance(seed, bool) or not isinstance(seed, int | np.integer):
            raise ConfigError(f"perception.seed must be an integer, got {seed!r}")
        object.__setattr__(self, "seed", int(seed))


__all__ = ["PerceptionConfig"]
