"""Benchmark: sweeps of the 25 s demo scenario at the engine's speed, end to end.

Grids of time shift x ego cruise speed (base ``normal-cap``: SFM rider, PID + CAP),
20 Hz, 500 steps, each ``run_sweep`` into a fresh folder: reading and compiling the
scenario, the automatic time shift, the engine, every default metric, part files,
results.parquet, critical variants and the risk maps. Printed:

1. **throughput**: the 10^5-variant sweep's variants/s next to the engine alone on the same
   variants (``simulate(record='none')`` in chunks of the sweep's size, this process, numba
   on every core). A sweep's throughput is its variants over the time of the phases that
   grow with them (``SweepResult.timings``: prepare + evaluate + results, i.e. until
   results.parquet and the critical ranking are written); the ``post`` phase (recording
   and drawing the 20 critical variants, the risk and severity maps) is a fixed cost per
   sweep, printed beside it, and end-to-end variants/s (wall) too. Target: the sweep >= 50 %
   of the engine.
2. **workers**: the 10^5-variant sweep with 1 worker (numba on 1 thread), ``N`` = the CPU
   count workers (the sweep's process and N - 1 children, one numba thread each), and, for
   reference, 1 worker with numba on every core (the default of ``--workers 1``). Each
   sweep runs in a fresh Python process, as ``vei sweep`` does (the modules a started
   ``vei sweep`` has imported are imported before the clock starts; the compiled kernel's
   first load is timed, in ``prepare``).
   Target: N=2 workers >= 1.7x the one-thread worker, on the throughput above (the ratio of
   the evaluate phase alone, where the workers run, is printed too).
3. **10^6 variants** (only with ``--million``: it takes minutes): 1000 x 1000 grid with
   ``N`` workers; wall time and peak memory = the sum over this process and every worker
   of its peak resident set (VmHWM, polled from /proc every 50 ms). Targets: < 120 s,
   < 2 GB.

Exit status 1 when a target is missed. ``python -m benchmarks.bench_sweep [--million]
[--side N]`` (``--side`` sets the grid side of parts 1-2, default 316: 99 856 variants).
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import threading
import time
from pathlib import Path

SIDE = 316  # 316^2 = 99 856 variants (10^5)
MILLION_SIDE = 1000
THROUGHPUT_TARGET = 0.5
SPEEDUP_TARGET = 1.7
MILLION_TARGET_S = 120.0
MILLION_TARGET_MB = 2000.0


def _spec(side: int):
    from vei.sweep.spec import spec_from_dict

    return spec_from_dict(
        {
            "design": "grid",
            "base": "normal-cap",
            "parameters": {
                "time_shift_s": {"min": -3.0, "max": 3.0, "num": side},
                "ego.cruise_speed_mps": {"min": 3.0, "max": 9.0, "num": side},
            },
        }
    )


def _descendants(pid: int) -> list[int]:
    """Every process below ``pid`` (from /proc/<pid>/task/*/children)."""
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        try:
            tasks = os.listdir(f"/proc/{p}/task")
        except OSError:
            continue
        for t in tasks:
            try:
                with open(f"/proc/{p}/task/{t}/children") as fh:
                    kids = [int(k) for k in fh.read().split()]
            except OSError:
                continue
            out.extend(kids)
            todo.extend(kids)
    return out


def _hwm_mb(pid: int) -> float | None:
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmHWM:"):
                    return int(line.split()[1]) / 1024.0
    except OSError:
        return None
    return None


class PeakMemory:
    """Polls this process and its descendants every ``period_s``: each one's peak resident
    set (VmHWM) [MB]; :attr:`total_mb` is their sum (an upper bound of the peak of the
    sum)."""

    def __init__(self, period_s: float = 0.05) -> None:
        self.period_s = period_s
        self.peaks: dict[int, float] = {}
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._poll, daemon=True)

    def _poll(self) -> None:
        me = os.getpid()
        while not self._stop.is_set():
            for pid in (me, *_descendants(me)):
                mb = _hwm_mb(pid)
                if mb is not None:
                    self.peaks[pid] = max(self.peaks.get(pid, 0.0), mb)
            self._stop.wait(self.period_s)

    def __enter__(self) -> PeakMemory:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join()

    @property
    def total_mb(self) -> float:
        return sum(self.peaks.values())


class _Run:
    """What a sweep in its own process reported (:func:`_child`): n_run, timings [s]."""

    def __init__(self, doc: dict) -> None:
        self.n_run = int(doc["n_run"])
        self.timings = {k: float(v) for k, v in doc["timings"].items()}
        busy = sum(self.timings[k] for k in ("prepare", "evaluate", "results"))
        self.variants_per_s = self.n_run / busy


def _timed_sweep(
    scen: Path, side: int, out: Path, workers: int, threads: int | None = None
) -> tuple[float, _Run, PeakMemory]:
    """(wall [s] of run_sweep, what it reported, peak memory of every process) of one sweep
    into ``out``, run as ``vei sweep`` runs it: in a fresh Python process (``threads``:
    its NUMBA_NUM_THREADS; None: every core)."""
    import json
    import subprocess

    env = dict(os.environ)
    if threads is not None:
        env["NUMBA_NUM_THREADS"] = str(threads)
    cmd = [sys.executable, "-m", "benchmarks.bench_sweep", "--child", str(scen), str(out),
           str(workers), str(side)]  # fmt: skip
    with PeakMemory() as mem:
        run = subprocess.run(cmd, env=env, capture_output=True, text=True, check=False,
                             cwd=Path(__file__).resolve().parents[1])  # fmt: skip
    if run.returncode != 0:
        raise RuntimeError(f"sweep process failed: {run.stderr[-2000:]}")
    doc = json.loads(run.stdout.strip().splitlines()[-1])
    if "results" not in doc["timings"]:
        raise RuntimeError(f"the sweep in {out} did not complete: {doc}; {run.stderr[-2000:]}")
    return float(doc["wall"]), _Run(doc), mem


def _child(scen: str, out: str, workers: int, side: int) -> None:
    """One sweep in this (fresh) process; prints {wall, n_run, timings} as JSON."""
    import json

    import matplotlib

    matplotlib.use("Agg")
    # What the started ``vei sweep`` process has imported before it runs the sweep (the CLI
    # and the modules run_sweep and the scenario's preparation import lazily): import time
    # is a cost of starting Python, not of the sweep. The compiled kernel is not loaded.
    import pyarrow.parquet  # noqa: F401
    import scipy.interpolate  # noqa: F401

    import vei.cli.main  # noqa: F401
    import vei.io.scenario  # noqa: F401
    import vei.sim.engine  # noqa: F401
    import vei.sim.state  # noqa: F401
    import vei.sim.timeshift  # noqa: F401
    from vei.sweep.run import run_sweep

    spec = _spec(side)
    t0 = time.perf_counter()
    res = run_sweep(Path(scen), spec, Path(out), workers=workers, progress=False)
    wall = time.perf_counter() - t0
    print(json.dumps({"wall": wall, "n_run": res.n_run, "timings": res.timings}))


def _engine_rate(scen: Path, spec, workers: int) -> tuple[float, int]:
    """variants/s of the engine alone (record='none') on the sweep's variants, in the
    sweep's chunks, this process (numba on every core)."""
    from vei.sim.engine import simulate
    from vei.sweep.run import EngineEvaluator, auto_chunk_size, variant_params
    from vei.sweep.spec import variants_table

    ev = EngineEvaluator(time_shift_reference="auto", base=spec.base)
    prep = ev.prepare(scen)
    table = variants_table(spec, prep.scenario_id)
    size = auto_chunk_size(len(table), workers)
    first = variant_params(table.iloc[:1], prep.arrays, auto_shift_s=prep.auto_shift_s)
    simulate(prep.arrays, first, record="none", kernel=ev.sim.kernel)  # load / compile
    t_engine = 0.0
    for start in range(0, len(table), size):
        params = variant_params(
            table.iloc[start : start + size], prep.arrays, auto_shift_s=prep.auto_shift_s
        )
        t0 = time.perf_counter()
        simulate(prep.arrays, params, record="none", kernel=ev.sim.kernel)
        t_engine += time.perf_counter() - t0
    return len(table) / t_engine, size


def main(argv: list[str] | None = None) -> int:
    """Run the sweep benchmark, print its tables; returns 1 when a target is missed."""
    ap = argparse.ArgumentParser(prog="python -m benchmarks.bench_sweep")
    ap.add_argument("--million", action="store_true", help="also the 10^6-variant sweep")
    ap.add_argument("--side", type=int, default=SIDE, help="grid side of the 10^5 sweep")
    ap.add_argument("--skip-small", action="store_true", help="only the 10^6 sweep")
    ap.add_argument("--child", nargs=4, metavar=("SCEN", "OUT", "WORKERS", "SIDE"),
                    help=argparse.SUPPRESS)  # fmt: skip
    args = ap.parse_args(argv)
    if args.child:
        scen, out, w, side = args.child
        _child(scen, out, int(w), int(side))
        return 0

    import matplotlib

    matplotlib.use("Agg")
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct
    from vei.sweep.runners import threads_per_worker

    cpus = threads_per_worker(1)
    workers = max(2, cpus)
    missed: list[str] = []
    print(f"demo scenario (25 s, 20 Hz, 500 steps); {cpus} CPUs; load {os.getloadavg()}")
    with tempfile.TemporaryDirectory() as tmp:
        scen = Path(tmp) / "scenario"
        write_scenario(reconstruct(demo_interaction()), scen)
        if not args.skip_small:
            spec = _spec(args.side)
            n = args.side**2
            rate_engine, size = _engine_rate(scen, spec, workers)
            side, base = args.side, Path(tmp)
            rows = [
                ("1 (1 thread)", *_timed_sweep(scen, side, base / "w1", 1, threads=1)),
                (f"{workers} (1 thread each)", *_timed_sweep(scen, side, base / "wn", workers)),
                (f"1 ({cpus} threads)", *_timed_sweep(scen, side, base / "w1t", 1)),
            ]
            print(f"\n{n} variants ({args.side} x {args.side}), chunks of {size}")
            print(
                f"{'workers':>20} {'prepare':>8} {'evaluate':>9} {'results':>8} {'post':>6} "
                f"{'variants/s':>11} {'wall s':>7} {'wall var/s':>11} {'peak MB':>8}"
            )
            for name, wall, res, mem in rows:
                t = res.timings
                print(
                    f"{name:>20} {t['prepare']:8.2f} {t['evaluate']:9.2f} {t['results']:8.2f} "
                    f"{t['post']:6.2f} {res.variants_per_s:11.0f} {wall:7.2f} "
                    f"{res.n_run / wall:11.0f} {mem.total_mb:8.0f}"
                )
            speedup = rows[1][2].variants_per_s / rows[0][2].variants_per_s
            eval_ratio = rows[0][2].timings["evaluate"] / rows[1][2].timings["evaluate"]
            best = max(r[2].variants_per_s for r in rows)
            share = best / rate_engine
            print(
                f"engine alone (record='none', {cpus} threads): {rate_engine:.0f} variants/s; "
                f"best sweep {best:.0f} variants/s = {share:.0%} (target >= "
                f"{THROUGHPUT_TARGET:.0%}): {'MET' if share >= THROUGHPUT_TARGET else 'MISSED'}"
            )
            print(
                f"{workers} workers / 1 worker (1 thread each): {speedup:.2f}x (target >= "
                f"{SPEEDUP_TARGET}x): {'MET' if speedup >= SPEEDUP_TARGET else 'MISSED'}; "
                f"evaluate phase alone {eval_ratio:.2f}x"
            )
            if share < THROUGHPUT_TARGET:
                missed.append("throughput")
            if speedup < SPEEDUP_TARGET:
                missed.append("speed-up")
        if args.million:
            wall, res, mem = _timed_sweep(scen, MILLION_SIDE, Path(tmp) / "million", workers)
            n_run = res.n_run
            ok_t, ok_m = wall < MILLION_TARGET_S, mem.total_mb < MILLION_TARGET_MB
            print(f"\n{n_run} variants ({MILLION_SIDE} x {MILLION_SIDE}), {workers} workers")
            print(
                f"wall {wall:.1f} s (target < {MILLION_TARGET_S:.0f}): "
                f"{'MET' if ok_t else 'MISSED'}; {n_run / wall:.0f} variants/s; phases "
                + ", ".join(f"{k} {v:.1f} s" for k, v in res.timings.items())
            )
            each = ", ".join(f"{v:.0f}" for v in sorted(mem.peaks.values(), reverse=True))
            print(
                f"peak memory {mem.total_mb:.0f} MB = sum of {len(mem.peaks)} processes' peaks "
                f"({each}) (target < {MILLION_TARGET_MB:.0f}): {'MET' if ok_m else 'MISSED'}"
            )
            if not ok_t:
                missed.append("10^6 wall time")
            if not ok_m:
                missed.append("10^6 memory")
        else:
            print("\n(10^6 variants: python -m benchmarks.bench_sweep --million)")
    print(f"load after: {os.getloadavg()}")
    if missed:
        print(f"missed: {', '.join(missed)}")
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
