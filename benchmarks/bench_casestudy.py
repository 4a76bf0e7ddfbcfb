"""Benchmark: the paper's whole case study in-process (five configurations, 25 s at 20 Hz).

On the built-in synthetic demo scenario (reconstructed once, outside the timing): the
automatic time shift, the five configurations as one engine batch, the metrics; then,
separately, writing the figures. Median of several repeats after one warm-up run.
Target: the case study (shift + engine + metrics) under 1 s.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

TARGET_S = 1.0
REPEATS = 5


def _median_time(fn, repeats: int = REPEATS) -> float:
    fn()  # warm-up (imports, caches)
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


def main() -> None:
    """Time the case study stages and print a table with the target."""
    import matplotlib

    matplotlib.use("Agg")
    from vei.config import PAPER_CASES, SimConfig
    from vei.experiments.casestudy import run_casestudy, write_casestudy
    from vei.experiments.demo_data import demo_interaction
    from vei.metrics import summarize
    from vei.recon.pipeline import reconstruct
    from vei.sim.engine import run_cases
    from vei.sim.timeshift import find_time_shift

    scenario = reconstruct(demo_interaction())
    sim = SimConfig()
    shift = float(find_time_shift(scenario, sim=sim))
    result = run_casestudy(scenario, time_shift="auto")
    n_steps = result.t_s.size

    t_shift = _median_time(lambda: find_time_shift(scenario, sim=sim))

    def engine(kernel: str):
        return run_cases(scenario, list(PAPER_CASES), time_shift_s=shift, sim=sim, kernel=kernel)

    engine(sim.kernel)  # compiled kernel: load / compile outside the timing
    t_engine = _median_time(lambda: engine(sim.kernel))
    t_engine_numpy = _median_time(lambda: engine("numpy"))
    run_casestudy(scenario, time_shift="auto")
    trace = run_cases(scenario, list(PAPER_CASES), time_shift_s=shift, sim=sim).to_trace()
    t_metrics = _median_time(lambda: summarize(trace))
    t_total = _median_time(lambda: run_casestudy(scenario, time_shift="auto"))
    with tempfile.TemporaryDirectory() as tmp:
        t_write = _median_time(lambda: write_casestudy(result, Path(tmp)), repeats=2)

    rows = [
        ("automatic time shift (find_time_shift)", t_shift, None),
        (f"engine: 5 configurations, one batch (kernel {sim.kernel})", t_engine, None),
        ("engine: the same with the numpy reference kernel", t_engine_numpy, None),
        ("metrics: summary of 5 runs", t_metrics, None),
        ("case study in-process (shift + engine + frame + metrics)", t_total, TARGET_S),
        ("writing outputs + 5 figures (not in the target)", t_write, None),
    ]
    print(
        f"case study on the synthetic demo: {len(PAPER_CASES)} configurations x {n_steps} steps "
        f"({result.t_s[-1]:.0f} s at {1 / (result.t_s[1] - result.t_s[0]):.0f} Hz), median of {REPEATS}"
    )
    print(f"{'stage':58s} {'time [s]':>9s} {'target [s]':>11s} {'ok':>4s}")
    for name, t, target in rows:
        ok = "" if target is None else ("yes" if t < target else "NO")
        tgt = "" if target is None else f"< {target:g}"
        print(f"{name:58s} {t:9.3f} {tgt:>11s} {ok:>4s}")


if __name__ == "__main__":
    main()
