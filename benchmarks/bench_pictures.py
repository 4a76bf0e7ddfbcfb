"""Benchmark: the pictures of a sweep at any size (issue 35.0).

Every sweep picture is drawn from at most MAX_BINS_PER_AXIS^2 = 400 binned cells
(vei.sweep.riskmap), whatever the number of variants. Printed:

1. **a real grid sweep of the demo** (``--side-t`` time-shift values x ``--side-v`` cruise
   speeds, default 100 x 100 = 10^4 variants, ``--workers 2``): the sweep's phases
   (``SweepResult.timings``: prepare, evaluate = the variants, results, post = critical
   variants and every map), then each picture drawn again on its results.parquet, timed
   alone;
2. **10^6 variants** (10,000 time-shift values x 100 cruise speeds, the grid of issue 35):
   by default a *synthetic* results table with the real sweep's exact columns and dtypes
   (each synthetic variant takes the outcome of the real variant nearest in the plane, so
   the maps show the real boundary), written as results.parquet; reading it, the critical
   ranking and each picture are timed. Running 10^6 real variants takes minutes on two
   shared cores; ``--million`` runs them instead (the real sweep, then the same timings).

Target: every picture < 10 s at 10^6 variants (before issue 35: probability_map.png drew
one hatched cell per grid value, 10^6 cells, and was still running after 6 minutes).
Exit status 1 when a target is missed.

``python -m benchmarks.bench_pictures [--side-t 100] [--side-v 100] [--workers 2] [--million]``
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import time
from pathlib import Path

PICTURE_TARGET_S = 10.0
MILLION_T, MILLION_V = 10_000, 100


def _spec(n_t: int, n_v: int):
    from vei.sweep.spec import spec_from_dict

    return spec_from_dict(
        {
            "design": "grid",
            "base": "normal-cap",
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0, "num": n_t},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0, "num": n_v},
            },
        }
    )


def _pictures(results, spec, out: Path) -> list[tuple[str, float, int]]:
    """(picture, seconds, cells drawn) of each sweep picture of ``results``."""
    from vei.sweep.riskmap import sweep_probability_map, sweep_risk_map, sweep_severity_maps

    rows = []
    t0 = time.perf_counter()
    r = sweep_risk_map(results, spec, out / "riskmap.png")
    rows.append(("riskmap.png", time.perf_counter() - t0, r["binned"]["count"].size))
    t0 = time.perf_counter()
    p = sweep_probability_map(results, spec, out / "probability_map.png")
    rows.append(("probability_map.png", time.perf_counter() - t0, p["grid"]["p"].size))
    t0 = time.perf_counter()
    written = sweep_severity_maps(results, spec, out)
    rows.append(
        (
            ", ".join(q.name for q in written.values()),
            time.perf_counter() - t0,
            r["binned"]["count"].size,
        )
    )
    return rows


def _synthetic(real, n_t: int, n_v: int, spec_real, spec_big):
    """A results table of n_t x n_v variants with ``real``'s exact columns and dtypes: each
    row copies the outcome of the real variant nearest to it in the plane."""
    import numpy as np

    from vei.sweep.spec import variants_table

    big = variants_table(spec_big, str(real["scenario_id"].iloc[0]))
    rt = np.sort(real["time_shift_s"].unique())
    rv = np.sort(real["ego.cruise_speed_mps"].unique())

    def nearest(grid, v):
        i = np.clip(np.searchsorted(grid, v), 1, len(grid) - 1)
        return np.where(np.abs(v - grid[i - 1]) <= np.abs(grid[i] - v), i - 1, i)

    it = nearest(rt, big["time_shift_s"].to_numpy(float))
    iv = nearest(rv, big["ego.cruise_speed_mps"].to_numpy(float))
    cell = np.full((len(rt), len(rv)), -1, dtype=np.int64)
    cell[
        np.searchsorted(rt, real["time_shift_s"]), np.searchsorted(rv, real["ego.cruise_speed_mps"])
    ] = np.arange(len(real))
    out = real.iloc[cell[it, iv]].reset_index(drop=True)
    for c in big.columns:
        if c in out.columns:
            out[c] = big[c].astype(out[c].dtype).to_numpy()
    return out[real.columns]


def _table(title: str, rows: list[tuple[str, float, int]]) -> list[str]:
    print(f"\n{title}")
    print(f"{'output':>48} {'seconds':>8} {'cells':>6}")
    missed = []
    for name, s, cells in rows:
        print(f"{name:>48} {s:8.2f} {cells if cells else '':>6}")
        if cells and s > PICTURE_TARGET_S:
            missed.append(f"{name}: {s:.1f} s > {PICTURE_TARGET_S} s")
    return missed


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--side-t", type=int, default=100, help="time-shift values of the real sweep")
    ap.add_argument("--side-v", type=int, default=100, help="cruise speeds of the real sweep")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--million", action="store_true", help="run 10^6 real variants")
    args = ap.parse_args(argv)

    import os

    import matplotlib

    matplotlib.use("Agg")
    import pandas as pd

    from vei.experiments.demo_data import demo_interaction
    from vei.io.atomic import write_parquet
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct
    from vei.sweep.io import most_critical, read_results
    from vei.sweep.run import run_sweep

    print(f"demo scenario (25 s, 20 Hz); load {os.getloadavg()}")
    missed: list[str] = []
    with tempfile.TemporaryDirectory() as tmp:
        scen = Path(tmp) / "scenario"
        write_scenario(reconstruct(demo_interaction()), scen)
        sizes = [(args.side_t, args.side_v)] + ([(MILLION_T, MILLION_V)] if args.million else [])
        real = None
        for n_t, n_v in sizes:
            spec = _spec(n_t, n_v)
            out = Path(tmp) / f"sweep_{n_t}x{n_v}"
            t0 = time.perf_counter()
            res = run_sweep(scen, spec, out, workers=args.workers, progress=False)
            wall = time.perf_counter() - t0
            rows = [(f"sweep phase {k}", v, 0) for k, v in res.timings.items()]
            rows.append(("sweep wall (everything)", wall, 0))
            t0 = time.perf_counter()
            real = read_results(out)
            rows.append(("read results.parquet (all columns)", time.perf_counter() - t0, 0))
            rows += _pictures(real, spec, out / "again")
            missed += _table(f"real grid sweep: {n_t} x {n_v} = {n_t * n_v:,} variants, "
                             f"--workers {args.workers}", rows)  # fmt: skip
        if not args.million:
            spec = _spec(MILLION_T, MILLION_V)
            t0 = time.perf_counter()
            big = _synthetic(real, MILLION_T, MILLION_V, _spec(args.side_t, args.side_v), spec)
            rows = [("build the synthetic table", time.perf_counter() - t0, 0)]
            out = Path(tmp) / "synthetic"
            out.mkdir()
            write_parquet(out / "results.parquet", big)
            del big
            t0 = time.perf_counter()
            big = pd.read_parquet(out / "results.parquet")
            rows.append(("read results.parquet (all columns)", time.perf_counter() - t0, 0))
            t0 = time.perf_counter()
            most_critical(big, 20)
            rows.append(("critical ranking (20 of them)", time.perf_counter() - t0, 0))
            rows += _pictures(big, spec, out)
            missed += _table(
                f"SYNTHETIC {len(big):,}-row results table ({MILLION_T:,} x {MILLION_V} grid; "
                f"{big.shape[1]} columns = the real sweep's)", rows
            )  # fmt: skip
    if missed:
        print("\nmissed: " + "; ".join(missed))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
