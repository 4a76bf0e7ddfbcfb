"""Array views of a :class:`vei.types.Trace` shared by the metric modules (internal)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.boxes import box_gap
from vei.errors import InputError
from vei.metrics.geometry import box_corners
from vei.types import Trace

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]


@dataclass(frozen=True)
class TraceArrays:
    """A Trace as validated float/bool arrays ([B, T] unless noted), with derived geometry."""

    trace: Trace
    #: memo of derived series keyed by (name, config), filled by the metric modules
    memo: dict = field(default_factory=dict, compare=False, repr=False)
    #: per-run settings of the runs [B] (see :func:`arrays`): 'rider_mass_kg',
    #: 'ego_max_decel_mps2'; a missing key = the config default (95 kg, 8.0 m/s^2)
    params: dict = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        t = self.t_s
        b, n = self.ego_speed.shape
        if t.ndim != 1 or t.size != n:
            raise InputError(
                f"trace t_s has shape {t.shape}, expected [{n}] to match ego_speed_mps [B, T]"
            )
        expected = {
            "ego_xy_m": (b, n, 2),
            "ego_yaw_rad": (b, n),
            "ego_accel_mps2": (b, n),
            "other_xy_m": (b, n, 2),
            "other_yaw_rad": (b, n),
            "other_speed_mps": (b, n),
            "other_vel_mps": (b, n, 2),
            "other_active": (b, n),
            "collided": (b, n),
        }
        for name, shape in expected.items():
            got = np.shape(getattr(self.trace, name))
            if got != shape:
                raise InputError(
                    f"trace field {name} has shape {got}, expected {shape}", field=name
                )
        if n > 2 and not np.allclose(np.diff(t), t[1] - t[0], rtol=1e-6, atol=1e-9):
            raise InputError("trace t_s is not a uniform time grid", field="t_s")

    @cached_property
    def t_s(self) -> FloatArray:
        return np.asarray(self.trace.t_s, dtype=np.float64)

    @property
    def dt_s(self) -> float:
        return self.trace.dt_s

    @cached_property
    def ego_xy(self) -> FloatArray:
        return np.asarray(self.trace.ego_xy_m, dtype=np.float64)

    @cached_property
    def ego_yaw(self) -> FloatArray:
        return np.asarray(self.trace.ego_yaw_rad, dtype=np.float64)

    @cached_property
    def ego_speed(self) -> FloatArray:
        return np.atleast_2d(np.asarray(self.trace.ego_speed_mps, dtype=np.float64))

    @cached_property
    def ego_accel(self) -> FloatArray:
        return np.asarray(self.trace.ego_accel_mps2, dtype=np.float64)

    @cached_property
    def ego_vel(self) -> FloatArray:
        """[B, T, 2] ego velocity vector (m/s) from speed and heading."""
        return self.ego_speed[..., None] * np.stack(
            [np.cos(self.ego_yaw), np.sin(self.ego_yaw)], axis=-1
        )

    @cached_property
    def other_xy(self) -> FloatArray:
        return np.asarray(self.trace.other_xy_m, dtype=np.float64)

    @cached_property
    def other_yaw(self) -> FloatArray:
        return np.asarray(self.trace.other_yaw_rad, dtype=np.float64)

    @cached_property
    def other_vel(self) -> FloatArray:
        return np.asarray(self.trace.other_vel_mps, dtype=np.float64)

    @cached_property
    def active(self) -> BoolArray:
        return np.asarray(self.trace.other_active, dtype=bool)

    @cached_property
    def collided(self) -> BoolArray:
        return np.asarray(self.trace.collided, dtype=bool)

    @cached_property
    def ego_corners(self) -> FloatArray:
        tr = self.trace
        return box_corners(self.ego_xy, self.ego_yaw, tr.ego_length_m, tr.ego_width_m)

    @cached_property
    def other_corners(self) -> FloatArray:
        tr = self.trace
        # Inactive steps may hold NaN positions: park them far away (results are masked).
        xy = np.where(self.active[..., None] & np.isfinite(self.other_xy), self.other_xy, 1e9)
        yaw = np.where(np.isfinite(self.other_yaw), self.other_yaw, 0.0)
        return box_corners(xy, yaw, tr.other_length_m, tr.other_width_m)

    @cached_property
    def gap(self) -> FloatArray:
        """[B, T] box-to-box gap (m); NaN where the other road user is inactive."""
        tr = self.trace
        # Inactive steps may hold NaN positions: park them far away (results are masked).
        ok = self.active & np.isfinite(self.other_xy).all(axis=-1)
        g = box_gap(
            self.ego_xy[..., 0],
            self.ego_xy[..., 1],
            self.ego_yaw,
            tr.ego_length_m,
            tr.ego_width_m,
            np.where(ok, self.other_xy[..., 0], 1e9),
            np.where(ok, self.other_xy[..., 1], 1e9),
            np.where(np.isfinite(self.other_yaw), self.other_yaw, 0.0),
            tr.other_length_m,
            tr.other_width_m,
        )
        return np.where(self.active, g, np.nan)

    @cached_property
    def rel_xy(self) -> FloatArray:
        """[B, T, 2] other's centre in the ego frame (x forward, y left) (m)."""
        d = self.other_xy - self.ego_xy
        c, s = np.cos(self.ego_yaw), np.sin(self.ego_yaw)
        return np.stack([c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1]], axis=-1)

    @cached_property
    def ahead(self) -> BoolArray:
        """[B, T] the other's centre is ahead of the ego's centre along the ego heading."""
        return self.active & (self.rel_xy[..., 0] > 0.0)


RUN_PARAMS: tuple[str, ...] = ("rider_mass_kg", "ego_max_decel_mps2")
#: Per-run sensor parameters (vei.metrics.seen: when the other was first seen), from the
#: case's perception (vei.config.PerceptionConfig); absent = no sensor model (first seen
#: = first present). Range inf and field of view 360 deg = no limit.
SENSOR_PARAMS: tuple[str, ...] = (
    "sensor_range_m", "sensor_fov_deg", "sensor_x_m", "sensor_y_m",
    "sensor_min_visible_fraction",
)  # fmt: skip


def arrays(
    trace: Trace | TraceArrays, params: Mapping[str, npt.ArrayLike] | None = None
) -> TraceArrays:
    """Wrap a Trace (idempotent), validating its shapes.

    Args:
        trace: B runs.
        params: optional per-run settings, each a scalar or [B]: 'rider_mass_kg' (the
            rider + e-scooter mass, kg; the case's ``sfm.mass_kg``) and
            'ego_max_decel_mps2' (the car's full brake, m/s^2; ``ego.max_decel_mps2``).
            See :func:`run_params`. Given with a TraceArrays, they are added to it.
    """
    a = trace if isinstance(trace, TraceArrays) else TraceArrays(trace)
    for key, value in (params or {}).items():
        if key in SENSOR_PARAMS:
            a.params[key] = _sensor_param(key, value, a.ego_speed.shape[0])
            continue
        if key not in RUN_PARAMS:
            known = ", ".join(RUN_PARAMS + SENSOR_PARAMS)
            raise InputError(f"unknown run parameter {key!r}; known: {known}")
        v = np.broadcast_to(np.asarray(value, dtype=np.float64), a.ego_speed.shape[:1]).copy()
        if not (np.isfinite(v) & (v > 0)).all():
            raise InputError(f"run parameter {key} must be finite and > 0, got {v}", field=key)
        a.params[key] = v
    return a


def run_params(cases: Sequence[Any]) -> dict[str, FloatArray]:
    """Per-run settings of B cases (``vei.config.CaseConfig``), for :func:`arrays`: the
    rider mass (``sfm.mass_kg``; also for a replayed rider, which has no SFM of its own)
    and the car's full brake (``ego.max_decel_mps2``); the sensor's (:data:`SENSOR_PARAMS`)
    when some case has an enabled perception (``case.perception``)."""
    out = {
        "rider_mass_kg": np.array([float(c.sfm.mass_kg) for c in cases]),
        "ego_max_decel_mps2": np.array([float(c.ego.max_decel_mps2) for c in cases]),
    }
    out.update(sensor_params([getattr(c, "perception", None) for c in cases]))
    return out


def sensor_params(perceptions: Sequence[Any]) -> dict[str, FloatArray]:
    """:data:`SENSOR_PARAMS` of B runs from their PerceptionConfig (None or disabled =
    no sensor: range inf, field of view 360 deg); {} when no run has one."""
    on = [p is not None and bool(getattr(p, "enabled", False)) for p in perceptions]
    if not any(on):
        return {}
    n = len(perceptions)
    out = {
        "sensor_range_m": np.full(n, np.inf),
        "sensor_fov_deg": np.full(n, 360.0),
        "sensor_x_m": np.zeros(n),
        "sensor_y_m": np.zeros(n),
        "sensor_min_visible_fraction": np.full(n, 0.2),
    }
    for i, (p, use) in enumerate(zip(perceptions, on, strict=True)):
        if use:
            out["sensor_range_m"][i] = p.range_m
            out["sensor_fov_deg"][i] = p.fov_deg
            out["sensor_x_m"][i] = p.sensor_x_m
            out["sensor_y_m"][i] = p.sensor_y_m
            out["sensor_min_visible_fraction"][i] = p.min_visible_fraction
    return out


def _sensor_param(key: str, value: Any, n: int) -> FloatArray:
    """[n] a checked sensor parameter (InputError naming it otherwise)."""
    v = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,)).copy()
    ok = ~np.isnan(v)
    if key == "sensor_range_m":
        ok &= v > 0
    elif key == "sensor_fov_deg":
        ok &= (v > 0) & (v <= 360.0)
    elif key == "sensor_min_visible_fraction":
        ok &= (v > 0) & (v <= 1.0)
    else:
        ok &= np.isfinite(v)
    if not ok.all():
        raise InputError(f"run parameter {key} out of range, got {v}", field=key)
    return v


def param_of(a: TraceArrays, key: str, override: float | None) -> FloatArray:
    """[B] a per-run setting: ``override`` when given (a MetricsConfig field), else the
    run's own (:func:`arrays` params), else the config default."""
    n = a.ego_speed.shape[0]
    if override is not None:
        return np.full(n, float(override))
    if key in a.params:
        return a.params[key]
    from vei.config.models import EgoConfig, SFMConfig

    default = SFMConfig.mass_kg if key == "rider_mass_kg" else EgoConfig.max_decel_mps2
    return np.full(n, float(default))
