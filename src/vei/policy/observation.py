"""What an ego policy sees: the :class:`Observation` of B variants at one engine step.

Every array has a leading batch axis ``[B]`` (one entry per variant of the block the
policy drives); road users are ``[B, N]`` with a validity mask. No per-variant Python
objects: a vectorised policy computes on whole columns.

Frames and units (DESIGN.md conventions):
- ego frame: origin at the ego's centre, x forward along its heading, y left (ISO 8855);
- positions [m], velocities [m/s], angles [rad] (relative yaw wrapped to (-pi, pi]);
- ``rel_vx_mps`` / ``rel_vy_mps`` are the object's world velocity minus the ego's
  (speed along its heading), rotated into the ego frame: a standing object straight
  ahead of an ego at 10 m/s has ``rel_vx_mps = -10``. (The ego's yaw rate is neglected.)

Road users (axis N), in this order:
- index 0: the primary rider (the simulated e-scooter / cyclist);
- then the extra social-force riders (``sim.sfm_riders``), if any;
- then every replayed recorded road user (``ScenarioArrays.other_ids`` order).
An entry is valid (``valid``) while the object is present in the scene, perceived, and
its delayed sample exists (t >= perception delay). Invalid entries hold 0 (pose,
velocity) and +inf (``path_gap_m``, ``path_lateral_m``); never read them unmasked.

``path_gap_m`` / ``path_lateral_m`` are computed by the engine from the ego's path (as
the paper's CAP does, :func:`vei.models.ego.corridor_check`): the free distance along the
ego path from the ego's front bumper to the object's nearest extent (clipped at 0), +inf
when the object is not ahead in the corridor (|lateral offset| <=
``cap.corridor_half_width_m``, within ``cap.detection_range_m``), and the signed lateral
offset of the object's centre from the path (left positive; +inf where invalid).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import Any

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]

#: int8 category codes of ``Observation.category`` (vei.types.CATEGORIES order + ego).
CATEGORY_CODES: dict[str, int] = {
    "escooter": 0,
    "cyclist": 1,
    "pedestrian": 2,
    "vehicle": 3,
    "ego": 4,
}
#: Code of a category vei does not know.
CATEGORY_OTHER = 5

#: ``Observation.source`` codes (bit 0: the on-board sensor, bit 1: V2X): where a road
#: user's entry comes from (vei.policy.v2x.fusion).
SOURCE_NONE, SOURCE_SENSOR, SOURCE_V2X, SOURCE_BOTH = 0, 1, 2, 3


def category_code(name: str) -> int:
    """The int8 code of a road-user category name (``CATEGORY_OTHER`` if unknown)."""
    return CATEGORY_CODES.get(name, CATEGORY_OTHER)


@dataclass(frozen=True)
class Observation:
    """The observation of B variants at one step (arrays ``[B]`` / ``[B, N]``).

    Attributes:
        t_s: [B] engine time t = k dt [s].
        dt_s: the engine step [s] (a float, the same for every variant).
        ego_speed_mps: [B] ego speed along its path (>= 0) [m/s].
        ego_accel_mps2: [B] the ego's reported longitudinal acceleration [m/s^2].
        ego_s_m: [B] ego progress: arc length of its centre along its path [m] (negative
            on the run-up before the recorded start).
        path_length_m: [B] the path's arc length at its recorded end [m].
        cruise_speed_mps: [B] the configured cruise speed v_d [m/s].
        max_accel_mps2, max_decel_mps2: [B] the actuator's full throttle / full brake
            accelerations (both > 0) [m/s^2]; demands beyond them are clipped.
        ego_length_m, ego_width_m: the ego's footprint [m] (floats).
        collided: [B] bool, the ego has collided with the primary rider (the engine
            freezes such variants whatever the policy demands).
        valid: [B, N] bool, the object is perceived at this step.
        rel_x_m, rel_y_m: [B, N] object centre in the ego frame [m].
        rel_yaw_rad: [B, N] object heading minus ego heading, wrapped [rad].
        rel_vx_mps, rel_vy_mps: [B, N] relative velocity in the ego frame [m/s].
        length_m, width_m: [B, N] object footprint [m].
        age_s: [B, N] age of the detection: how old the sample the policy sees is [s]
            (the perception delay; +inf where invalid).
        category: [B, N] int8 category code (:data:`CATEGORY_CODES`).
        path_gap_m: [B, N] free distance along the ego path from the ego front to the
            object's nearest extent [m], +inf when not ahead in the path corridor.
        path_lateral_m: [B, N] signed lateral offset of the object centre from the ego
            path [m] (left positive), +inf where invalid.
        source: [B, N] int8, where the entry comes from: :data:`SOURCE_SENSOR` (the
            on-board perception; ideal perception counts as the sensor), :data:`SOURCE_V2X`
            (a V2X message only), :data:`SOURCE_BOTH`; :data:`SOURCE_NONE` where invalid.
            None (a hand-built observation) = sensor wherever valid.
        position_std_m: [B, N] 1-sigma position uncertainty the car attaches to the entry
            per axis [m]: the sensor's noise, a V2X message's stated accuracy, or their
            fusion (vei.policy.v2x.fusion); +inf where invalid. None = unknown.
    """

    t_s: FloatArray
    dt_s: float
    ego_speed_mps: FloatArray
    ego_accel_mps2: FloatArray
    ego_s_m: FloatArray
    path_length_m: FloatArray
    cruise_speed_mps: FloatArray
    max_accel_mps2: FloatArray
    max_decel_mps2: FloatArray
    ego_length_m: float
    ego_width_m: float
    collided: BoolArray
    valid: BoolArray
    rel_x_m: FloatArray
    rel_y_m: FloatArray
    rel_yaw_rad: FloatArray
    rel_vx_mps: FloatArray
    rel_vy_mps: FloatArray
    length_m: FloatArray
    width_m: FloatArray
    age_s: FloatArray
    category: npt.NDArray[np.int8]
    path_gap_m: FloatArray
    path_lateral_m: FloatArray
    source: npt.NDArray[np.int8] | None = None
    position_std_m: FloatArray | None = None

    @property
    def batch_size(self) -> int:
        """B, the number of variants."""
        return int(self.ego_speed_mps.shape[0])

    @property
    def n_objects(self) -> int:
        """N, the number of road-user slots (valid or not)."""
        return int(self.valid.shape[1])

    def variant(self, i: int) -> Any:
        """Variant i as a plain namespace (scalars and [N] arrays) for per-variant code.

        Slow (a Python object per call); :class:`vei.policy.base.PerVariantPolicy` uses it.
        """
        from types import SimpleNamespace

        out: dict[str, Any] = {}
        for f in fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.ndarray):
                out[f.name] = v[i] if v.ndim == 2 else v[i].item()
            else:
                out[f.name] = v
        return SimpleNamespace(**out)

    def sensor_view(self) -> Observation:
        """This observation without the entries known from V2X alone (their ``valid``
        False, pose and velocity 0, gap / lateral offset / age / uncertainty +inf): what
        the on-board sensor gives. Entries of both sources keep their fused values."""
        if self.source is None:
            return self
        keep = self.valid & ((self.source & SOURCE_SENSOR) != 0)
        if np.array_equal(keep, self.valid):
            return self
        from dataclasses import replace

        z, inf = 0.0, np.inf
        out: dict[str, Any] = {"valid": keep}
        for name, fill in (
            ("rel_x_m", z), ("rel_y_m", z), ("rel_yaw_rad", z), ("rel_vx_mps", z),
            ("rel_vy_mps", z), ("age_s", inf), ("path_gap_m", inf), ("path_lateral_m", inf),
            ("position_std_m", inf),
        ):  # fmt: skip
            v = getattr(self, name)
            if v is not None:
                out[name] = np.where(keep, v, fill)
        out["source"] = np.where(keep, self.source, SOURCE_NONE).astype(np.int8)
        return replace(self, **out)


def wrap_angle(a: npt.ArrayLike) -> FloatArray:
    """Angles wrapped to (-pi, pi] [rad]."""
    a = np.asarray(a, dtype=np.float64)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


__all__ = [
    "CATEGORY_CODES",
    "CATEGORY_OTHER",
    "SOURCE_BOTH",
    "SOURCE_NONE",
    "SOURCE_SENSOR",
    "SOURCE_V2X",
    "Observation",
    "category_code",
    "wrap_angle",
]
