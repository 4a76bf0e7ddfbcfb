"""Cars that react: the Intelligent Driver Model on the recorded path, written once for both
engines (NumPy ufuncs and :func:`vei.models.ego_core.select` / ``maximum`` / ``minimum``
only: vectorised in :mod:`vei.sim.traffic`, compiled on scalars in
:mod:`vei.sim.kernel.traffic`).

The IDM (Treiber, Hennecke & Helbing 2000, Phys. Rev. E 62:1805; Treiber & Kesting 2013,
*Traffic Flow Dynamics*, eq. 11.3-11.4)::

    a_IDM = a [1 - (v / v0)^delta - (s*(v, dv) / s)^2]
    s*(v, dv) = s0 + max(0, v T + v dv / (2 sqrt(a b)))      dv = v - v_leader

with the gap s bumper to bumper (no leader: s = +inf). A reacting car follows its own
recorded intent bounded by it: ``a = min(a_intent, a_IDM)`` in [-max_decel, a], where
``a_intent = a_rec + (v_rec - v) / T`` (its recorded acceleration and speed at that time:
a speed deficit is closed within one time headway).

Units: speeds [m/s], accelerations [m/s^2], gaps and distances [m], times [s].
"""

from __future__ import annotations

from typing import Any

import numpy as np

from vei.models.ego_core import maximum, minimum, select

#: Smallest gap [m] the IDM divides by (touching or overlapping: the strongest braking).
GAP_FLOOR_M = 0.01
#: Modes of a reacting car (int codes in the engine's arrays): replayed as recorded,
#: reacting (noticed a deviation; still on its recording for its reaction time), driven
#: by the IDM, stopped by a contact.
REPLAY, REACTING, IDM, STOPPED = 0, 1, 2, 3


def idm_accel_core(
    v_mps: Any, v_lead_mps: Any, gap_m: Any, v0_mps: Any, t_headway_s: Any, s0_m: Any,
    a_mps2: Any, b_mps2: Any, delta: Any,
) -> Any:  # fmt: skip
    """The IDM acceleration [m/s^2] of a car at speed v behind a leader at v_lead, ``gap_m``
    bumper to bumper (+inf: no leader). Parameters: v0, T, s0, a, b, delta."""
    s_star = s0_m + maximum(
        0.0, v_mps * t_headway_s + v_mps * (v_mps - v_lead_mps) / (2.0 * np.sqrt(a_mps2 * b_mps2))
    )
    ratio = s_star / maximum(gap_m, GAP_FLOOR_M)
    return a_mps2 * (1.0 - (v_mps / v0_mps) ** delta - ratio * ratio)


def car_accel_core(
    a_rec_mps2: Any, v_rec_mps: Any, v_mps: Any, a_idm_mps2: Any, t_headway_s: Any,
    a_mps2: Any, max_decel_mps2: Any,
) -> Any:  # fmt: skip
    """A reacting car's acceleration [m/s^2]: its recorded intent ``a_rec + (v_rec - v) / T``
    bounded by the IDM, within [-max_decel, a]."""
    intent = a_rec_mps2 + (v_rec_mps - v_mps) / maximum(t_headway_s, 0.1)
    return maximum(minimum(minimum(intent, a_idm_mps2), a_mps2), -max_decel_mps2)


def notices_core(a_actual_mps2: Any, a_recorded_mps2: Any, trigger_mps2: Any) -> Any:
    """The driver notices a deviation: the IDM towards the actual leader asks at least
    ``trigger_mps2`` more braking than towards the recorded one."""
    return a_actual_mps2 < a_recorded_mps2 - trigger_mps2


def leader_gap_core(
    sigma_m: Any, lat_m: Any, ext_m: Any, s_car_m: Any, half_length_m: Any, lat_limit_m: Any
) -> Any:
    """The bumper-to-bumper gap [m] to a road user mapped onto the car's path (its arc
    ``sigma_m`` along the car's path, lateral offset ``lat_m``, half-extent along the path
    ``ext_m``), +inf where it is not on the path ahead (|lat| > ``lat_limit_m`` or behind
    the car's centre)."""
    ahead = np.logical_and(np.abs(lat_m) <= lat_limit_m, sigma_m > s_car_m)
    gap = sigma_m - s_car_m - half_length_m - ext_m
    return select(ahead, gap, np.inf)
