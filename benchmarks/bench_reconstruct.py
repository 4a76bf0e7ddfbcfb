"""Benchmark: reconstruction of the 61 s real scenario stadtmitte_12_audi_geradeaus_03.

The scenario is imported from the trafficmonitoring data ($VEI_DATA_DIR or ../shared/data)
into a temporary interaction folder and read once (not timed); then ``reconstruct()`` runs
in-process for each interpolation option: one warm-up, then the median of ``RUNS`` runs.
Target (issue 2): under 1 s per reconstruction.
"""

from __future__ import annotations

import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

SCENARIO = "stadtmitte_12_audi_geradeaus_03"
TARGET_S = 1.0
RUNS = 7
REPO = Path(__file__).resolve().parents[1]


def _data_root() -> Path | None:
    env = os.environ.get("VEI_DATA_DIR")
    base = Path(env) if env else REPO.parent / "shared" / "data"
    root = base / "trafficmonitoring"
    return root if root.exists() else None


def main() -> int:
    """Run the benchmark and print its table; returns 0 (1 if a target is missed)."""
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction
    from vei.recon.interpolate import INTERP_METHODS
    from vei.recon.pipeline import ReconstructionConfig, reconstruct

    root = _data_root()
    if root is None:
        print("bench_reconstruct: trafficmonitoring data not found (set VEI_DATA_DIR); skipped")
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        interaction = read_interaction(import_scenario(root, SCENARIO, Path(tmp) / SCENARIO))
    n_ann = len(interaction.annotations)
    span = interaction.ego["t_s"].iloc[-1] - interaction.ego["t_s"].iloc[0]
    rows = []
    for method in INTERP_METHODS:
        cfg = ReconstructionConfig(interp=method)
        scenario = reconstruct(interaction, cfg)  # warm-up (imports, caches)
        times = []
        for _ in range(RUNS):
            t0 = time.perf_counter()
            scenario = reconstruct(interaction, cfg)
            times.append(time.perf_counter() - t0)
        err = scenario.extra["reconstruction_error"]["riders"]
        rows.append(
            (
                method,
                statistics.median(times),
                min(times),
                len(scenario.trajectories),
                err["mean_rmse_m"],
                err["max_rmse_m"],
            )
        )
    print(
        f"reconstruct(): {SCENARIO} ({span:.0f} s, {n_ann} annotations, 20 Hz), median of {RUNS} runs"
    )
    print(
        f"{'interp':<10} {'median [s]':>10} {'min [s]':>8} {'target [s]':>10} {'ok':>3} {'rows':>6} {'mean RMSE [m]':>13} {'max RMSE [m]':>12}"
    )
    ok_all = True
    for method, med, best, nrows, mean_rmse, max_rmse in rows:
        ok = med < TARGET_S
        ok_all &= ok
        print(
            f"{method:<10} {med:>10.3f} {best:>8.3f} {'< ' + str(TARGET_S):>10} {'yes' if ok else 'NO':>3} {nrows:>6} {mean_rmse:>13.3f} {max_rmse:>12.3f}"
        )
    return 0 if ok_all else 1


if __name__ == "__main__":
    sys.exit(main())
