"""The rider's yield / go decision at a conflict with the car, written once for both engines.

Like :mod:`vei.models.sfm_core`: NumPy ufuncs, arithmetic and
:func:`vei.models.ego_core.select` / :func:`~vei.models.ego_core.maximum` /
:func:`~vei.models.ego_core.minimum` only, so that the same source runs vectorised on
arrays ``[B]`` (the NumPy step, :mod:`vei.sim.decisions`; the calibration rollout) and
compiled by numba on scalars (:mod:`vei.sim.kernel.decision`).

A *conflict* is where the rider's path crosses the ego's path: arc length ``s_r_c`` [m]
along the rider's path and ``s_e_c`` along the ego's, and the half-lengths of the
*conflict zone* along each path (:func:`zone_half_lengths_core`): the stretch of the
rider's path on which its box overlaps the car's swept strip, and the stretch of the
ego's path on which the car's box overlaps the rider's. The rider compares the times to
arrive at the zone (TTA) and decides on the *offered gap* ``DTA = TTA_car - TTA_rider``
(difference in time-to-arrival; Mohammadi, Bianchi Piccinini & Dozza 2023, Accid. Anal.
Prev. 107156): go when DTA >= its critical gap t_c, else yield. A deterministic rider has
its own t_c; a population of riders whose t_c follows a logistic distribution (location
t_c, scale s) goes with probability ``1 / (1 + exp(-(DTA - t_c) / s))``
(:func:`go_probability_core`), the logistic gap-acceptance model.

Decision states (int codes): FREE (no live conflict within the horizon: the social force
alone), GO (committed: rides on until it has crossed the zone), YIELD (lets the car pass
first: brakes towards a stop short of the zone where it would otherwise enter before the
car has left; decides again every step).

Units: arc lengths and distances [m], speeds [m/s], times [s], decelerations [m/s^2].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vei.models.ego_core import maximum, minimum, select

#: Decision states.
FREE, GO, YIELD = 0, 1, 2
#: Speed floor [m/s] of a time to arrive (a standing car arrives "never": 20 m -> 400 s).
V_FLOOR_MPS = 0.05
#: Smallest crossing angle [rad] of a conflict zone's extent (20 deg): at shallower angles
#: the paths run alongside each other, which is following, not crossing.
MIN_CROSSING_RAD = float(np.deg2rad(20.0))


def zone_half_lengths_core(
    sin_abs: Any, cos_abs: Any, ego_l_m: Any, ego_w_m: Any, rider_l_m: Any, rider_w_m: Any
) -> tuple[Any, Any]:
    """Half-lengths [m] of the conflict zone along the rider's and the ego's paths.

    The paths cross at an angle theta (|sin theta| = ``sin_abs``, clamped below at
    sin(:data:`MIN_CROSSING_RAD`) by the caller; |cos theta| = ``cos_abs``). The rider's
    box (length x width) overlaps the car's swept strip of half-width W_e / 2 while its
    centre is within ``(W_e / 2 + L_r / 2 sin + W_r / 2 cos) / sin`` of the crossing along
    its path; the car's box overlaps the rider's strip within
    ``(W_r / 2 + L_e / 2 sin + W_e / 2 cos) / sin`` along the ego's path.

    Returns:
        (hz_rider_m, hz_ego_m).
    """
    hz_r = (0.5 * ego_w_m + 0.5 * rider_l_m * sin_abs + 0.5 * rider_w_m * cos_abs) / sin_abs
    hz_e = (0.5 * rider_w_m + 0.5 * ego_l_m * sin_abs + 0.5 * ego_w_m * cos_abs) / sin_abs
    return hz_r, hz_e


def reference_speed_core(v0_mps: Any, lookahead_m: Any, sigma_m: Any) -> Any:
    """The speed floor [m/s] of the rider's own time to arrive: half its cruise speed
    ``v0 L / sqrt(L^2 + sigma^2)`` (a rider starting from rest covers a short distance at
    about half the speed it reaches)."""
    return 0.5 * v0_mps * lookahead_m / np.sqrt(lookahead_m * lookahead_m + sigma_m * sigma_m)


def conflict_times_core(
    prog_m: Any, v_rider_mps: Any, s_ego_m: Any, v_ego_mps: Any,
    s_r_c_m: Any, s_e_c_m: Any, hz_r_m: Any, hz_e_m: Any, clear_m: Any, v_ref_mps: Any,
) -> tuple[Any, Any, Any, Any, Any]:  # fmt: skip
    """What the rider knows of one conflict.

    Args:
        prog_m: the rider's arc length along its path [m]. v_rider_mps: its speed.
        s_ego_m: the ego's arc length along its path [m] (its centre). v_ego_mps: its speed.
        s_r_c_m, s_e_c_m: the crossing's arc lengths along both paths [m].
        hz_r_m, hz_e_m: the zone's half-lengths along both paths [m].
        clear_m: the car has left the zone once its centre is this far beyond it [m].
        v_ref_mps: the rider's speed floor of its time to arrive [m/s].
    Returns:
        (d_r, tta_r, dta, t_clear, live): the rider's distance to the zone [m] (<= 0:
        inside or past), its time to arrive [s] (at least at ``v_ref``), the offered gap
        DTA = TTA_car - TTA_rider [s] (TTA_car = 0 while the car is in the zone), the time
        until the car has left the zone [s], and ``live``: the rider has not passed the
        zone and the car has not left it.
    """
    d_r = s_r_c_m - hz_r_m - prog_m
    tta_r = maximum(d_r, 0.0) / maximum(v_rider_mps, v_ref_mps)
    v_e = maximum(v_ego_mps, V_FLOOR_MPS)
    tta_e = maximum(s_e_c_m - hz_e_m - s_ego_m, 0.0) / v_e
    out_e = s_e_c_m + hz_e_m + clear_m - s_ego_m
    t_clear = maximum(out_e, 0.0) / v_e
    live = np.logical_and(prog_m <= s_r_c_m + hz_r_m, out_e >= 0.0)
    return d_r, tta_r, tta_e - tta_r, t_clear, live


def decide_core(
    state: Any, live: Any, dta_s: Any, tta_r_s: Any, d_r_m: Any, t_c_s: Any, horizon_s: Any
) -> Any:
    """The new decision state (FREE / GO / YIELD) of a rider at one conflict.

    No live conflict: FREE. GO stays GO (committed), and a rider inside the zone goes (it
    must clear it). Within the horizon (or already yielding) the rider decides: GO when
    the offered gap ``dta_s`` >= its critical gap ``t_c_s``, else YIELD. Before the horizon:
    FREE.
    """
    decided = select(dta_s >= t_c_s, GO, YIELD)
    go_now = np.logical_or(state == GO, d_r_m <= 0.0)
    ask = np.logical_or(tta_r_s <= horizon_s, state == YIELD)
    return select(live, select(go_now, GO, select(ask, decided, FREE)), FREE)


def yield_speed_core(
    state: Any, d_r_m: Any, v_rider_mps: Any, tta_r_s: Any, t_clear_s: Any,
    stop_margin_m: Any, decel_mps2: Any, tau_s: Any,
) -> Any:  # fmt: skip
    """The speed cap [m/s] of a yielding rider (+inf where there is none).

    A YIELD rider that would reach the zone before the car has left it (``tta_r`` <
    ``t_clear``) brakes towards a stop ``stop_margin_m`` short of the zone: its desired
    speed is at most ``sqrt(2 a d)``, d = the distance left to that stop minus what it
    covers in its relaxation time ``tau_s`` (m / k_des: the social force follows a desired
    speed with that lag), ``a = decel_mps2``.
    """
    d_stop = d_r_m - stop_margin_m - v_rider_mps * tau_s
    cap = np.sqrt(2.0 * decel_mps2 * maximum(d_stop, 0.0))
    brake = np.logical_and(state == YIELD, tta_r_s < t_clear_s)
    return select(brake, cap, np.inf)


def capped_velocity_core(vx_mps: Any, vy_mps: Any, cap_mps: Any) -> tuple[Any, Any]:
    """The desired velocity (vx, vy) [m/s] scaled down to at most ``cap_mps`` in speed
    (unchanged where the cap is +inf or not binding)."""
    speed = np.sqrt(vx_mps * vx_mps + vy_mps * vy_mps)
    f = minimum(1.0, cap_mps / maximum(speed, 1e-9))
    return vx_mps * f, vy_mps * f


def go_probability_core(dta_s: Any, t_c_s: Any, scale_s: Any) -> Any:
    """P(go | offered gap) of a population whose critical gaps are logistic (location
    ``t_c_s``, scale ``scale_s`` > 0): ``1 / (1 + exp(-(dta - t_c) / s))``."""
    return 1.0 / (1.0 + np.exp(-(dta_s - t_c_s) / scale_s))
