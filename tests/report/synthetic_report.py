"""SYNTHETIC report data for scale tests (issue 35.3): N encounters shaped exactly like
:func:`vei.catalogue.report_data.encounter_data`'s (same keys, array lengths of a typical
TrafficMonitoring encounter: 4 road users over 30 s of tracks at 5 Hz, 5 case-study
configurations replayed over 10 s at 10 Hz, a 240-variant sweep, the TTC at 20 Hz over the
window), with made-up but smooth motion (constant headings, accelerations a random walk), the
riders' the same in every configuration as in vei's case study, the TTC and its zones
computed from the ego's and the rider's motion. Not measured data: for sizes and load times
only."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import numpy as np
import pandas as pd

from vei.catalogue.report_data import OVERVIEW_COLUMNS
from vei.catalogue.report_maps import catalogue_map, risk_map

CONFIGS = ("replay", "normal", "aggressive", "normal-cap", "aggressive-cap")
N_SWEEP = 240


def _sweep_rows(rng: np.random.Generator, eid: str) -> pd.DataFrame:
    t = rng.uniform(-2, 2, N_SWEEP)
    v = rng.uniform(3, 9, N_SWEEP)
    coll = rng.random(N_SWEEP) < np.clip(0.5 - np.abs(t) * 0.3 + (v - 6) * 0.05, 0, 1)
    return pd.DataFrame({
        "encounter_id": eid, "kind": "sweep", "p.time_shift_s": t, "p.ego.cruise_speed_mps": v,
        "collision": coll, "safety_index": np.where(coll, 0.0, rng.uniform(0.3, 1.0, N_SWEEP)),
        "seen_too_late": False,
    })  # fmt: skip


def _agent(rng: np.random.Generator, n: int, dt: float) -> dict[str, np.ndarray]:
    heading = rng.uniform(-np.pi, np.pi)
    # the acceleration a random walk (0.5 m/s^2 per sqrt(s), within +-3 m/s^2), the speed
    # its integral: smooth as a vehicle's (white-noise acceleration made the synthetic ego
    # two to three times as costly to store as a real one)
    acc = np.clip(np.cumsum(rng.normal(0.0, 0.5 * np.sqrt(dt), n)), -3.0, 3.0)
    speed = np.clip(rng.normal(5.0, 1.0) + np.cumsum(acc * dt), 0, None)
    s = np.cumsum(speed * dt)
    return {
        "x": 10 * rng.normal() + s * np.cos(heading),
        "y": 10 * rng.normal() + s * np.sin(heading),
        "yaw": np.full(n, heading),
        "speed": speed,
    }


def _ttc(a: dict[str, np.ndarray], b: dict[str, np.ndarray]) -> np.ndarray:
    """Time to collision of two points [s] (distance / closing speed, NaN when not closing,
    clipped at 10 s as the report's plot), from their positions and headings."""
    dx, dy = b["x"] - a["x"], b["y"] - a["y"]
    dist = np.hypot(dx, dy)
    vx = b["speed"] * np.cos(b["yaw"]) - a["speed"] * np.cos(a["yaw"])
    vy = b["speed"] * np.sin(b["yaw"]) - a["speed"] * np.sin(a["yaw"])
    closing = -(dx * vx + dy * vy) / np.maximum(dist, 1e-9)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(closing > 0.1, np.minimum(dist / closing, 10.0), np.nan)


def encounter(i: int, columns: list[dict[str, Any]]) -> tuple[dict[str, Any], pd.DataFrame]:
    """(encounter ``i``'s data, its sweep rows) with a fixed seed per ``i``."""
    rng = np.random.default_rng(i)
    eid = f"synthetic_{i // 3:05d}__cyclist_{i % 3}"
    sweep = _sweep_rows(rng, eid)
    t_track = np.arange(0, 30, 0.2)
    tracks = {}
    for aid, cat in (
        ("ego", "car"),
        ("cyclist_1", "cyclist"),
        ("cyclist_2", "cyclist"),
        ("escooter_3", "escooter"),
    ):
        a = _agent(rng, t_track.size, 0.2)
        tracks[aid] = {"category": cat, "x": a["x"], "y": a["y"], "t": t_track}
    t = np.round(np.arange(10.0, 20.0, 0.1), 2)
    t_full = np.round(np.arange(10.0, 20.0, 0.05), 2)
    # as in vei's case study: the riders replay their recorded motion in every
    # configuration, the ego's planner differs per configuration
    rider = _agent(rng, t_full.size, 0.05)
    others = {aid: {k: v[::2] for k, v in _agent(rng, t.size * 2, 0.05).items() if k in ("x", "y")}
              for aid in ("cyclist_2", "escooter_3")}  # fmt: skip
    configs = []
    for name in CONFIGS:
        ego = _agent(rng, t_full.size, 0.05)
        ttc_full = _ttc(ego, rider)
        ttc = ttc_full[::2]
        zone = np.where(ttc <= 1.0, 2, np.where(ttc <= 2.0, 1, 0))
        cap = ["CRUISE"] * t.size
        k = int(rng.integers(0, t.size))
        cap[k:] = ["BRAKE"] * (t.size - k)
        configs.append({
            "name": name, "ego": {a: v[::2] for a, v in ego.items()},
            "rider": {a: v[::2] for a, v in rider.items()}, "others": others, "cap": cap,
            "zone": zone, "ttc": ttc, "ttc_t": t_full, "ttc_full": ttc_full,
        })  # fmt: skip
    row = {c["key"]: None for c in columns}
    row.update({"rank": i + 1, "encounter_id": eid, "category": "cyclist",
                "rec_path_distance_m": rng.uniform(0, 5), "rec_pet_s": rng.uniform(0, 30),
                "rec_min_gap_m": rng.uniform(1, 10), "time_shift_auto_s": rng.normal(0, 10),
                "n_configs": 245, "n_flagged": 0, "collision_share": float(sweep["collision"].mean()),
                "mean_safety_index": float(sweep["safety_index"].mean()),
                "worst_min_gap_m": 0.0, "casestudy_collisions": int(rng.integers(0, 6)),
                "secondary_share": 0.0, "rear_end_share": 0.0})  # fmt: skip
    summary = [{"name": n, "collision": bool(rng.random() < 0.3), "collision_time_s": None,
                "safety_index": rng.uniform(0, 1), "safety_index_rel": rng.uniform(0, 1),
                "min_gap_m": rng.uniform(0, 5), "min_ttc_s": rng.uniform(0, 3),
                "peak_decel_mps2": rng.uniform(0, 6), "ego_speed_std_mps": rng.uniform(0, 2),
                "first_seen_gap_m": rng.uniform(5, 30), "seen_too_late": False}
               for n in CONFIGS]  # fmt: skip
    data = {
        "id": eid, "risk": None, "probmap": None, "row": row, "rider_id": "cyclist_1",
        "recording": eid.split("__")[0], "tracks": tracks, "roads": None,
        "road_layers": {"note": "no map (synthetic)"},
        "replay": {"t": t, "configs": configs, "dims": {"ego": [4.7, 1.85], "cyclist_1": [1.8, 0.6]},
                   "window": [10.0, 20.0]},
        "summary": summary, "time_shift_s": row["time_shift_auto_s"], "riskmap": risk_map(sweep),
    }  # fmt: skip
    return data, sweep


def synthetic_site(n: int) -> tuple[dict[str, Any], Iterator[dict[str, Any]]]:
    """(index, encounters) of ``n`` SYNTHETIC encounters for
    :func:`vei.report.html_site.write_site`; the index's catalogue map is drawn from every
    encounter's synthetic sweep (n x 240 variants)."""
    columns = [{"key": k, "label": lab, "fmt": f, "title": t} for k, lab, f, t in OVERVIEW_COLUMNS]
    rng = np.random.default_rng(12345)
    t = rng.uniform(-2, 2, n * N_SWEEP)
    v = rng.uniform(3, 9, n * N_SWEEP)
    rows = pd.DataFrame({
        "encounter_id": np.repeat(np.arange(n), N_SWEEP).astype(str), "kind": "sweep",
        "p.time_shift_s": t, "p.ego.cruise_speed_mps": v,
        "collision": rng.random(t.size) < np.clip(0.6 - np.abs(t) * 0.4 + (v - 6) * 0.1, 0, 1),
        "seen_too_late": False,
    })  # fmt: skip
    index = {
        "dataset": f"SYNTHETIC ({n} encounters)", "status": "complete", "n_rows": n * 245,
        "settings": {}, "recordings": [], "failed_encounters": [], "columns": columns,
        "ranked_by": "criticality", "catalogue_map": catalogue_map(rows),
    }  # fmt: skip
    return index, (encounter(i, columns)[0] for i in range(n))
