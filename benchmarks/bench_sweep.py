"""Benchmark: a 10^4-variant sweep of the 25 s demo scenario, end to end.

``run_sweep`` on a grid of 100 time shifts x 100 ego cruise speeds (base ``normal-cap``:
SFM rider, PID + CAP), 20 Hz, into a fresh folder: reading and compiling the scenario,
the automatic time shift, the engine, every default metric, part files, results.parquet,
critical variants and the risk map. Run with ``workers`` = the machine's CPU count (local
processes) and, for reference, in one process. Also printed: the split of one chunk's time
between engine and metrics. Target: under 30 s on 2 cores.
"""

from __future__ import annotations

import os
import tempfile
import time
from pathlib import Path

TARGET_S = 30.0
N_SIDE = 100
CHUNK = 2500


def _spec():
    from vei.experiments.sweep_spec import spec_from_dict

    return spec_from_dict(
        {
            "design": "grid",
            "base": "normal-cap",
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0, "num": N_SIDE},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0, "num": N_SIDE},
            },
        }
    )


def main() -> None:
    """Run the sweep benchmark and print its table."""
    import matplotlib

    matplotlib.use("Agg")
    from vei.experiments.demo_data import demo_interaction
    from vei.experiments.sweep import EngineEvaluator, run_sweep, variant_params
    from vei.experiments.sweep_spec import variants_table
    from vei.io.scenario import write_scenario
    from vei.metrics import summarize
    from vei.recon.pipeline import reconstruct
    from vei.sim.engine import simulate

    spec = _spec()
    workers = max(1, os.cpu_count() or 1)
    with tempfile.TemporaryDirectory() as tmp:
        scen = Path(tmp) / "scenario"
        write_scenario(reconstruct(demo_interaction()), scen)

        # split of one chunk (engine vs metrics)
        ev = EngineEvaluator(time_shift_reference="auto", base=spec.base)
        prep = ev.prepare(scen)
        chunk = variants_table(spec, prep.scenario_id).iloc[:CHUNK]
        params = variant_params(chunk, prep.arrays, base=spec.base, auto_shift_s=prep.auto_shift_s)
        simulate(prep.arrays, params.take([0]), record="full", kernel=ev.sim.kernel)  # compile
        t0 = time.perf_counter()
        result = simulate(prep.arrays, params, record="full", kernel=ev.sim.kernel)
        t_engine = time.perf_counter() - t0
        t0 = time.perf_counter()
        summarize(result.to_trace(), names=ev.metrics)
        t_metrics = time.perf_counter() - t0
        del result

        timings = []
        for w in (workers, 1) if workers > 1 else (1,):
            t0 = time.perf_counter()
            res = run_sweep(
                scen, spec, Path(tmp) / f"out-{w}", workers=w, chunk_size=CHUNK, progress=False
            )
            timings.append((w, time.perf_counter() - t0, res.n_run))

    print(
        f"sweep of the 25 s demo scenario (20 Hz, 500 steps), {N_SIDE}x{N_SIDE} grid, chunks of {CHUNK}"
    )
    print(f"one chunk of {CHUNK}: engine {t_engine:.2f} s, metrics {t_metrics:.2f} s")
    print(
        f"{'workers':>8} {'variants':>9} {'wall s':>8} {'variants/s':>11} {'target s':>9} {'status':>7}"
    )
    for w, t, n in timings:
        ok = "MET" if t < TARGET_S else "MISSED"
        print(f"{w:>8} {n:>9} {t:8.1f} {n / t:11.0f} {TARGET_S:9.0f} {ok:>7}")


if __name__ == "__main__":
    main()
