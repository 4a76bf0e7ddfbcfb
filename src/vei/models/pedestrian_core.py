"""Pedestrians by the social-force model (Helbing & Molnar 1995), written once: NumPy ufuncs
and :func:`vei.models.ego_core.select` only (vectorised in :mod:`vei.sim.pedestrians`).

Per pedestrian i (accelerations, the forces divided by its mass m)::

    dv/dt = (v0 e - v) / tau + sum_j w_ij A/m exp((r_i + r_j - d_ij) / B) n_ji
                             + sum_k w_ik A/m exp((r_i - d_ik) / B_v) n_ki

- the driving term: towards a goal on its own recorded path at its own desired speed v0
  (Helbing & Molnar 1995, Phys. Rev. E 51:4282; relaxation time tau 0.5 s);
- among pedestrians: the circular specification of Helbing, Farkas & Vicsek 2000 (Nature
  407:487): A = 2000 N, B = 0.08 m, radii r (0.25-0.35 m), m = 80 kg, d_ij the centre
  distance, n_ji the unit vector from j to i;
- from a vehicle or a rider k: the same exponential of the gap d_ik - ... from the closest
  point of its box (vehicles) or its disc (riders), with a longer range B_v (pedestrians
  step aside about a metre before contact; not in the literature, which models crowds);
- anisotropy (Helbing et al. 2005, Transp. Sci. 39:1): ``w = lambda + (1 - lambda)
  (1 + cos phi) / 2``, phi the angle between its walking direction and the direction to
  the source (lambda = 0.75: what is behind counts a quarter less);
- speeds capped at 1.3 v0 (Helbing & Molnar 1995).

Units: positions [m], velocities [m/s], accelerations [m/s^2], forces [N], masses [kg].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vei.models.ego_core import maximum, minimum, select

#: The speed cap as a multiple of the desired speed (Helbing & Molnar 1995: v_max = 1.3 v0).
MAX_SPEED_FACTOR = 1.3
#: Distance [m] over which the desired speed fades at the goal (the normalised desired
#: velocity of the riders, vei.models.sfm_core).
GOAL_SIGMA_M = 0.3
#: Beyond this gap [m] a source exerts no force (A exp(-10 / 0.08 m): nothing; vehicles:
#: 2000 N exp(-20) at B_v = 0.5 m).
CUTOFF_M = 10.0


def drive_accel_core(
    px: Any, py: Any, gx: Any, gy: Any, vx: Any, vy: Any, v0: Any, tau: Any
) -> tuple[Any, Any]:
    """(ax, ay) [m/s^2] of the driving term towards the goal g: ``(v_des - v) / tau`` with
    ``v_des = v0 d / sqrt(|d|^2 + GOAL_SIGMA_M^2)``, d = g - p."""
    dx = gx - px
    dy = gy - py
    f = v0 / np.sqrt(dx * dx + dy * dy + GOAL_SIGMA_M * GOAL_SIGMA_M)
    return (f * dx - vx) / tau, (f * dy - vy) / tau


def anisotropy_core(vx: Any, vy: Any, nx: Any, ny: Any, lam: Any) -> Any:
    """The weight ``lambda + (1 - lambda) (1 + cos phi) / 2`` of a force along (nx, ny)
    (unit, from the source to the pedestrian) on a pedestrian walking along (vx, vy):
    cos phi = the walking direction . (-n); standing (|v| ~ 0): isotropic (1)."""
    sp = np.sqrt(vx * vx + vy * vy)
    moving = sp > 1e-6
    cos_phi = -(vx * nx + vy * ny) / select(moving, sp, 1.0)
    return select(moving, lam + (1.0 - lam) * 0.5 * (1.0 + cos_phi), 1.0)


def repulsion_accel_core(
    dx: Any, dy: Any, gap_m: Any, a_n: Any, b_m: Any, mass_kg: Any, vx: Any, vy: Any, lam: Any
) -> tuple[Any, Any]:
    """(ax, ay) [m/s^2] on a pedestrian from a source at offset (dx, dy) = pedestrian -
    source point [m] whose gap to it is ``gap_m`` [m] (negative: overlapping):
    ``w A / m exp(-gap / B) n``, n = (dx, dy) / |(dx, dy)|; zero beyond CUTOFF_M or
    where the offset vanishes."""
    d = np.sqrt(dx * dx + dy * dy)
    acts = np.logical_and(d > 1e-9, gap_m < CUTOFF_M)
    safe = select(acts, d, 1.0)
    nx, ny = dx / safe, dy / safe
    mag = select(acts, a_n / mass_kg * np.exp(-maximum(gap_m, -CUTOFF_M) / b_m), 0.0)
    w = anisotropy_core(vx, vy, nx, ny, lam)
    return w * mag * nx, w * mag * ny


def speed_cap_core(vx: Any, vy: Any, v0: Any) -> tuple[Any, Any]:
    """The velocity capped at ``MAX_SPEED_FACTOR v0`` in speed."""
    sp = np.sqrt(vx * vx + vy * vy)
    f = minimum(1.0, MAX_SPEED_FACTOR * v0 / maximum(sp, 1e-9))
    return vx * f, vy * f


#: The largest acceleration [m/s^2] of a pedestrian: HFV's body-contact forces are meant for
#: steps of a few milliseconds; at the engine's 0.05 s they would throw a pedestrian
#: metres per step. 5 m/s^2 is about what a person reaches stepping aside or stopping.
MAX_ACCEL_MPS2 = 5.0


def accel_cap_core(ax: Any, ay: Any, amax: Any) -> tuple[Any, Any]:
    """The acceleration capped at ``amax`` [m/s^2] in magnitude."""
    a = np.sqrt(ax * ax + ay * ay)
    f = minimum(1.0, amax / maximum(a, 1e-9))
    return ax * f, ay * f
