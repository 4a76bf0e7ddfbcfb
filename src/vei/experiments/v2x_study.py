"""The V2X case study: an occluded crossing, perception alone against perception + V2X.

The scene (:func:`occluded_crossing`, SYNTHETIC: the search of the shared recordings found
no case where the occlusion decides the outcome, docs/v2x.md): the car drives straight at
30 km/h; a van (5.9 x 2.1 m) is parked at the right kerb, its left side 1.45 m right of
the car's path; an e-scooter rider waits just ahead of the van's front, inside the car's
path corridor but hidden from its sensor by the van, then crosses (2 m/s^2 to 4 m/s). The
car runs the paper's CAP (``paper-cap``) on its perception (vei.policy.perception: range,
field of view, occlusion); the rider is a kinematic replay (it does not react).

:func:`compare` runs every time shift of the rider with perception alone, ideal
perception and perception + V2X (the rider's GNSS of a consumer smartphone, the default,
and of a corrected receiver); :func:`occlusion_window` is the span of shifts in which
perception alone collides. :func:`sweep_specs` are the sweeps over that window: latency x
packet-delivery factor, penetration rate, GNSS error. :func:`run_study` runs all of it and
the figures (:mod:`vei.experiments.v2x_run`, :mod:`vei.experiments.v2x_figures`).
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd

from vei.config import CaseConfig, PerceptionConfig, SimConfig, V2XConfig, case_preset
from vei.types import EGO_ID, Scenario

#: The rider's GNSS error of a corrected receiver per axis [m]: real-time precise point
#: positioning on a dual-frequency phone, horizontal RMS 0.81 m (Chen et al. 2019,
#: Sensors 19(12):2835) / sqrt(2).
PPP_GNSS_STD_M = round(0.81 / math.sqrt(2.0), 2)

#: Scene constants of :func:`occluded_crossing` (documented in docs/v2x.md).
EGO_SPEED_MPS = 8.3
CROSSING_X_M = 60.0
VAN_FRONT_X_M = 58.95
VAN_Y_M = -2.5
VAN_LENGTH_M, VAN_WIDTH_M = 5.9, 2.1
RIDER_WAIT_Y_M = -2.2
RIDER_GO_S = 12.0
RIDER_ACCEL_MPS2 = 2.0
RIDER_SPEED_MPS = 4.0


def occluded_crossing(
    *,
    ego_speed_mps: float = EGO_SPEED_MPS,
    rider_go_s: float = RIDER_GO_S,
    rider_accel_mps2: float = RIDER_ACCEL_MPS2,
    rider_speed_mps: float = RIDER_SPEED_MPS,
    duration_s: float = 20.0,
    rate_hz: float = 20.0,
) -> Scenario:
    """The synthetic occluded crossing (see the module docstring; labelled synthetic).

    Ego along +x on y = 0 from x = 0; van centre (VAN_FRONT_X_M - 2.95, VAN_Y_M); rider
    (e-scooter, heading +y) standing at (CROSSING_X_M, RIDER_WAIT_Y_M) until
    ``rider_go_s``, then accelerating at ``rider_accel_mps2`` to ``rider_speed_mps`` up to
    y = 15 m.
    """
    from vei.sim.testing import TrackSpec, ego_straight, make_scenario

    t = np.arange(int(round(duration_s * rate_hz)) + 1) / rate_hz
    van_x = VAN_FRONT_X_M - VAN_LENGTH_M / 2.0
    van = TrackSpec(
        "vehicle", t, np.full_like(t, van_x), np.full_like(t, VAN_Y_M), np.zeros_like(t),
        np.zeros_like(t), length_m=VAN_LENGTH_M, width_m=VAN_WIDTH_M,
    )  # fmt: skip
    tau = np.clip(t - rider_go_s, 0.0, None)
    t_acc = rider_speed_mps / rider_accel_mps2
    s = np.where(tau < t_acc, 0.5 * rider_accel_mps2 * tau**2,
                 0.5 * rider_speed_mps * t_acc + rider_speed_mps * (tau - t_acc))  # fmt: skip
    v = np.where(tau < t_acc, rider_accel_mps2 * tau, rider_speed_mps)
    y = RIDER_WAIT_Y_M + s
    keep = y <= 15.0
    rider = TrackSpec(
        "escooter", t[keep], np.full(int(keep.sum()), CROSSING_X_M), y[keep],
        np.full(int(keep.sum()), math.pi / 2.0), v[keep],
    )  # fmt: skip
    sc = make_scenario(
        {EGO_ID: ego_straight(ego_speed_mps, duration_s, rate_hz), "rider1": rider, "van": van},
        primary_threat="rider1",
        rate_hz=rate_hz,
        scenario_id="v2x-occluded-crossing",
    )
    note = (
        "SYNTHETIC occluded crossing of vei's V2X case study (vei.experiments.v2x_study): "
        "a van parked at the kerb hides an e-scooter rider waiting ahead of it, who then "
        "crosses; no shared recording had a case where the occlusion decides (docs/v2x.md)"
    )
    return replace(sc, extra={"synthetic": True, "note": note})


def study_case(v2x: V2XConfig | None = None, *, name: str = "v2x-study") -> CaseConfig:
    """The study's configuration: replayed rider, the paper's CAP on the policy API with
    the default perception (range 50 m, field of view 90 deg, occlusion), and ``v2x``."""
    base = case_preset("replay")
    case = replace(base, name=name, ego=replace(base.ego, policy="paper-cap"),
                   perception=PerceptionConfig(enabled=True))  # fmt: skip
    return replace(case, v2x=v2x) if v2x is not None else case


#: The configurations :func:`compare` runs: label -> (perception on, V2XConfig or None).
COMPARED: dict[str, tuple[bool, V2XConfig | None]] = {
    "perception alone": (True, None),
    "ideal perception": (False, None),
    "perception + V2X (smartphone GNSS)": (True, V2XConfig(enabled=True)),
    "perception + V2X (corrected GNSS)": (
        True, V2XConfig(enabled=True, position_error_std_m=PPP_GNSS_STD_M),
    ),
}  # fmt: skip


def compare(scenario: Scenario, shifts_s: np.ndarray, sim: SimConfig | None = None) -> pd.DataFrame:
    """Collisions of each :data:`COMPARED` configuration at each time shift.

    Args:
        scenario: the scene. shifts_s: [n] rider time shifts [s].
    Returns:
        DataFrame [n rows]: time_shift_s, then per configuration '<label>' (collided, bool)
        and '<label> t' (collision time [s], NaN without).
    """
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario

    arrays = prepare_scenario(scenario, sim or SimConfig())
    out = pd.DataFrame({"time_shift_s": np.asarray(shifts_s, dtype=np.float64)})
    labels = np.array([f"shift{x:+.3f}" for x in out["time_shift_s"]], dtype=object)
    for label, (perceived, v2x) in COMPARED.items():
        case = study_case(v2x)
        if not perceived:
            case = replace(case, perception=None)
        p = VariantParams.from_case(case, arrays, len(out), time_shift_s=out["time_shift_s"])
        res = simulate(arrays, p.with_values(labels=labels), record="none")
        out[label] = np.isfinite(res.collision_time_s)
        out[f"{label} t"] = res.collision_time_s
    return out


def occlusion_window(table: pd.DataFrame) -> tuple[float, float]:
    """(first, last) time shift [s] at which perception alone collides (:func:`compare`)."""
    hit = table.loc[table["perception alone"], "time_shift_s"]
    if hit.empty:
        raise ValueError("perception alone never collides: no occlusion window")
    return float(hit.min()), float(hit.max())


#: Sweep axes of the study (docs/v2x.md).
LATENCIES_S = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.75, 1.0, 1.5, 2.0)
PDR_FACTORS = (1.0, 0.8, 0.6, 0.4, 0.3, 0.2, 0.1, 0.05, 0.02, 0.0)
PENETRATIONS = (0.0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 1.0)
GNSS_STDS_M = (0.0, 0.25, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0)


def sweep_specs(
    window: tuple[float, float], step_2d_s: float, step_1d_s: float, *, quick: bool = False
) -> dict:
    """The study's sweep specs (mappings, the YAML form) over the occlusion window.

    Every spec: base 'replay' with ego.policy paper-cap, perception on, V2X on with the
    corrected GNSS (:data:`PPP_GNSS_STD_M`) unless swept, absolute time shifts
    (``time_shift_reference: zero``) over ``window`` every ``step_2d_s`` (latency x
    delivery) or ``step_1d_s`` (penetration, GNSS) seconds.

    Returns:
        {'latency_pdr': spec, 'penetration': spec, 'gnss': spec}.
    """

    def pick(seq: tuple[float, ...]) -> list[float]:
        return list(seq[::3] if quick else seq)

    def grid(step: float) -> dict:
        num = max(2, int(round((window[1] - window[0]) / step)) + 1)
        return {"min": float(window[0]), "max": float(window[1]), "num": num}

    common = {
        "design": "grid",
        "base": "replay",
        "time_shift_reference": "zero",
        "perception": {"enabled": True},
        "v2x": {"enabled": True, "position_error_std_m": PPP_GNSS_STD_M},
    }
    two = {"ego.policy": "paper-cap", "time_shift_s": grid(step_2d_s)}
    one = {"ego.policy": "paper-cap", "time_shift_s": grid(step_1d_s)}
    return {
        "latency_pdr": {**common, "parameters": {
            **two, "v2x.latency_s": {"choices": pick(LATENCIES_S)},
            "v2x.pdr_factor": {"choices": pick(PDR_FACTORS)}}},
        "penetration": {**common, "parameters": {
            **one, "v2x.penetration_rate": {"choices": pick(PENETRATIONS)}}},
        "gnss": {**common, "parameters": {
            **one, "v2x.position_error_std_m": {"choices": pick(GNSS_STDS_M)}}},
    }  # fmt: skip


def collision_share(results: pd.DataFrame, by: list[str]) -> pd.DataFrame:
    """Share of colliding variants per group, with a 95 % Wilson interval.

    Args:
        results: a sweep's results (column 'collision'). by: grouping columns.
    Returns:
        DataFrame: the ``by`` columns, n, collisions, share, lo, hi.
    """
    g = results.groupby(by, sort=True)["collision"]
    out = g.agg(n="size", collisions="sum").reset_index()
    n, k = out["n"].to_numpy(float), out["collisions"].to_numpy(float)
    z = 1.959963984540054
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    out["share"], out["lo"], out["hi"] = p, centre - half, centre + half
    return out


__all__ = [
    "COMPARED",
    "PPP_GNSS_STD_M",
    "collision_share",
    "compare",
    "occluded_crossing",
    "occlusion_window",
    "study_case",
    "sweep_specs",
]
