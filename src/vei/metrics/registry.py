"""One interface for every metric: ``Metric.compute(trace, cfg) -> np.ndarray`` and a
registry by name.

Scalar metrics return one value per run ``[B]``; series metrics return ``[B, T]``.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from types import MappingProxyType
from typing import Literal

import numpy as np
import numpy.typing as npt

import vei.metrics.conflict as conflict
import vei.metrics.ego_dynamics as ego_dynamics
import vei.metrics.kinematics as kinematics
import vei.metrics.secondary as secondary
import vei.metrics.seen as seen
import vei.metrics.severity as severity
import vei.metrics.ttc as ttc
import vei.metrics.where as where
from vei.errors import ConfigError
from vei.metrics._trace import TraceArrays, arrays
from vei.metrics.config import MetricsConfig
from vei.types import Trace

MetricFn = Callable[[TraceArrays, MetricsConfig], np.ndarray]


@dataclass(frozen=True)
class Metric:
    """A named metric.

    Attributes:
        name: registry key (also the summary column).
        kind: 'scalar' -> compute returns [B]; 'series' -> [B, T].
        unit: unit of the values ('s', 'm', 'm/s^2', 'm/s', '1', 'bool', 'zone', 'label':
            a string per run, '' where undefined).
        description: one line.
        fn: the implementation (trace arrays, config) -> array.
    """

    name: str
    kind: Literal["scalar", "series"]
    unit: str
    description: str
    fn: MetricFn

    def compute(self, trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> np.ndarray:
        """Evaluate on a trace of B runs: [B] (scalar) or [B, T] (series)."""
        return self.fn(arrays(trace), MetricsConfig() if cfg is None else cfg)


def _collision(a: TraceArrays, cfg: MetricsConfig) -> npt.NDArray[np.bool_]:
    return a.collided.any(axis=1)


def _collision_time(a: TraceArrays, cfg: MetricsConfig) -> np.ndarray:
    hit = a.collided.any(axis=1)
    first = np.argmax(a.collided, axis=1)
    return np.where(hit, a.t_s[first], np.nan)


def _nanmin(x: np.ndarray) -> np.ndarray:
    out = np.full(x.shape[0], np.nan)
    has = ~np.isnan(x).all(axis=1)
    out[has] = np.nanmin(x[has], axis=1)
    return out


def _zone_time(zone: str) -> MetricFn:
    return lambda a, cfg: ttc.zone_durations(a, cfg)[zone]


_ALL: tuple[Metric, ...] = (
    Metric(
        "collision", "scalar", "bool", "ego and road user collided (boxes overlapped)", _collision
    ),
    Metric(
        "collision_time_s",
        "scalar",
        "s",
        "time of the first collision (NaN if none)",
        _collision_time,
    ),
    Metric(
        "safety_index",
        "scalar",
        "1",
        "paper: (T_safe + T_attention) / T_all, 0 on collision",
        lambda a, c: ttc.safety_index(a, c),
    ),
    Metric(
        "t_safe_s", "scalar", "s", "time in the safe zone (TTC > safe_ttc_s)", _zone_time("safe")
    ),
    Metric("t_attention_s", "scalar", "s", "time in the attention zone", _zone_time("attention")),
    Metric(
        "t_alert_s",
        "scalar",
        "s",
        "time in the alert zone (TTC <= alert_ttc_s)",
        _zone_time("alert"),
    ),
    Metric(
        "t_collision_s",
        "scalar",
        "s",
        "time in the collision zone (after the crash)",
        _zone_time("collision"),
    ),
    Metric(
        "t_interaction_s",
        "scalar",
        "s",
        "length of the interaction span (road user active)",
        _zone_time("all"),
    ),
    Metric(
        "min_gap_m", "scalar", "m", "smallest box-to-box gap", lambda a, c: conflict.min_gap(a, c)
    ),
    Metric(
        "min_ttc_s",
        "scalar",
        "s",
        "smallest paper TTC = gap / v_ego",
        lambda a, c: _nanmin(ttc.paper_ttc(a, c)),
    ),
    Metric(
        "min_ttc_rel_s",
        "scalar",
        "s",
        "smallest TTC with relative velocity (boxes)",
        lambda a, c: _nanmin(ttc.relative_ttc(a, c)),
    ),
    Metric(
        "pet_s",
        "scalar",
        "s",
        "post-encroachment time at the paths' conflict point",
        lambda a, c: conflict.pet(a, c),
    ),
    Metric(
        "max_drac_mps2",
        "scalar",
        "m/s^2",
        "largest deceleration rate to avoid a crash at >= reaction_time_s before contact, "
        "capped at the car's full brake",
        lambda a, c: conflict.max_drac(a, c),
    ),
    Metric(
        "drac_unavoidable",
        "scalar",
        "bool",
        "DRAC exceeded the car's full brake (ego.max_decel_mps2) at a step >= reaction_time_s "
        "before contact: had both kept their velocities, full braking from then on could "
        "not have avoided contact (the rider may still have escaped)",
        lambda a, c: conflict.drac_unavoidable(a, c),
    ),
    Metric(
        "impact_speed_mps",
        "scalar",
        "m/s",
        "relative speed at first contact (velocities of the step before; NaN if none)",
        lambda a, c: severity.impact_speed(a, c),
    ),
    Metric(
        "delta_v_rider_mps",
        "scalar",
        "m/s",
        "rider's velocity change in a plastic impact (momentum; NaN if no collision)",
        lambda a, c: severity.delta_v(a, c)[0],
    ),
    Metric(
        "delta_v_car_mps",
        "scalar",
        "m/s",
        "car's velocity change in a plastic impact (momentum; NaN if no collision)",
        lambda a, c: severity.delta_v(a, c)[1],
    ),
    Metric(
        "impact_side",
        "scalar",
        "label",
        "side of the car hit: front / rear / left / right ('' if no collision)",
        lambda a, c: severity.impact_side(a, c),
    ),
    Metric(
        "striking",
        "scalar",
        "label",
        "car-hits-rider / rider-hits-car / rider-hits-standing-car ('' if no collision)",
        lambda a, c: severity.striking(a, c),
    ),
    Metric(
        "injury_risk",
        "scalar",
        "1",
        "rider's injury risk at the impact speed (MetricsConfig.injury_outcome; 0 if none)",
        lambda a, c: severity.injury_risk(a, c),
    ),
    Metric(
        "peak_decel_mps2",
        "scalar",
        "m/s^2",
        "largest ego deceleration before any crash",
        lambda a, c: kinematics.peak_deceleration(a, c),
    ),
    Metric(
        "ego_speed_std_mps",
        "scalar",
        "m/s",
        "std of the ego speed over the run (Fig. 6)",
        lambda a, c: kinematics.ego_speed_std(a, c),
    ),
    Metric(
        "ego_speed_mean_mps",
        "scalar",
        "m/s",
        "mean ego speed over the run",
        lambda a, c: kinematics.ego_speed_mean(a, c),
    ),
    Metric(
        "ego_speed_min_mps",
        "scalar",
        "m/s",
        "lowest ego speed over the run",
        lambda a, c: kinematics.ego_speed_min(a, c),
    ),
    Metric(
        "ego_max_yaw_step_rad",
        "scalar",
        "rad",
        "largest ego yaw change between two steps (a path kink shows here)",
        lambda a, c: ego_dynamics.max_yaw_step(a, c),
    ),
    Metric(
        "ego_max_yaw_rate_radps",
        "scalar",
        "rad/s",
        "largest ego yaw rate",
        lambda a, c: ego_dynamics.max_yaw_rate(a, c),
    ),
    Metric(
        "ego_max_lat_accel_mps2",
        "scalar",
        "m/s^2",
        "largest ego lateral acceleration (yaw rate x speed)",
        lambda a, c: ego_dynamics.max_lateral_accel(a, c),
    ),
    # ---- issue 22 / 28.7: could the car have known; the safety index on the relative TTC
    Metric(
        "first_seen_gap_m",
        "scalar",
        "m",
        "box gap when the road user was first seen (entered the sensor's range and view, "
        "or the scene without a sensor model; NaN if never)",
        lambda a, c: seen.first_seen_gap(a, c),
    ),
    Metric(
        "first_seen_ttc_s",
        "scalar",
        "s",
        "TTC with relative velocity when the road user was first seen (inf: not on a "
        "collision course then; NaN if never seen)",
        lambda a, c: seen.first_seen_ttc(a, c),
    ),
    Metric(
        "seen_too_late",
        "scalar",
        "bool",
        "no planner could have reacted: contact within reaction_time_s of first seen, or "
        "first seen on a collision course closer than the car's stopping distance",
        lambda a, c: seen.seen_too_late(a, c),
    ),
    Metric(
        "safety_index_rel",
        "scalar",
        "1",
        "the paper's safety index on the zones of the relative-velocity TTC "
        "(min_ttc_rel_s's series), 0 on collision",
        lambda a, c: seen.safety_index_rel(a, c),
    ),
    # ---- issue 24: secondary collisions (every contact but the ego's with this rider)
    Metric(
        "secondary_collision",
        "scalar",
        "bool",
        "some other pair of road users touched (the ego rear-ended, the rider into a car, a "
        "reacting car into another; vei.metrics.secondary)",
        lambda a, c: secondary.secondary_metric("secondary_collision", a),
    ),
    Metric(
        "secondary_collisions",
        "scalar",
        "1",
        "number of pairs of road users that touched, the ego / rider pair aside (NaN: the "
        "source reports none)",
        lambda a, c: secondary.secondary_metric("secondary_collisions", a),
    ),
    Metric(
        "secondary_first",
        "scalar",
        "label",
        "the first secondary collision, 'striker -> struck' ('' if none)",
        lambda a, c: secondary.secondary_metric("secondary_first", a),
    ),
    Metric(
        "secondary_time_s",
        "scalar",
        "s",
        "time of the first secondary collision (NaN if none)",
        lambda a, c: secondary.secondary_metric("secondary_time_s", a),
    ),
    Metric(
        "secondary_impact_speed_mps",
        "scalar",
        "m/s",
        "highest relative speed at a secondary collision (NaN if none)",
        lambda a, c: secondary.secondary_metric("secondary_impact_speed_mps", a),
    ),
    Metric(
        "rear_end_collision",
        "scalar",
        "bool",
        "a vehicle hit the ego from behind (the cost of hard braking)",
        lambda a, c: secondary.secondary_metric("rear_end_collision", a),
    ),
    # ---- issue 31: where the contacts happened (recorded behaviour, run-in, run-out)
    Metric(
        "contact_where",
        "scalar",
        "label",
        "where the rider was at its first contact with the ego: 'recorded', 'run-in', "
        "'run-out' of its continued track ('' if none; vei.continuation.where)",
        lambda a, c: where.where_metric("contact_where", a),
    ),
    Metric(
        "secondary_where",
        "scalar",
        "label",
        "where the other road user of the first secondary collision was: 'recorded', "
        "'run-in', 'run-out' ('' if none)",
        lambda a, c: where.where_metric("secondary_where", a),
    ),
    Metric(
        "collision_recorded",
        "scalar",
        "bool",
        "the ego hit the rider while the rider was on its recorded behaviour",
        lambda a, c: where.where_metric("collision_recorded", a),
    ),
    Metric("ttc_s", "series", "s", "paper TTC per step", lambda a, c: ttc.paper_ttc(a, c)),
    Metric(
        "ttc_zone",
        "series",
        "zone",
        "TTC zone code per step (see vei.metrics.ttc.ZONE_NAMES)",
        lambda a, c: ttc.ttc_zones(a, c),
    ),
    Metric(
        "ttc_rel_s",
        "series",
        "s",
        "TTC with relative velocity per step",
        lambda a, c: ttc.relative_ttc(a, c),
    ),
    Metric(
        "gap_m", "series", "m", "box-to-box gap per step", lambda a, c: conflict.gap_series(a, c)
    ),
    Metric(
        "drac_mps2", "series", "m/s^2", "DRAC per step", lambda a, c: conflict.drac_series(a, c)
    ),
)

#: Every metric by name (read-only).
METRICS: Mapping[str, Metric] = MappingProxyType({m.name: m for m in _ALL})
#: Names of the scalar metrics, in summary-column order.
SCALAR_METRICS: tuple[str, ...] = tuple(m.name for m in _ALL if m.kind == "scalar")
#: Names of the per-step metrics.
SERIES_METRICS: tuple[str, ...] = tuple(m.name for m in _ALL if m.kind == "series")


def get_metric(name: str) -> Metric:
    """The metric registered under ``name`` (ConfigError naming the known ones otherwise)."""
    try:
        return METRICS[name]
    except KeyError:
        raise ConfigError(f"unknown metric {name!r}; known: {', '.join(METRICS)}") from None
