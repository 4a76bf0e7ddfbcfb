"""What a collision costs: impact speed, delta-v, impact configuration, injury risk, and
the verdict of an avoidance policy against the no-avoidance run.

Definitions (one value per run; NaN / '' when the run has no collision):

- **Contact step**: the first step k at which the boxes overlap (``collided`` turns
  True). The engine zeroes both speeds on the step that detects the overlap, so the
  velocities *at* k are not the impact's. Every velocity below is the one of the last
  step before contact, k - 1 (dt = 0.05 s at the default 20 Hz). When there is no such
  step -- contact on the run's first step, or on the road user's first active step (a
  time shift that makes a rider *appear* overlapping the car: seen on the real
  recording audi_08_klinikum_rechtsabbiegen_02) -- there was no approach to measure:
  impact speed, delta-v and injury risk are NaN and 'striking' is '' (the side is still
  reported; ``collision`` is True).
- **Impact speed** ``|v_rel|``: norm of the relative velocity v_ego - v_rider [m/s],
  v_ego = speed * (cos yaw, sin yaw).
- **Delta-v** of a perfectly plastic impact (both end with the common velocity; momentum
  conserved): dv_car = m_r / (m_c + m_r) |v_rel|, dv_rider = m_c / (m_c + m_r) |v_rel|.
  Masses: ``MetricsConfig.car_mass_kg`` (1,500 kg) and the rider + e-scooter mass:
  ``MetricsConfig.rider_mass_kg`` when set, else the run's own ``sfm.mass_kg`` (95 kg
  default; a replayed rider uses its case's ``sfm.mass_kg`` too). The impact is taken
  as fully plastic over the *whole* relative velocity: for a glancing or side impact the
  tangential part is counted too, which overstates the delta-v of a graze. Plastic (restitution e = 0) is the usual assumption for a car
  striking a vulnerable road user, who is carried or thrown at about the car's speed; a
  bounce (e > 0) would multiply both delta-v by (1 + e), so these are the lower bound.
- **Impact side**: the face of the ego box through which the rider came in. In the ego
  frame (x forward, y left) at the contact step, the faces the rider's centre lies beyond
  (x > L/2: front, x < -L/2: rear, y > W/2: left, y < -W/2: right) are the candidates;
  at a corner (two candidates) the one with the larger approach speed v_rel . n (n its
  outward normal) wins -- a rider crossing in front of the car and caught by its front
  corner while moving away from the left face is hit by the *front* (measured on the real
  recording stadtmitte_12 with paper-cap: centre 2.60 m ahead, 1.10 m left, approach 3.96
  m/s through the front, -3.94 m/s through the left face). With the centre inside the box
  (or no approach velocity), the nearest face in box-scaled coordinates: |x| / (L/2) >=
  |y| / (W/2) -> front / rear, else left / right.
- **Who hit whom**: along the outward normal n of the hit face (front: ego heading,
  left: ego left, ...), the car's contribution to the closing speed is v_ego . n and
  the rider's -v_rider . n. 'car-hits-rider' when the car's contribution is at least the
  rider's, 'rider-hits-car' otherwise (e.g. a rider riding into the side of a moving car,
  whose motion has no component along a side face's normal), and
  'rider-hits-standing-car' where the rider hits a car slower than :data:`STANDING_MPS`
  (a rider riding into a car that stands: rare unless the rider model is aggressive).
  The face normal is used rather than the line of centres because the car is 4.7 m
  long: a rider touching the left side near the front corner lies 30 degrees off the
  car's axis, and the line of centres would credit the car's forward motion with a
  closing speed it does not have against that face.
- **Injury risk** of the rider: a logistic curve in the impact speed in km/h,
  P = 1 / (1 + exp(b0 - b1 v)), coefficients in :class:`vei.metrics.config.MetricsConfig`.
  Default: Rosen & Sander (2009), Accid. Anal. Prev. 41(3):536-542, b0 = 6.9,
  b1 = 0.090 per km/h, the probability of a *fatal* injury of an adult hit by the front
  of a passenger car (GIDAS). It is a pedestrian curve: cyclist curves from GIDAS exist
  (Jeppsson & Lubbe 2020, Accid. Anal. Prev. 142:105538, MAIS2+/MAIS3+/fatal), but their
  coefficients were not available to us to cite exactly, so we use the one we can quote
  and label it. It is a plausible order of magnitude for a rider: 7.6 % at 49 km/h, where
  the TARGET study (Traffic Safety Research; GIDAS-based VRU risk models) puts a
  cyclist's 10 % MAIS3+ (serious, not fatal) risk. Set the coefficients and
  ``injury_outcome`` to use another curve.

The verdict (:func:`verdict`) compares a policy run with the no-avoidance ('none' / PID)
run of the same variant: 'avoided' (no collision), 'mitigated' (impact speed at least
``mitigation_share`` below the no-avoidance run's), 'not-mitigated' otherwise -- which
includes a collision the no-avoidance run did not have. The no-avoidance run itself is
not judged against itself: case studies and sweeps label its row 'reference'
(vei.experiments.casestudy.add_verdicts, vei.sweep.compare).
The risk curve is a pedestrian, car-front one; it is applied to every rider impact,
also to a rider running into the side of a car, which it was not fitted to.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from vei.metrics._trace import TraceArrays, arrays, param_of
from vei.metrics.config import MetricsConfig
from vei.types import Trace

FloatArray = npt.NDArray[np.float64]
ObjArray = npt.NDArray[np.object_]

SIDES: tuple[str, ...] = ("front", "rear", "left", "right")
STRIKING: tuple[str, ...] = ("car-hits-rider", "rider-hits-car", "rider-hits-standing-car")
#: A car slower than this [m/s] on the step before a rider hits it stands (issue 32: a
#: rider that rides into a standing car is a failure of the rider model, said apart).
STANDING_MPS = 0.5
VERDICTS: tuple[str, ...] = ("avoided", "mitigated", "not-mitigated")
KMH_PER_MPS = 3.6


def _contact(a: TraceArrays) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(hit [B] bool, contact step k [B], step before it [B], approach [B] bool: the
    road user was active with a finite velocity on the step before contact)."""
    hit = a.collided.any(axis=1)
    k = np.argmax(a.collided, axis=1)
    pre = np.maximum(k - 1, 0)
    rows = np.arange(k.size)
    approach = (
        hit
        & (k > 0)
        & a.active[rows, pre]
        & np.isfinite(a.other_vel[rows, pre]).all(axis=-1)
        & np.isfinite(a.ego_vel[rows, pre]).all(axis=-1)
    )
    return hit, k, pre, approach


def _cached(a: TraceArrays, key: str, fn):  # noqa: ANN001, ANN202
    if key not in a.memo:
        a.memo[key] = fn()
    return a.memo[key]


def relative_velocity(trace: Trace | TraceArrays) -> FloatArray:
    """[B, 2] v_ego - v_rider just before first contact (m/s); NaN rows without collision."""
    a = arrays(trace)

    def compute() -> FloatArray:
        _, _, pre, approach = _contact(a)
        rows = np.arange(pre.size)
        v_rel = a.ego_vel[rows, pre] - np.nan_to_num(a.other_vel[rows, pre])
        return np.where(approach[:, None], v_rel, np.nan)

    return _cached(a, "severity.v_rel", compute)


def impact_speed(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] relative speed at first contact (m/s, >= 0); NaN without collision or without
    an approach (contact on the road user's first active step)."""
    return np.linalg.norm(relative_velocity(trace), axis=-1)


def delta_v(
    trace: Trace | TraceArrays, cfg: MetricsConfig | None = None
) -> tuple[FloatArray, FloatArray]:
    """([B] rider delta-v, [B] car delta-v) of a perfectly plastic impact (m/s); NaN
    without collision. dv_rider = m_c / (m_c + m_r) |v_rel|, dv_car = m_r / (...) |v_rel|;
    m_r = cfg.rider_mass_kg, or when None each run's rider mass (trace params, see
    :func:`vei.metrics._trace.arrays`; default 95 kg).
    """
    cfg = MetricsConfig() if cfg is None else cfg
    a = arrays(trace)
    v = impact_speed(a, cfg)
    m_r = param_of(a, "rider_mass_kg", cfg.rider_mass_kg)
    total = cfg.car_mass_kg + m_r
    return cfg.car_mass_kg / total * v, m_r / total * v


def _side_normal(a: TraceArrays) -> tuple[ObjArray, FloatArray]:
    """([B] hit side, [B, 2] the hit face's outward normal in the world frame)."""

    def compute() -> tuple[ObjArray, FloatArray]:
        hit, k, _, _ = _contact(a)
        rows = np.arange(k.size)
        rel = a.rel_xy[rows, k]
        tr = a.trace
        hl, hw = 0.5 * tr.ego_length_m, 0.5 * tr.ego_width_m
        yaw = a.ego_yaw[rows, k]
        c, s = np.cos(yaw), np.sin(yaw)
        # v_rel = v_ego - v_rider before contact, in the ego frame (x forward, y left)
        v = relative_velocity(a)
        vx, vy = c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1]
        # Faces (front, rear, left, right): outward normals in the ego frame, whether the
        # rider's centre lies beyond each, and the approach speed v_rel . n through it.
        beyond = np.stack([rel[:, 0] > hl, rel[:, 0] < -hl, rel[:, 1] > hw, rel[:, 1] < -hw], 1)
        approach = np.stack([vx, -vx, vy, -vy], axis=1)
        # Fallback (centre inside the box, or no velocity): the face nearest in box-scaled
        # coordinates.
        ex, ey = np.abs(rel[:, 0]) / hl, np.abs(rel[:, 1]) / hw
        fallback = np.where(
            ex >= ey,
            np.where(rel[:, 0] >= 0.0, 0, 1),
            np.where(rel[:, 1] > 0.0, 2, 3),
        )
        score = np.where(beyond & np.isfinite(approach), approach, -np.inf)
        face = np.where(np.isfinite(score.max(axis=1)), np.argmax(score, axis=1), fallback)
        side = np.asarray(SIDES, dtype=object)[face]
        side[~hit] = ""
        fwd = np.stack([c, s], axis=-1)
        left = np.stack([-s, c], axis=-1)
        normals = np.stack([fwd, -fwd, left, -left], axis=1)  # [B, 4, 2]
        return side, normals[rows, face]

    return _cached(a, "severity.side", compute)


def impact_side(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> ObjArray:
    """[B] side of the car hit: 'front' / 'rear' / 'left' / 'right'; '' without collision."""
    return _side_normal(arrays(trace))[0].copy()


def closing_contributions(trace: Trace | TraceArrays) -> tuple[FloatArray, FloatArray]:
    """([B] car's, [B] rider's) contribution to the closing speed along the hit face's
    outward normal just before contact (m/s); NaN without collision."""
    a = arrays(trace)
    _, _, pre, approach = _contact(a)
    rows = np.arange(pre.size)
    _, n = _side_normal(a)
    car = np.sum(a.ego_vel[rows, pre] * n, axis=-1)
    rider = -np.sum(np.nan_to_num(a.other_vel[rows, pre]) * n, axis=-1)
    return np.where(approach, car, np.nan), np.where(approach, rider, np.nan)


def striking(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> ObjArray:
    """[B] 'car-hits-rider', 'rider-hits-car' or 'rider-hits-standing-car' (see module
    docstring); '' without collision or without an approach."""
    car, rider = closing_contributions(trace)
    a = arrays(trace)
    _, _, pre, _ = _contact(a)
    standing = a.ego_speed[np.arange(pre.size), pre] < STANDING_MPS
    out = np.where(car >= rider, STRIKING[0], np.where(standing, STRIKING[2], STRIKING[1])).astype(
        object
    )
    out[np.isnan(car)] = ""
    return out


def injury_risk_of_speed(speed_mps: npt.ArrayLike, cfg: MetricsConfig | None = None) -> FloatArray:
    """Injury probability of the rider at impact speeds ``speed_mps`` (any shape, m/s):
    1 / (1 + exp(b0 - b1 * 3.6 v)); NaN stays NaN."""
    cfg = MetricsConfig() if cfg is None else cfg
    v_kmh = np.asarray(speed_mps, dtype=np.float64) * KMH_PER_MPS
    return 1.0 / (1.0 + np.exp(cfg.injury_intercept - cfg.injury_slope_per_kmh * v_kmh))


def injury_risk(trace: Trace | TraceArrays, cfg: MetricsConfig | None = None) -> FloatArray:
    """[B] the rider's injury risk at the impact speed (probability in (0, 1); the outcome
    is ``cfg.injury_outcome``); 0 without collision (no impact, no injury); NaN for a
    collision without an approach (impact speed unknown)."""
    a = arrays(trace)
    return injury_risk_at_impact(a.collided.any(axis=1), impact_speed(a, cfg), cfg)


def injury_risk_at_impact(
    collided: npt.ArrayLike, speed_mps: npt.ArrayLike, cfg: MetricsConfig | None = None
) -> FloatArray:
    """[B] the rider's injury risk of B runs from whether each collided and its impact
    speed [m/s]: :func:`injury_risk_of_speed` where it collided (NaN speed: NaN), else 0."""
    return np.where(collided, injury_risk_of_speed(speed_mps, cfg), 0.0)


def verdict(
    collision: npt.ArrayLike,
    impact_speed_mps: npt.ArrayLike,
    none_collision: npt.ArrayLike,
    none_impact_speed_mps: npt.ArrayLike,
    mitigation_share: float = MetricsConfig.mitigation_share,
) -> ObjArray:
    """Verdict of B policy runs against their no-avoidance runs (same variants, same order).

    Args:
        collision, impact_speed_mps: [B] the policy runs (speed NaN where no collision).
        none_collision, none_impact_speed_mps: [B] the no-avoidance ('none') runs.
        mitigation_share: the share in (0, 1) by which the impact speed must drop.
    Returns:
        [B] 'avoided' (no collision), 'mitigated' (impact speed <= (1 - share) x the
        no-avoidance run's), else 'not-mitigated' (also a collision the 'none' run did
        not have).
    """
    if not 0.0 < mitigation_share < 1.0:
        raise ValueError(f"mitigation_share must lie in (0, 1), got {mitigation_share}")
    hit = np.asarray(collision, dtype=bool)
    v = np.asarray(impact_speed_mps, dtype=np.float64)
    none_hit = np.asarray(none_collision, dtype=bool)
    v0 = np.asarray(none_impact_speed_mps, dtype=np.float64)
    if not (hit.shape == v.shape == none_hit.shape == v0.shape):
        raise ValueError(
            f"verdict needs equal shapes, got {hit.shape}, {v.shape}, {none_hit.shape}, {v0.shape}"
        )
    with np.errstate(invalid="ignore"):
        reduced = none_hit & (v <= (1.0 - mitigation_share) * v0)
    out = np.where(hit, np.where(reduced, VERDICTS[1], VERDICTS[2]), VERDICTS[0])
    return out.astype(object)
