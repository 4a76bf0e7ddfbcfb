"""Benchmark: engine throughput with V2X on against perception on (issue 25's target).

Scenes (20 Hz, record="none", after a warm-up at B = 10; the two configurations run
alternately ``REPEATS`` times, best CPU time of each):

- ``occluded``: the V2X study's occluded crossing (vei.experiments.v2x_study; ego, the
  e-scooter rider and a parked van: N = 2 road users, 1 sender, 401 steps);
- ``four riders``: vei.sim.testing.four_rider_scenario (ego + 4 e-scooters: N = 4, all
  senders, 501 steps), the three extra riders replayed.

Configurations (both run the paper's CAP on the policy API, B variants over time shifts):
``perception`` = the default sensor model (range, field of view, occlusion), ``+ V2X`` =
the same plus V2X at its defaults (ITS-G5, penetration 1, smartphone GNSS, NLOS blockage).
Rate = agent-steps/s = B (1 + N) T / t, t the process's CPU time (``time.process_time``: the
engine is single-threaded NumPy, so on a machine shared with other jobs CPU time measures
the work, where wall time would also measure the others). Target: V2X on >= 0.5 x
perception on.

``python -m benchmarks.bench_v2x`` prints the table.
"""

from __future__ import annotations

import time
from dataclasses import replace

import numpy as np

BATCHES = (1_000, 10_000)
REPEATS = 3


def _case(v2x: bool):
    from vei.config import PerceptionConfig, V2XConfig, case_preset

    base = case_preset("replay")
    case = replace(base, ego=replace(base.ego, policy="paper-cap"),
                   perception=PerceptionConfig(enabled=True))  # fmt: skip
    return replace(case, v2x=V2XConfig(enabled=True)) if v2x else case


def _scenes():
    from vei.config import SimConfig
    from vei.experiments.v2x_study import occluded_crossing
    from vei.sim.state import prepare_scenario
    from vei.sim.testing import four_rider_scenario

    sim = SimConfig()
    return {
        "occluded": (prepare_scenario(occluded_crossing(), sim), (-6.0, -2.2)),
        "four riders": (prepare_scenario(four_rider_scenario(), sim), (3.0, 6.0)),
    }


def _run(arrays, shifts_span, v2x: bool, b: int):
    """A closure that simulates B variants once (record="none")."""
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams

    shifts = np.linspace(*shifts_span, b)
    labels = np.array([f"v{i}" for i in range(b)], dtype=object)
    params = VariantParams.from_case(_case(v2x), arrays, b, time_shift_s=shifts)
    params = params.with_values(labels=labels)
    return lambda: simulate(arrays, params, record="none")


def rows(batches: tuple[int, ...] = BATCHES) -> list[tuple]:
    """(scene, B, perception rate, CPU s, V2X rate, CPU s, ratio) per scene and batch: the
    two configurations run alternately, ``REPEATS`` times each, best CPU time of each."""
    out = []
    for name, (arrays, span) in _scenes().items():
        _run(arrays, span, True, 10)()  # warm-up (imports, first allocations)
        n = 1 + len(arrays.other_ids) + arrays.riders.n
        for b in batches:
            runs = {v: _run(arrays, span, v, b) for v in (False, True)}
            best = {False: float("inf"), True: float("inf")}
            for _ in range(REPEATS):
                for v, fn in runs.items():
                    t0 = time.process_time()
                    fn()
                    best[v] = min(best[v], time.process_time() - t0)
            rate = {v: b * (1 + n) * arrays.t_s.size / w for v, w in best.items()}
            out.append((name, b, rate[False], best[False], rate[True], best[True],
                        rate[True] / rate[False]))  # fmt: skip
    return out


def main() -> None:
    print("engine throughput, paper-cap on the policy API: perception vs perception + V2X")
    print(f"{'scene':>12} {'B':>7} {'perception/s':>13} {'cpu s':>7} {'+V2X/s':>10} "
          f"{'cpu s':>7} {'ratio':>6}")  # fmt: skip
    worst = float("inf")
    for name, b, rp, wp, rv, wv, ratio in rows():
        worst = min(worst, ratio)
        print(f"{name:>12} {b:>7} {rp:>13.3g} {wp:>7.2f} {rv:>10.3g} {wv:>7.2f} {ratio:>6.2f}")
    print(f"target: V2X on >= 0.5 x perception on; worst ratio {worst:.2f} "
          f"({'met' if worst >= 0.5 else 'NOT met'})")  # fmt: skip


if __name__ == "__main__":
    main()
