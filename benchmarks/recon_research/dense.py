"""Rider kinematics reconstructed from dense vs sparse keyframes (issue 36: ``interp='auto'``).

Two measurements:

* :func:`recording_figures`: per shared TrafficMonitoring recording, imported at the
  camera's 30 Hz (as tests/datasets/test_two_doors.py does) and at the paper's 1 Hz, each
  rider's reconstructed speed (the trajectories' ``speed_mps``) and acceleration (finite
  differences of the 20 Hz positions, what a simulator replaying them sees): max and p99,
  per method, next to the speed of its keyframe positions over 1 s windows
  (:func:`windowed_speed`).
* :func:`synthetic_rmse`: a rider at a known 4 m/s on a curve, sampled at 1-30 Hz with
  Gaussian position noise, reconstructed per method: RMSE of the speed against the truth.

Run: ``python -m benchmarks.recon_research.dense`` (``$VEI_DATA_DIR`` or ../shared/data).
"""

from __future__ import annotations

import os
import sys
import tempfile
import warnings
from collections.abc import Iterable
from pathlib import Path

import numpy as np
import pandas as pd

from vei.recon.interpolate import fit_track_segmented
from vei.recon.pipeline import ReconstructionConfig, reconstruct
from vei.types import RIDER_CATEGORIES, Scenario

#: Window of the displacement speed [s].
WINDOW_S = 1.0


def windowed_speed(
    t_s: np.ndarray, xy_m: np.ndarray, window_s: float = WINDOW_S, max_gap_s: float = 2.5
) -> np.ndarray:
    """Speed of the positions over ``window_s`` windows: |p(t + w) - p(t)| / w [m/s].

    The track is split where consecutive keyframes are more than ``max_gap_s`` apart (as
    the reconstruction splits it); a part shorter than w gives its mean speed over its own
    span (w = that span).

    Args:
        t_s: [K] strictly increasing keyframe times [s]; xy_m: [K, 2] positions [m].
        window_s: window length w [s].
        max_gap_s: gap [s] that splits the track (ReconstructionConfig.max_gap_s).
    Returns:
        [M] speeds, one for every keyframe time t of a part with t + w inside that part
        (p(t + w) linear between keyframes); parts of one keyframe give none.
    """
    t = np.asarray(t_s, dtype=np.float64)
    xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
    cuts = np.flatnonzero(np.diff(t) > max_gap_s) + 1
    out = []
    for ts, ps in zip(np.split(t, cuts), np.split(xy, cuts), strict=True):
        if ts.size < 2:
            continue
        w = min(window_s, ts[-1] - ts[0])
        t0 = ts[ts + w <= ts[-1] + 1e-9]
        t1 = t0 + w
        p0 = np.column_stack([np.interp(t0, ts, ps[:, 0]), np.interp(t0, ts, ps[:, 1])])
        p1 = np.column_stack([np.interp(t1, ts, ps[:, 0]), np.interp(t1, ts, ps[:, 1])])
        out.append(np.linalg.norm(p1 - p0, axis=1) / w)
    return np.concatenate(out) if out else np.zeros(0)


def rider_rows(scenario: Scenario) -> list[dict]:
    """Per rider of a reconstructed scenario: keyframe spacing, max / p99 of its speed
    [m/s] and of its acceleration [m/s^2] (finite differences of the rate_hz positions),
    max / p99 of its 1 s windowed keyframe speed [m/s], and the method used."""
    rows = []
    methods = {t["agent_id"]: t["method"] for t in scenario.extra["reconstruction"]["tracks"]}
    for agent in scenario.agents:
        if agent.category not in RIDER_CATEGORIES:
            continue
        tr = scenario.track(agent.agent_id)
        kf = scenario.keyframes[scenario.keyframes["agent_id"] == agent.agent_id]
        t = tr["t_s"].to_numpy(float)
        xy = tr[["x_m", "y_m"]].to_numpy(float)
        tk = kf["t_s"].to_numpy(float)
        win = windowed_speed(tk, kf[["x_m", "y_m"]].to_numpy(float))
        speed = tr["speed_mps"].to_numpy(float)
        if t.size >= 3:
            v = np.gradient(xy, t, axis=0)
            acc = np.linalg.norm(np.gradient(v, t, axis=0), axis=1)
        else:
            acc = np.zeros(1)
        rows.append(
            {
                "agent_id": agent.agent_id,
                "n_keyframes": int(tk.size),
                "median_dt_s": float(np.median(np.diff(tk))) if tk.size > 1 else float("nan"),
                "method": methods.get(agent.agent_id),
                "v_max": float(speed.max()),
                "v_p99": float(np.percentile(speed, 99)),
                "a_max": float(acc.max()),
                "a_p99": float(np.percentile(acc, 99)),
                "win_max": float(win.max()) if win.size else float("nan"),
                "win_p99": float(np.percentile(win, 99)) if win.size else float("nan"),
            }
        )
    return rows


def recording_figures(
    root: Path,
    names: Iterable[str],
    rates_hz: Iterable[float] = (30.0, 1.0),
    methods: Iterable[str] = ("cubic", "smoothing", "auto"),
    door_b: bool = True,
) -> pd.DataFrame:
    """Rider figures (:func:`rider_rows`) per recording, door, annotation rate and method.

    Door A: ``vei import trafficmonitoring`` at each rate; door B (``door_b``): the
    recording in the inD layout at the camera's 30 Hz, imported with the INS as the ego
    (as tests/datasets/test_two_doors.py). Recordings that do not import (no riders) are
    left out."""
    from vei.datasets import ind
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.datasets.trafficmonitoring_ind import write_as_ind
    from vei.datasets.world_import import build_interaction
    from vei.errors import InputError
    from vei.io.interaction import read_interaction

    rows = []
    methods = list(methods)
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            inters = []
            for rate in rates_hz:
                out = Path(tmp) / f"{name}_{rate:g}"
                try:
                    import_scenario(root, name, out, rate_hz=rate)
                except InputError:
                    continue
                inters.append(("A", rate, read_interaction(out)))
            if door_b and inters:
                ex = write_as_ind(root, name, Path(tmp) / f"{name}_ind")
                rec = ind.read_recording(Path(tmp) / f"{name}_ind", ex.recording)
                inters.append(("B", 30.0, build_interaction(rec, ex.ins_ego_id)))
            for door, rate, inter in inters:
                for method in methods:
                    sc = reconstruct(inter, ReconstructionConfig(interp=method))
                    for r in rider_rows(sc):
                        rows.append(
                            {
                                "recording": name,
                                "door": door,
                                "rate_hz": rate,
                                "interp": method,
                                **r,
                            }
                        )
    return pd.DataFrame(rows)


def curve_truth(t_s: np.ndarray, speed_mps: float = 4.0, radius_m: float = 15.0) -> np.ndarray:
    """Positions [N, 2] (m) of a rider on a circle of ``radius_m`` at ``speed_mps``."""
    ang = speed_mps * np.asarray(t_s, dtype=np.float64) / radius_m
    return radius_m * np.column_stack([np.sin(ang), 1.0 - np.cos(ang)])


def synthetic_rmse(
    noise_m: float,
    methods: Iterable[str] = ("cubic", "smoothing"),
    rate_hz: float = 30.0,
    duration_s: float = 10.0,
    speed_mps: float = 4.0,
    seed: int = 0,
) -> dict[str, float]:
    """Speed RMSE [m/s] against the true ``speed_mps`` of each method on a 20 Hz grid, for a
    rider on a 15 m radius curve sampled at ``rate_hz`` with Gaussian noise ``noise_m``
    [m] per axis (ReconstructionConfig's smoothing defaults)."""
    rng = np.random.default_rng(seed)
    tk = np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz)
    xy = curve_truth(tk, speed_mps) + rng.normal(0.0, noise_m, (tk.size, 2))
    grid = np.arange(0.0, duration_s + 1e-9, 0.05)
    cfg = ReconstructionConfig()
    out = {}
    for method in methods:
        f = fit_track_segmented(tk, xy, method, cfg.smoothing, cfg.max_gap_s)
        v = np.linalg.norm(f.velocity(grid), axis=1)
        out[method] = float(np.sqrt(np.mean((v - speed_mps) ** 2)))
    return out


def main() -> int:
    """Print both tables."""
    from vei.datasets.trafficmonitoring import list_scenarios

    base = Path(
        os.environ.get("VEI_DATA_DIR") or Path(__file__).resolve().parents[3] / "shared" / "data"
    )
    root = base / "trafficmonitoring"
    pd.set_option("display.width", 200)
    pd.set_option("display.max_rows", 500)
    methods = [a for a in sys.argv[1:] if not a.startswith("-")] or ["cubic", "smoothing", "auto"]
    warnings.simplefilter("ignore")  # the implausible speeds are what is measured here
    df = recording_figures(root, list_scenarios(root), methods=methods)
    print(df.round(2).to_string(index=False))
    print("\nspeed RMSE [m/s] vs the true 4 m/s on a 15 m radius curve (20 s, mean of 10 seeds):")
    rows = []
    for noise in (0.1, 0.2, 0.25, 0.3):
        for rate in (1.0, 2.0, 5.0, 10.0, 30.0):
            r = [synthetic_rmse(noise, rate_hz=rate, duration_s=20.0, seed=s) for s in range(10)]
            rows.append(
                {"noise_m": noise, "rate_hz": rate}
                | {m: float(np.mean([x[m] for x in r])) for m in r[0]}
            )
    print(pd.DataFrame(rows).round(3).to_string(index=False))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
