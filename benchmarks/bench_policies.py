"""Benchmark: simulations per second of the ego policies, as ratios to the paper's CAP.

Issue 34: ``aeb``, ``idm`` and users' compiled policies (vei.policy.compiled) run inside
the compiled kernel; Python policies run the NumPy step loop. One run, two scenes:

- ``demo``: the built-in 25 s synthetic demo scenario at 20 Hz (ego + one e-scooter,
  500 steps), SFM ``normal`` rider;
- ``real``: the shared recording ``audi_10_marktkauf_linksabbiegen`` (a left turn with
  every recorded road user replayed: the policies observe all of them), imported at
  1 Hz and reconstructed like ``vei import`` + ``vei reconstruct`` (needs the shared data
  at ``$VEI_DATA`` or ``../shared/data``; skipped without it).

Rows (B variants over time shifts around the automatic shift, ``record="none"``; the
one-time compilation of each feature set excluded by a warm-up at B = 10; best of
``REPEATS``, the rows interleaved): ``paper-cap`` (the compiled CAP: ego mode cap), ``aeb``, ``idm``, the
example compiled policy ``examples/my_compiled_policy.py:MyCompiledPolicy`` (all compiled
kernel), the example Python policy ``examples/my_policy.py:MyPolicy`` and ``aeb`` on the
NumPy step loop (how ``aeb`` ran before issue 34), both at ``B_NUMPY`` variants. Columns:
simulations/s (wall), the ratio to paper-cap, CPU seconds per 1000 simulations (all
threads) and paper-cap's CPU time over the row's ("x (CPU)": the same ratio in CPU time,
which a shared machine's load disturbs less than the wall time).
Targets (issue 34): aeb and idm >= 50 % of paper-cap's rate; the compiled user policy
>= 25 %.

``python -m benchmarks.bench_policies [--quick]`` (``--quick``: the demo scene only).
"""

from __future__ import annotations

import os
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

B_KERNEL = 4000  # variants of a compiled-kernel row
B_NUMPY = 400  # variants of a NumPy-loop row (its rate hardly depends on B beyond ~100)
REPEATS = 3
ROOT = Path(__file__).resolve().parents[1]
REAL = "audi_10_marktkauf_linksabbiegen"
#: (label, policy spec or case preset, kernel)
ROWS = (
    ("paper-cap", "normal-cap", "numba"),
    ("aeb", "aeb", "numba"),
    ("idm", "idm", "numba"),
    ("compiled user policy", f"{ROOT}/examples/my_compiled_policy.py:MyCompiledPolicy", "numba"),
    ("Python policy (vectorised)", f"{ROOT}/examples/my_policy.py:MyPolicy", "numpy"),
    ("aeb, NumPy loop (before)", "aeb", "numpy"),
)


def _demo():
    from vei.config import SimConfig
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.state import prepare_scenario
    from vei.sim.timeshift import find_time_shift

    scenario = reconstruct(demo_interaction())
    return prepare_scenario(scenario, SimConfig()), float(find_time_shift(scenario))


def _real(work: Path):
    from vei.config import SimConfig
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.state import prepare_scenario
    from vei.sim.timeshift import find_time_shift

    data = Path(os.environ.get("VEI_DATA", ROOT.parent / "shared" / "data"))
    root = data / "trafficmonitoring"
    if not root.is_dir():
        return None
    import_scenario(root, REAL, work / "interaction", rate_hz=1.0)
    scenario = reconstruct(read_interaction(work / "interaction"))
    return prepare_scenario(scenario, SimConfig()), float(find_time_shift(scenario))


def _params(arrays, auto: float, spec: str, b: int):
    from vei.config import case_preset
    from vei.sim.params import VariantParams

    shifts = auto + np.linspace(-3.0, 3.0, b)
    if spec == "normal-cap":
        return VariantParams.from_case(case_preset("normal-cap"), arrays, b, time_shift_s=shifts)
    c = case_preset("normal")
    case = replace(c, name="policy", ego=replace(c.ego, policy=spec))
    return VariantParams.from_case(case, arrays, b, time_shift_s=shifts)


def rows(arrays, auto: float) -> list[tuple[str, int, float, float]]:
    """(label, B, simulations/s, CPU s per 1000 simulations) of every row on one scene.

    The rows are measured interleaved (round r runs every row once), each keeping its best
    wall and CPU time over the rounds, so that a busy moment of a shared machine does not
    fall on one row only."""
    from vei.sim.engine import simulate

    params = []
    for _, spec, kern in ROWS:
        simulate(arrays, _params(arrays, auto, spec, 10), record="none", kernel=kern)  # warm
        params.append(_params(arrays, auto, spec, B_KERNEL if kern == "numba" else B_NUMPY))
    wall = np.full(len(ROWS), np.inf)
    cpu = np.full(len(ROWS), np.inf)
    for r in range(REPEATS):
        for i, (_, _, kern) in enumerate(ROWS):
            if kern == "numpy" and r > 0:  # seconds per run: once is enough
                continue
            w0, c0 = time.perf_counter(), time.process_time()
            simulate(arrays, params[i], record="none", kernel=kern)
            wall[i] = min(wall[i], time.perf_counter() - w0)
            cpu[i] = min(cpu[i], time.process_time() - c0)
    return [
        (label, p.batch_size, p.batch_size / wall[i], 1000.0 * cpu[i] / p.batch_size)
        for i, ((label, _, _), p) in enumerate(zip(ROWS, params, strict=True))
    ]


def _print(title: str, table: list[tuple[str, int, float, float]]) -> bool:
    cap, cap_cpu = table[0][2], table[0][3]
    print(title)
    hdr = (
        f"{'policy':<28} {'kernel':>7} {'B':>6} {'sims/s':>10} {'x paper-cap':>12} "
        f"{'CPU s/1000':>11} {'x (CPU)':>8}"
    )
    print(hdr)
    print("-" * len(hdr))
    ok = True
    for (label, b, rate, cpu), (_, _, kern) in zip(table, ROWS, strict=True):
        ratio = rate / cap
        print(f"{label:<28} {kern:>7} {b:>6} {rate:10.0f} {ratio:12.2f} {cpu:11.3f} "
              f"{cap_cpu / cpu:8.2f}")  # fmt: skip
        if label in ("aeb", "idm"):
            ok &= ratio >= 0.5
        if label == "compiled user policy":
            ok &= ratio >= 0.25
    return ok


def main(argv: list[str] | None = None) -> int:
    """Print the tables; 1 when a target (aeb / idm >= 0.5, user >= 0.25 x paper-cap) is missed."""
    argv = sys.argv[1:] if argv is None else argv
    import numba

    print(f"ego policies, simulations per second; {os.cpu_count()} CPU(s), "
          f"{numba.get_num_threads()} numba threads")  # fmt: skip
    arrays, auto = _demo()
    ok = _print(f"demo scene ({arrays.n_steps} steps, 2 agents)", rows(arrays, auto))
    if "--quick" not in argv:
        with tempfile.TemporaryDirectory() as tmp:
            real = _real(Path(tmp))
        if real is None:
            print(f"\n{REAL}: shared data not found, skipped")
        else:
            arrays, auto = real
            n = 2 + len(arrays.other_ids) + arrays.riders.n
            print()
            ok &= _print(f"{REAL} ({arrays.n_steps} steps, {n} road users observed)",
                         rows(arrays, auto))  # fmt: skip
    print(
        "targets (aeb, idm >= 0.5 x paper-cap; compiled user >= 0.25):", "met" if ok else "MISSED"
    )
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
