"""Perception between the world and the ego's policy: range, field of view, occlusion, noise.

A pure, batched (leading axis ``[B]`` = variants, then ``[N]`` = objects), deterministic
and seeded model of what the ego's sensor reports each step. The engine gives it the
ground truth (:class:`GroundTruth`; with ``CAPConfig.perception_delay_s`` > 0 the engine
passes the objects' *delayed* states: latency is the engine's, not this module's) and the
carried :class:`PerceptionState`; :func:`perceive` returns what the policy sees
(:class:`PerceivedObjects`, in the ego frame) and the new state. Nothing is mutated.

Per step, object j of variant i is

1. **visible** when it is present (``truth.valid``) and the share of its 5 sample points
   (box centre and corners) that lie within ``range_m`` of the sensor, within +-``fov_deg``/2
   of the ego's heading (bearing measured at the sensor) and - with ``occlusion`` on - have
   a clear line of sight from the sensor (the segment crosses no other present occluding
   box: ``truth.can_occlude``; a target never hides itself) is >= ``min_visible_fraction``
   (:mod:`vei.policy.perception_geometry`);
2. **detected** when visible and a uniform draw u < ``detection_probability`` (independent
   per step and object);
3. **measured** with white Gaussian noise: position x and y each + N(0, position_noise_std_m^2),
   velocity vx and vy each + N(0, velocity_noise_std_mps^2), independent per step, object
   and axis (isotropic, so the same in world and ego axes); heading and box size exact;
4. **held** when missed: the last measurement is kept and its ``age_s`` grows by ``dt_s``
   each step; its position is predicted at constant velocity in the world frame,
   ``x + vx * age_s`` (then seen from the ego's current pose), its velocity, heading and
   size kept. A held track is dropped once ``age_s > max_hold_s`` (1e-9 s tolerance for
   the summed steps); ``max_hold_s = 0`` drops a missed object at once.

The ego knows its own pose and velocity exactly. Random numbers depend only on
``(seed, variant_keys[i], k, j)`` (:mod:`vei.policy.perception_random`), so a variant
perceives the same in a batch of any size, and the same seed gives bit-identical results.

With ``enabled=False`` (the default) perception is ideal: every present object is detected
this step, exact, age 0, and no track is held - the paper's case is unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from vei.config.perception import PerceptionConfig
from vei.policy import perception_geometry as geom
from vei.policy.perception_random import (
    STREAM_DETECTION,
    STREAM_POSITION,
    STREAM_VELOCITY,
    counter_normal_pair,
    counter_uniform,
)

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

HOLD_TOL_S = 1e-9
_FRACTION_TOL = 1e-9


def _check_shape(owner: str, names: tuple[str, ...], obj: Any, shape: tuple[int, ...]) -> None:
    for name in names:
        arr = getattr(obj, name)
        if not isinstance(arr, np.ndarray) or arr.shape != shape:
            got = getattr(arr, "shape", type(arr).__name__)
            raise ValueError(f"{owner}.{name} must be an array of shape {shape}, got {got}")


_OBJECT_FIELDS = ("x_m", "y_m", "yaw_rad", "vx_mps", "vy_mps", "length_m", "width_m")
_EGO_FIELDS = ("ego_x_m", "ego_y_m", "ego_yaw_rad", "ego_vx_mps", "ego_vy_mps")


@dataclass(frozen=True)
class GroundTruth:
    """The world as it is (or, with latency, was), in the world frame.

    Objects ``[B, N]`` (float64 unless said; entries with ``valid`` False are ignored and
    may hold anything, NaN included):

    Attributes:
        x_m, y_m: box centre [m]. yaw_rad: heading [rad, CCW from +x].
        vx_mps, vy_mps: velocity [m/s]. length_m, width_m: box along / across heading [m].
        valid: [B, N] bool, the object is present in the scene.
        can_occlude: [B, N] bool, the object's box hides what is behind it (recorded road
            users; the engine decides, e.g. every recorded vehicle, rider and pedestrian).
        ego_x_m, ego_y_m, ego_yaw_rad: ego box centre and heading ``[B]`` [m, rad].
        ego_vx_mps, ego_vy_mps: ego velocity ``[B]`` [m/s] (world frame).
    """

    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    vx_mps: FloatArray
    vy_mps: FloatArray
    length_m: FloatArray
    width_m: FloatArray
    valid: BoolArray
    can_occlude: BoolArray
    ego_x_m: FloatArray
    ego_y_m: FloatArray
    ego_yaw_rad: FloatArray
    ego_vx_mps: FloatArray
    ego_vy_mps: FloatArray

    def __post_init__(self) -> None:
        shape = np.shape(self.x_m)
        if len(shape) != 2:
            raise ValueError(f"GroundTruth.x_m must be [B, N], got shape {shape}")
        _check_shape("GroundTruth", (*_OBJECT_FIELDS, "valid", "can_occlude"), self, shape)
        _check_shape("GroundTruth", _EGO_FIELDS, self, shape[:1])
        if self.valid.dtype != np.bool_ or self.can_occlude.dtype != np.bool_:
            raise ValueError("GroundTruth.valid and can_occlude must be bool arrays")

    @property
    def shape(self) -> tuple[int, int]:
        """(B, N)."""
        return self.x_m.shape  # type: ignore[return-value]


@dataclass(frozen=True)
class PerceptionState:
    """Tracks carried from step to step, ``[B, N]``; build the first with :func:`init_state`.

    Attributes:
        tracked: bool, a track exists (detected now or held).
        age_s: time since its last detection [s] (0 = detected this step); NaN where no
            track.
        x_m, y_m, yaw_rad, vx_mps, vy_mps, length_m, width_m: the last measurement in the
            world frame (noise included); NaN where no track.
    """

    tracked: BoolArray
    age_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    vx_mps: FloatArray
    vy_mps: FloatArray
    length_m: FloatArray
    width_m: FloatArray


def init_state(n_variants: int, n_objects: int) -> PerceptionState:
    """The state before the first step: no tracks.

    Args:
        n_variants: B. n_objects: N.
    Returns:
        A :class:`PerceptionState` of shape [B, N].
    """
    shape = (int(n_variants), int(n_objects))
    nan = np.full(shape, np.nan)
    return PerceptionState(np.zeros(shape, dtype=bool), *(nan.copy() for _ in range(8)))


@dataclass(frozen=True)
class PerceivedObjects:
    """What the policy sees, ``[B, N]`` in the ego frame (x forward, y left, origin at the
    ego box centre, axes of the ego's current heading). Object j is truth object j.

    Attributes:
        tracked: bool, the entry carries a perceived object (detected now or held); every
            float field is NaN where False.
        detected: bool, detected in this step (``tracked`` and ``age_s == 0``).
        age_s: time since the last detection [s]: 0 fresh, > 0 held. The engine's latency
            (``perception_delay_s``) is not included: the sample the policy sees is
            ``age_s + perception_delay_s`` old.
        x_m, y_m: box centre relative to the ego box centre [m] (held: predicted).
        yaw_rad: heading relative to the ego's heading [rad], in (-pi, pi].
        vx_mps, vy_mps: object velocity minus ego velocity, in ego axes [m/s] (the
            rotation rate of the ego frame is not added).
        length_m, width_m: box size [m].
    """

    tracked: BoolArray
    detected: BoolArray
    age_s: FloatArray
    x_m: FloatArray
    y_m: FloatArray
    yaw_rad: FloatArray
    vx_mps: FloatArray
    vy_mps: FloatArray
    length_m: FloatArray
    width_m: FloatArray


def visible_fraction(cfg: PerceptionConfig, truth: GroundTruth) -> FloatArray:
    """Share of each object's 5 sample points the sensor sees (range, FOV, line of sight).

    Args:
        cfg: the sensor. truth: the world [B, N].
    Returns:
        [B, N] in {0, 0.2, ..., 1}; 0 for absent objects.
    """
    return geom.visible_fraction(
        truth.x_m,
        truth.y_m,
        truth.yaw_rad,
        truth.length_m,
        truth.width_m,
        truth.valid,
        truth.can_occlude,
        truth.ego_x_m,
        truth.ego_y_m,
        truth.ego_yaw_rad,
        range_m=cfg.range_m,
        fov_deg=cfg.fov_deg,
        sensor_x_m=cfg.sensor_x_m,
        sensor_y_m=cfg.sensor_y_m,
        occlusion=cfg.occlusion,
    )


def _to_ego_frame(state: PerceptionState, truth: GroundTruth) -> PerceivedObjects:
    """World-frame tracks (held ones predicted by ``age_s``) seen from the ego's pose."""
    age = np.where(state.tracked, state.age_s, np.nan)
    wx = state.x_m + state.vx_mps * age
    wy = state.y_m + state.vy_mps * age
    c = np.cos(truth.ego_yaw_rad)[:, None]
    s = np.sin(truth.ego_yaw_rad)[:, None]
    dx = wx - truth.ego_x_m[:, None]
    dy = wy - truth.ego_y_m[:, None]
    dvx = state.vx_mps - truth.ego_vx_mps[:, None]
    dvy = state.vy_mps - truth.ego_vy_mps[:, None]
    rel_yaw = np.pi - np.mod(np.pi - (state.yaw_rad - truth.ego_yaw_rad[:, None]), 2.0 * np.pi)
    return PerceivedObjects(
        tracked=state.tracked.copy(),
        detected=state.tracked & (age == 0.0),
        age_s=age,
        x_m=c * dx + s * dy,
        y_m=-s * dx + c * dy,
        yaw_rad=rel_yaw,
        vx_mps=c * dvx + s * dvy,
        vy_mps=-s * dvx + c * dvy,
        length_m=np.where(state.tracked, state.length_m, np.nan),
        width_m=np.where(state.tracked, state.width_m, np.nan),
    )


def perceive(
    cfg: PerceptionConfig,
    state: PerceptionState,
    truth: GroundTruth,
    k: int,
    dt_s: float,
    variant_keys: npt.ArrayLike,
) -> tuple[PerceivedObjects, PerceptionState]:
    """One perception step: detect, measure, hold or drop, and express in the ego frame.

    Pure: returns new arrays, mutates nothing. See the module docstring for the rules.

    Args:
        cfg: the sensor model.
        state: the tracks after step k-1 (:func:`init_state` before the first step), [B, N].
        truth: the world at step k (objects possibly delayed by the engine), [B, N].
        k: step index (>= 0), a counter of the random numbers.
        dt_s: time since the previous call [s] (> 0): the held tracks' ageing.
        variant_keys: [B] integers identifying the variants (stable across batches: e.g.
            the variant's index in the sweep), the other counter of the random numbers.
    Returns:
        (perceived [B, N] in the ego frame, new state [B, N]).
    """
    n_var, n_obj = truth.shape
    if state.tracked.shape != (n_var, n_obj):
        raise ValueError(f"state shape {state.tracked.shape} != truth shape {(n_var, n_obj)}")
    keys = np.asarray(variant_keys)
    if keys.shape != (n_var,):
        raise ValueError(f"variant_keys must have shape ({n_var},), got {keys.shape}")
    if not (isinstance(dt_s, int | float) and math.isfinite(dt_s) and dt_s > 0):
        raise ValueError(f"dt_s must be a finite number > 0, got {dt_s!r}")
    valid = truth.valid
    if not cfg.enabled:
        detected = valid.copy()
    else:
        detected = valid & (
            visible_fraction(cfg, truth) >= cfg.min_visible_fraction - _FRACTION_TOL
        )
        if cfg.detection_probability < 1.0:
            u = counter_uniform(cfg.seed, keys, k, n_obj, STREAM_DETECTION)
            detected &= u < cfg.detection_probability
    # Measurement (world frame) of the detected objects.
    mx, my = truth.x_m, truth.y_m
    mvx, mvy = truth.vx_mps, truth.vy_mps
    if cfg.enabled and cfg.position_noise_std_m > 0.0:
        zx, zy = counter_normal_pair(cfg.seed, keys, k, n_obj, STREAM_POSITION)
        mx = mx + cfg.position_noise_std_m * zx
        my = my + cfg.position_noise_std_m * zy
    if cfg.enabled and cfg.velocity_noise_std_mps > 0.0:
        zx, zy = counter_normal_pair(cfg.seed, keys, k, n_obj, STREAM_VELOCITY)
        mvx = mvx + cfg.velocity_noise_std_mps * zx
        mvy = mvy + cfg.velocity_noise_std_mps * zy
    # Hold or drop the missed tracks.
    if cfg.enabled:
        held_age = state.age_s + float(dt_s)
        held = state.tracked & ~detected & (held_age <= cfg.max_hold_s + HOLD_TOL_S)
    else:
        held_age = state.age_s
        held = np.zeros_like(detected)
    tracked = detected | held
    nan = np.nan

    def pick(measured: FloatArray, kept: FloatArray) -> FloatArray:
        return np.where(detected, measured, np.where(held, kept, nan))

    new_state = PerceptionState(
        tracked=tracked,
        age_s=np.where(detected, 0.0, np.where(held, held_age, nan)),
        x_m=pick(mx, state.x_m),
        y_m=pick(my, state.y_m),
        yaw_rad=pick(truth.yaw_rad, state.yaw_rad),
        vx_mps=pick(mvx, state.vx_mps),
        vy_mps=pick(mvy, state.vy_mps),
        length_m=pick(truth.length_m, state.length_m),
        width_m=pick(truth.width_m, state.width_m),
    )
    return _to_ego_frame(new_state, truth), new_state
