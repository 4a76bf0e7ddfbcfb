"""Benchmark: throughput of the batched engine vs PySocialForce and a per-variant loop.

Scene: the built-in 25 s synthetic demo scenario at 20 Hz (ego + one e-scooter rider:
2 agents per variant, 500 steps), configuration ``normal-cap`` (SFM rider + PID + CAP,
every model branch active), B variants spread over time shifts around the automatic one.

Columns (one row per batch size B):
- ``engine``: agent-steps/s of ``vei.sim.engine.simulate(..., record="none",
  kernel="auto")`` (the compiled numba kernel when installed: extra ``vei[fast]``; its
  one-time compilation is excluded) on B variants in one batch = B * 2 agents * 500 steps /
  wall time (best of ``REPEATS``).
- ``numpy``: the same with ``kernel="numpy"``, the reference implementation (the pure
  ``step`` function in a Python loop over time, vectorised over B).
- ``loop``: a plain per-variant Python loop, the same engine called with B = 1 for each
  variant; its rate does not depend on B, so it is measured on ``LOOP_VARIANTS`` variants.
- ``psf scene``: PySocialForce 1.1 stepping the same number of agents (2 B) in one scene
  (its forces are pairwise: O(N^2) time and memory), measured up to ``PSF_MAX_AGENTS``
  agents; above that ``-`` (N^2 pair arrays of > 10^8 entries).
- ``psf 2-agent``: PySocialForce stepping 2-agent scenes (one per variant, like ours),
  the best PySocialForce rate per agent-step on this workload; independent of B.
  PySocialForce's numba JIT is warmed up (20 steps) before any timing.
- ``x psf``: engine rate / the best PySocialForce rate at that agent count.
- ``mem/variant``: peak traced memory (``tracemalloc``: every NumPy buffer) of
  ``simulate(record="none")`` divided by B; for B >= 10^4 measured on the first 25 steps
  (record="none" keeps no history: the peak is reached in the first steps).
  ``sweep mem/variant`` (printed below the table): the same for one sweep chunk of 1000
  variants with full recording and all metrics (what ``vei sweep`` holds per variant).
Targets on 2 cores: >= 1e7 agent-steps/s at B = 1e4; >= 1000x PySocialForce per agent-step.
"""

from __future__ import annotations

import contextlib
import logging
import os
import tempfile
import time
import tracemalloc

import numpy as np

BATCHES = (1, 100, 10_000, 100_000)
REPEATS = 2
LOOP_VARIANTS = 10
PSF_MAX_AGENTS = 2000
TARGET_RATE = 1e7
TARGET_RATIO = 1000.0
AGENTS_PER_VARIANT = 2


def _scene():
    from vei.config import SimConfig
    from vei.experiments.demo_data import demo_interaction
    from vei.experiments.timeshift import find_time_shift
    from vei.recon.pipeline import reconstruct
    from vei.sim.state import prepare_scenario

    scenario = reconstruct(demo_interaction())
    arrays = prepare_scenario(scenario, SimConfig())
    auto = float(find_time_shift(scenario))
    return arrays, auto


def _params(arrays, auto: float, b: int):
    from vei.config import case_preset
    from vei.sim.state import VariantParams

    shifts = auto + (np.linspace(-3.0, 3.0, b) if b > 1 else np.zeros(1))
    return VariantParams.from_case(case_preset("normal-cap"), arrays, b, time_shift_s=shifts)


def _best(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


@contextlib.contextmanager
def _quiet_psf():
    """Import PySocialForce without its side effects (a file.log in the cwd, DEBUG logs)."""
    cwd = os.getcwd()
    with tempfile.TemporaryDirectory() as tmp:
        os.chdir(tmp)
        logging.disable(logging.INFO)  # PySocialForce sets its logger to DEBUG on import
        try:
            import pysocialforce  # noqa: F401
        finally:
            os.chdir(cwd)
        for name in ("root", "numba", "pysocialforce", "matplotlib", ""):
            logging.getLogger(name).setLevel(logging.WARNING)
        try:
            yield
        finally:
            logging.disable(logging.NOTSET)


def _psf_rate(n_agents: int, steps: int, scenes: int = 1) -> float:
    """PySocialForce agent-steps/s: ``scenes`` scenes of ``n_agents`` agents each."""
    import pysocialforce as psf

    rng = np.random.default_rng(0)
    sims = []
    for _ in range(scenes):
        st = np.zeros((n_agents, 6))
        st[:, 0:2] = rng.uniform(0.0, 50.0, (n_agents, 2))
        st[:, 2] = 4.0
        st[:, 4:6] = st[:, 0:2] + np.array([60.0, 0.0])
        s = psf.Simulator(st, groups=None, obstacles=None)
        s.step(20)  # numba JIT warm-up, excluded
        sims.append(s)
    t0 = time.perf_counter()
    for s in sims:
        s.step(steps)
    return scenes * n_agents * steps / (time.perf_counter() - t0)


def _peak_bytes(fn) -> int:
    tracemalloc.start()
    tracemalloc.reset_peak()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _partial_run(arrays, params, n_steps: int) -> None:
    from vei.sim.engine import batch_flags, initial_state, step

    fl = batch_flags(params, arrays.dt_s)
    st = initial_state(arrays, params, fl)
    for _ in range(n_steps):
        st = step(st, params, arrays, fl)


def _sweep_chunk_peak(arrays, auto: float) -> float:
    import pandas as pd

    from vei.experiments.sweep import EngineEvaluator, PreparedScenario

    ev = EngineEvaluator(time_shift_reference="auto", base="normal-cap")
    prep = PreparedScenario(arrays.scenario_id, "", arrays, auto)
    b = 1000
    table = pd.DataFrame(
        {
            "variant_id": [f"v{i}" for i in range(b)],
            "time_shift_s": np.linspace(-3.0, 3.0, b),
            "ego.cruise_speed_mps": np.linspace(3.0, 9.0, b),
        }
    )
    return _peak_bytes(lambda: ev.evaluate(prep, table)) / b


def main() -> None:
    """Measure and print the table with the targets."""
    from vei.sim.engine import simulate

    arrays, auto = _scene()
    steps = arrays.n_steps - 1
    with _quiet_psf():
        psf_pair = _psf_rate(2, 100, scenes=20)
        psf_scene: dict[int, float] = {}
        for b in BATCHES:
            n = AGENTS_PER_VARIANT * b
            if n <= PSF_MAX_AGENTS:
                psf_scene[b] = _psf_rate(n, max(5, min(100, 20_000 // n)))

    loop_params = _params(arrays, auto, LOOP_VARIANTS)

    def loop() -> None:
        for i in range(LOOP_VARIANTS):
            simulate(arrays, loop_params.take([i]), record="none")

    simulate(arrays, _params(arrays, auto, 10), record="none")  # warm-up
    simulate(arrays, _params(arrays, auto, 10), record="none", kernel="auto")  # compile / load
    t_loop = _best(loop, 1)
    loop_rate = LOOP_VARIANTS * AGENTS_PER_VARIANT * steps / t_loop

    rows = []
    for b in BATCHES:
        params = _params(arrays, auto, b)
        t = _best(
            lambda p=params: simulate(arrays, p, record="none", kernel="auto"),
            REPEATS if b <= 10_000 else 1,
        )
        rate = b * AGENTS_PER_VARIANT * steps / t
        t_np = _best(
            lambda p=params: simulate(arrays, p, record="none", kernel="numpy"),
            REPEATS if b <= 10_000 else 1,
        )
        rate_np = b * AGENTS_PER_VARIANT * steps / t_np
        if b >= 10_000:
            peak = _peak_bytes(lambda p=params: _partial_run(arrays, p, 25))
        else:
            peak = _peak_bytes(lambda p=params: simulate(arrays, p, record="none"))
        best_psf = max(psf_pair, psf_scene.get(b, 0.0))
        rows.append((b, t, rate, psf_scene.get(b), best_psf, peak / b, rate_np))
    chunk_mem = _sweep_chunk_peak(arrays, auto)

    from vei.sim import kernel as compiled

    kernel = "numba" if compiled.available() else "numpy"
    print(
        f"engine throughput, demo scenario: {AGENTS_PER_VARIANT} agents x {steps} steps per variant, "
        f"normal-cap, {os.cpu_count()} CPU(s); engine kernel 'auto' = {kernel}"
    )
    hdr = (
        f"{'B':>7} {'wall s':>8} {'engine ag-st/s':>15} {'numpy ag-st/s':>14} "
        f"{'loop ag-st/s':>13} {'psf scene':>10} "
        f"{'psf 2-agent':>12} {'x psf':>8} {'x loop':>7} {'mem/variant':>12}"
    )
    print(hdr)
    print("-" * len(hdr))
    for b, t, rate, scene, best_psf, mem, rate_np in rows:
        sc = f"{scene:10.3g}" if scene is not None else f"{'-':>10}"
        print(
            f"{b:>7} {t:8.3f} {rate:15.3g} {rate_np:14.3g} {loop_rate:13.3g} {sc} {psf_pair:12.3g} "
            f"{rate / best_psf:8.0f} {rate / loop_rate:7.0f} {mem / 1024:9.1f} KiB"
        )
    print(
        f"sweep chunk (1000 variants, full record + metrics): peak {chunk_mem / 1024:.0f} KiB per variant"
    )
    r4 = next(r for r in rows if r[0] == 10_000)
    print(
        f"target: >= {TARGET_RATE:.0e} agent-steps/s at B = 1e4: {r4[2]:.3g} "
        f"{'MET' if r4[2] >= TARGET_RATE else 'MISSED'}; "
        f">= {TARGET_RATIO:.0f}x PySocialForce per agent-step at B = 1e4: {r4[2] / r4[4]:.0f}x "
        f"{'MET' if r4[2] / r4[4] >= TARGET_RATIO else 'MISSED'}"
    )


if __name__ == "__main__":
    main()
