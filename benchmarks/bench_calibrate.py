"""Benchmark + report: rider calibration on the shared TrafficMonitoring data.

Times each stage (reading and smoothing the camera tracks of every scenario, the batched
closed-loop rollout, the per-track fit, the leave-one-scenario-out validation) and prints
the validation table (ADE / FDE at 3 s and 5 s: CV, CA, CS-path, the paper's SFM, the
calibrated SFM). Needs the data ($VEI_DATA_DIR, else ../shared/data).

    python -m benchmarks calibrate
"""

from __future__ import annotations

import os
import time
from pathlib import Path


def main() -> None:
    import numpy as np

    from vei.calibrate.fit import fit_tracks
    from vei.calibrate.rollout import make_windows, pack_paths, rollout_sfm
    from vei.calibrate.tracks import load_scenes
    from vei.calibrate.validate import PAPER_PARAMS, validate_loso

    root = Path(os.environ.get("VEI_DATA_DIR", "../shared/data")) / "trafficmonitoring"
    if not (root / "data" / "measurements").is_dir():
        print(f"real data not found under {root}: nothing to benchmark")
        return
    t0 = time.perf_counter()
    scenes = load_scenes(root)
    t_load = time.perf_counter() - t0
    by = {s.scenario: s for s in scenes}
    tracks = [t for s in scenes for t in s.riders]
    paths = pack_paths(tracks)
    win = make_windows(tracks, by, paths, 3.0, 0.5)
    reps = 20
    t0 = time.perf_counter()
    for _ in range(reps):
        rollout_sfm(paths, win, PAPER_PARAMS)
    t_roll = (time.perf_counter() - t0) / reps
    steps = win.size * win.horizon_steps
    t0 = time.perf_counter()
    res = fit_tracks(tracks, by, bootstrap=0)
    t_fit = time.perf_counter() - t0
    t0 = time.perf_counter()
    table = validate_loso(scenes, (3.0, 5.0))
    t_val = time.perf_counter() - t0
    print(f"{'stage':44s} {'time':>10s}")
    print(f"{'load + smooth 9 scenarios':44s} {t_load:9.2f}s")
    print(
        f"{f'rollout: {win.size} windows x {win.horizon_steps} steps':44s} {t_roll * 1e3:8.1f}ms"
        f"  ({steps / t_roll / 1e6:.2f} M rider-steps/s)"
    )
    print(f"{f'fit {len(res.tracks)} tracks (no bootstrap)':44s} {t_fit:9.2f}s")
    print(f"{'leave-one-scenario-out validation (4 folds)':44s} {t_val:9.2f}s")
    print()
    print(table.format())
    for h in table.horizons_s:
        print(
            f"ADE@{h:g}s calibrated SFM vs CV: {100 * table.gain('SFM calibrated', 'CV', h):+.0f} %, "
            f"vs paper SFM: {100 * table.gain('SFM calibrated', 'SFM paper', h):+.0f} %"
        )
    tau = np.array([f.tau_s for f in res.tracks])
    print(f"fitted relaxation time tau: median {np.median(tau):.2f} s over {tau.size} tracks")


if __name__ == "__main__":
    main()
