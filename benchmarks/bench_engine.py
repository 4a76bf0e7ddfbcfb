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

Second table, several riders (``SimConfig.sfm_riders``, vei.sim.riders): the 25 s
synthetic crossing scene (vei.sim.testing.four_rider_scenario, 500 steps) with three more
e-scooters (two crossing the ego's lane at x = 45 and 75 m, one riding towards the first
along y = 8); ``normal-cap``, B = ``RIDER_BATCH`` variants over time shifts. R = 1: the
one-rider engine (``sfm_riders='primary'``, the three others replayed); R = 2: one of them
social-force driven too; R = 4: all. Agents per variant = ego + R riders; agent-steps/s =
B (1 + R) 500 / wall time (best of ``REPEATS``, compiled kernel, record="none"; also the
NumPy reference at a smaller batch). Target: per agent-step, R = 4 within 2x of R = 1.
``python -m benchmarks.bench_engine --riders`` prints only this table.

Fourth table, the road users' behaviour (issue 24, ``--behaviour`` prints only this one):
normal-cap on the demo scene without and with the rider's decisions (and reacting cars),
B = 10^4, compiled kernel; then a sweep chunk of 10^4 variants with two reacting cars
following the ego (:func:`behaviour_scene`) scored in the kernel's pass. Target: the rate
with decisions at least 50 % of the rate without.

Third table, ego policies (vei.policy, ``--policy`` prints only this one): the demo scene
(2 agents, 500 steps), SFM normal rider, B in ``POLICY_BATCHES`` over time shifts. Rows:
the built-in CAP (``normal-cap``) on the compiled kernel and on the NumPy step; the same
CAP through the policy API (``vei.policy.builtin:PaperCAP``, NumPy step + observation
building); the example vectorised user policy (``examples/my_policy.py:MyPolicy``) and the
built-in ``aeb`` (both on the API). agent-steps/s = 2 B 500 / wall (one run after a
warm-up at B = 10; record="none").
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
RIDER_BATCH = 10_000
RIDER_BATCH_NUMPY = 1_000
RIDER_COUNTS = (1, 2, 4)
POLICY_BATCHES = (1_000, 10_000)


def _scene():
    from vei.config import SimConfig
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct
    from vei.sim.state import prepare_scenario
    from vei.sim.timeshift import find_time_shift

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

    from vei.sweep.run import EngineEvaluator, PreparedScenario

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


def riders_rows(batch: int = RIDER_BATCH, batch_numpy: int = RIDER_BATCH_NUMPY) -> list[tuple]:
    """(R, agents/variant, B, wall s, agent-steps/s, numpy agent-steps/s) for R in RIDER_COUNTS."""
    from vei.config import SimConfig, case_preset
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario
    from vei.sim.testing import four_rider_scenario

    scenario = four_rider_scenario()
    select = {1: "primary", 2: ("e2",), 4: "all"}
    rows = []
    for r in RIDER_COUNTS:
        arrays = prepare_scenario(scenario, SimConfig(sfm_riders=select[r]))
        assert arrays.riders.n == r - 1
        steps = arrays.n_steps - 1
        agents = 1 + r

        def params(b: int, arrays=arrays) -> VariantParams:
            shifts = 4.9 + np.linspace(-3.0, 3.0, b)
            return VariantParams.from_case(
                case_preset("normal-cap"), arrays, b, time_shift_s=shifts
            )

        simulate(arrays, params(10), record="none", kernel="auto")  # compile / load
        p = params(batch)
        t = _best(lambda p=p, a=arrays: simulate(a, p, record="none", kernel="auto"), REPEATS)
        pn = params(batch_numpy)
        t_np = _best(lambda p=pn, a=arrays: simulate(a, p, record="none", kernel="numpy"), 1)
        rows.append(
            (r, agents, batch, t, batch * agents * steps / t, batch_numpy * agents * steps / t_np)
        )
    return rows


def main_riders() -> None:
    """Print the several-rider table with its target."""
    from vei.sim import kernel as compiled

    rows = riders_rows()
    kernel = "numba" if compiled.available() else "numpy"
    print(
        f"several riders: crossing scene + 3 e-scooters, 500 steps, normal-cap, "
        f"{os.cpu_count()} CPU(s); engine kernel 'auto' = {kernel}"
    )
    hdr = (
        f"{'R':>3} {'agents':>7} {'B':>7} {'wall s':>8} {'engine ag-st/s':>15} "
        f"{'per ag-st vs R=1':>17} {'numpy ag-st/s':>14}"
    )
    print(hdr)
    print("-" * len(hdr))
    base = rows[0][4]
    for r, agents, b, t, rate, rate_np in rows:
        print(
            f"{r:>3} {agents:>7} {b:>7} {t:8.3f} {rate:15.3g} {rate / base:17.2f} "
            f"{rate_np:14.3g} (B={RIDER_BATCH_NUMPY})"
        )
    worst = min(row[4] for row in rows) / base
    print(
        f"target: per agent-step throughput with R = 4 within 2x of R = 1 (ratio >= 0.5): "
        f"{rows[-1][4] / base:.2f} {'MET' if worst >= 0.5 else 'MISSED'}"
    )


def policy_rows(batches: tuple[int, ...] = POLICY_BATCHES) -> list[tuple]:
    """(label, B, wall s, agent-steps/s) of the ego-policy table."""
    from dataclasses import replace
    from pathlib import Path

    from vei.config import case_preset
    from vei.sim.engine import simulate
    from vei.sim.params import EGO_POLICY
    from vei.sim.state import VariantParams

    arrays, auto = _scene()
    example = Path(__file__).resolve().parents[1] / "examples" / "my_policy.py"

    def params(kind: str, b: int) -> VariantParams:
        shifts = auto + np.linspace(-3.0, 3.0, b)
        if kind in ("cap", "cap-numpy"):
            return VariantParams.from_case(
                case_preset("normal-cap"), arrays, b, time_shift_s=shifts
            )
        if kind == "cap-api":
            from vei.policy.builtin import PaperCAP

            p = VariantParams.from_case(case_preset("normal-cap"), arrays, b, time_shift_s=shifts)
            return p.with_values(ego_mode=EGO_POLICY, policy=PaperCAP())
        spec = f"{example}:MyPolicy" if kind == "user" else "aeb"
        c = case_preset("normal")
        case = replace(c, ego=replace(c.ego, policy=spec))
        return VariantParams.from_case(case, arrays, b, time_shift_s=shifts)

    kinds = (
        ("paper-cap, compiled kernel", "cap", "auto"),
        ("paper-cap, NumPy step", "cap-numpy", "numpy"),
        ("paper-cap via policy API", "cap-api", "numpy"),
        ("user policy (vectorised)", "user", "numpy"),
        ("aeb via policy API", "aeb", "numpy"),
    )
    rows = []
    for label, kind, kern in kinds:
        simulate(arrays, params(kind, 10), record="none", kernel=kern)  # warm-up / compile
        for b in batches:
            p = params(kind, b)
            wall = _best(lambda p=p, kern=kern: simulate(arrays, p, record="none", kernel=kern), 1)
            rows.append((label, b, wall, AGENTS_PER_VARIANT * b * arrays.n_steps / wall))
    return rows


def main_policy() -> None:
    """Print the ego-policy table."""
    print(f"ego policies: demo scene, 2 agents, 500 steps, normal rider, {os.cpu_count()} CPU(s)")
    hdr = f"{'policy / path':<30} {'B':>7} {'wall s':>8} {'agent-steps/s':>14}"
    print(hdr)
    print("-" * len(hdr))
    for label, b, wall, rate in policy_rows():
        print(f"{label:<30} {b:>7} {wall:8.2f} {rate:14.3g}")


def behaviour_scene():
    """The crossing scene (ego at 5.6 m/s, an e-scooter crossing at x = 60 m) with two cars
    recorded behind the ego at its speed, 1 s and 2.5 s (bumper to bumper) behind it:
    the reacting cars of the behaviour table (issue 24)."""
    from vei.config import SimConfig
    from vei.sim.state import prepare_scenario
    from vei.sim.testing import TrackSpec, crossing_scenario

    t = np.arange(0, 501) / 20.0
    z = np.zeros_like(t)

    def follower(headway_s: float) -> TrackSpec:
        x = 5.6 * t - 4.7 - 5.6 * headway_s
        return TrackSpec("vehicle", t, x, z, z, np.full_like(t, 5.6))

    scene = crossing_scenario(others=[("car1", follower(1.0)), ("car2", follower(2.5))])
    return prepare_scenario(scene, SimConfig())


def behaviour_rows(batch: int = 10_000) -> list[tuple]:
    """(label, B, wall s, agent-steps/s, secondary collisions, rear-end) of the behaviour
    table: normal-cap on the demo scene off / with decisions / with decisions and
    reacting cars (compiled kernel, record='none'), then a sweep chunk of ``batch``
    variants with reacting cars on :func:`behaviour_scene` scored in the kernel's pass
    (vei.sim.engine.simulate_metrics, the default sweep metrics)."""
    from dataclasses import replace

    from vei.config import DecisionConfig, TrafficConfig, case_preset
    from vei.sim.engine import simulate, simulate_metrics
    from vei.sim.state import VariantParams
    from vei.sweep.evaluator import DEFAULT_METRICS

    arrays, auto = _scene()
    base = case_preset("normal-cap")
    decide = replace(base, decision=DecisionConfig(enabled=True))
    both = replace(decide, traffic=TrafficConfig(cars_react=True))
    rows = []
    for label, case in (
        ("normal-cap", base),
        ("+ decisions", decide),
        ("+ decisions + cars", both),
    ):
        p = VariantParams.from_case(
            case, arrays, batch, time_shift_s=auto + np.linspace(-3, 3, batch)
        )
        simulate(arrays, p.take(slice(0, 10)), record="none", kernel="auto")
        wall = _best(lambda p=p: simulate(arrays, p, record="none", kernel="auto"), REPEATS)
        rows.append(
            (label, batch, wall, AGENTS_PER_VARIANT * batch * arrays.n_steps / wall, "", "")
        )
    a2 = behaviour_scene()
    p = VariantParams.from_case(
        both, a2, batch, time_shift_s=4.886 + np.linspace(-4, 4, batch)
    )  # the meeting shift of the crossing scene, +-4 s
    simulate_metrics(a2, p.take(slice(0, 10)), names=DEFAULT_METRICS)
    t0 = time.perf_counter()
    frame = simulate_metrics(a2, p, names=DEFAULT_METRICS)
    wall = time.perf_counter() - t0
    rows.append(
        ("sweep chunk, 2 reacting cars", batch, wall, 4 * batch * a2.n_steps / wall,
         int(frame["secondary_collision"].sum()), int(frame["rear_end_collision"].sum()))
    )  # fmt: skip
    return rows


def main_behaviour() -> None:
    """Print the behaviour table (issue 24): the rate with decisions must be >= 50 % of
    the rate without."""
    print(f"road users' behaviour: demo scene (2 agents, 500 steps), {os.cpu_count()} CPU(s)")
    hdr = f"{'case':<30} {'B':>7} {'wall s':>8} {'agent-steps/s':>14} {'secondary':>10} {'rear-end':>9}"
    print(hdr)
    print("-" * len(hdr))
    rows = behaviour_rows()
    for label, b, wall, rate, sec, rear in rows:
        print(f"{label:<30} {b:>7} {wall:8.2f} {rate:14.3g} {sec!s:>10} {rear!s:>9}")
    ratio = rows[1][3] / rows[0][3]
    print(f"target: decisions >= 50 % of the rate without: {100 * ratio:.0f} % "
          f"{'MET' if ratio >= 0.5 else 'MISSED'}")  # fmt: skip


if __name__ == "__main__":
    import sys

    args = sys.argv[1:]
    if "--behaviour" in args:
        main_behaviour()
    elif "--policy" in args:
        main_policy()
    else:
        if "--riders" not in args:
            main()
        main_riders()
