"""Benchmark: throughput of vei's Gymnasium environments, and a small policy learning on them.

First table, environment steps per second (one environment step = one engine step of one
environment, the agent's observation and reward included) with a uniformly random policy
(the actions drawn inside the timed loop), after a warm-up that compiles the kernels:

- ``vector (numba)``: :class:`vei.gym.vector.VeiVectorEnv` (``gymnasium.make_vec(
  "vei/Encounter-v0", num_envs=B)``), the compiled batched step, at B in ``BATCHES``;
  env-steps/s = B * steps / wall (``STEPS`` steps, autoresets included).
- ``vector (numpy)``: the same env with the engine's NumPy step per group of environments
  (the reference), at B = 10^4 over ``NUMPY_STEPS`` steps.
- ``single env``: ``gymnasium.make("vei/Encounter-v0")`` (the engine's NumPy step, B = 1).
- ``engine, built-in CAP``: ``vei.sim.engine.simulate(record="none", kernel="auto")`` of
  ``normal-cap`` (the built-in policy on the compiled engine kernel, no Python per step) at
  B = 10^4: variant-steps/s = B * 500 / wall (bench_engine.py reports it per agent-step:
  x 2 agents).
Scenes: the built-in demo (ego + one social-force e-scooter, 25 s at 20 Hz) and, when the
shared data is found (``../shared/data`` or ``$VEI_DATA_DIR``), the real recording
stadtmitte_12 with its Ingolstadt map (ego + SFM cyclist + 6 replayed riders, 61 s).
Target (issue 26): >= 10^6 environment steps/s at B = 10^4 on the 2-core machine.
Reference: GPUDrive (Kazemkhani et al., "GPUDrive: Data-driven, multi-agent driving
simulation at 1 million FPS", ICLR 2025, arXiv:2408.01584) reports over a million
simulation steps per second on a GPU.

``--features`` prints only the demo's vector env at B = 10^4 with each feature set of
issue 34 (``normal``: obstacle braking on; + the rider's decisions; + a perception delay
of 0.3 s), best of 3 runs of 100 steps; then the extra social-force riders
(``sim.sfm_riders``: 'primary' against 'all') on vei.sim.testing's four-rider crossing
(3 extra e-scooters, no map) and on stadtmitte_12 (6 extra riders) when the data is found;
then reacting cars (``traffic.cars_react``) on vei.sim.testing's follower scene (a car 1 s
behind the ego, random demands in [-8, 1] m/s^2 make it react), B = 10^3 and 10^4: the
compiled backend without reaction, with it, and the NumPy backend with it (``--cars``:
only these rows).

Second table (``--learn`` prints only this one): examples/gym_cem.py, the cross-entropy
method on a linear policy, 24 x 16 environments of the demo, 15 generations; the held-out
return of the mean policy against the random policy and blind cruising (a = 0).
"""

from __future__ import annotations

import importlib.util
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

BATCHES = (1_000, 10_000, 100_000)
STEPS = 200
NUMPY_STEPS = 10
TARGET = 1e6
GPUDRIVE = "GPUDrive (arXiv:2408.01584, ICLR 2025): over 1e6 steps/s on a GPU"


def machine() -> str:
    """The machine in words: CPU model, cores, load."""
    model = platform.processor() or "?"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    return f"{model}, {os.cpu_count()} cores, load average {load:.2f} (shared machine)"


def _data_dir() -> Path | None:
    env = os.environ.get("VEI_DATA_DIR")
    p = Path(env) if env else Path(__file__).resolve().parents[2] / "shared" / "data"
    return p if p.is_dir() else None


def _scenes(tmp: Path) -> dict[str, Path]:
    from vei.experiments.demo_map import write_demo_scenario

    out = {"demo": write_demo_scenario(tmp / "demo")}
    data = _data_dir()
    net = None if data is None else data / "maps" / "ingolstadt_research_intersection.net.xml.gz"
    if data is not None and net.is_file():
        from vei.cli.main import main as cli

        inter, scen = tmp / "stadtmitte_12" / "interaction", tmp / "stadtmitte_12" / "scenario"
        import contextlib
        import io

        with contextlib.redirect_stdout(io.StringIO()):
            ok = (
                cli(
                    [
                        "import",
                        "trafficmonitoring",
                        "--root",
                        str(data / "trafficmonitoring"),
                        "--scenario",
                        "stadtmitte_12_audi_geradeaus_03",
                        "--out",
                        str(inter),
                    ]
                )
                == 0
            )
            ok = ok and cli(["reconstruct", str(inter), "--out", str(scen), "--no-figure",
                             "--map", str(net)]) == 0  # fmt: skip
        if ok:
            out["stadtmitte_12"] = scen
    return out


def _feature_cases() -> dict[str, object]:
    """The vector env's feature sets (issue 34.4): 'normal' has obstacle braking on."""
    import dataclasses

    from vei.config import case_preset
    from vei.config.behaviour import DecisionConfig

    n = case_preset("normal")
    dec = dataclasses.replace(n, decision=DecisionConfig(enabled=True))
    delay = dataclasses.replace(dec, cap=dataclasses.replace(n.cap, perception_delay_s=0.3))
    return {"+ decisions": dec, "+ decisions + delay": delay}


def features() -> None:
    """The demo's vector env at B = 10^4 with each feature set (``--features``)."""
    with tempfile.TemporaryDirectory() as tmp:
        from vei.experiments.demo_map import write_demo_scenario

        folder = write_demo_scenario(Path(tmp) / "demo")
        print(f"machine: {machine()}")
        for name, case in {"normal": "normal", **_feature_cases()}.items():
            rate = max(_vector_rate(folder, 10_000, STEPS // 2, "numba", case) for _ in range(3))
            print(f"{'demo':<14} {'vector ' + name:<24} {10_000:>8} {rate:>14,.0f}", flush=True)
        from vei.config import SimConfig
        from vei.io.scenario import write_scenario
        from vei.sim.testing import four_rider_scenario

        scenes = {"four riders": (write_scenario(four_rider_scenario(), Path(tmp) / "four"), False)}
        real = _scenes(Path(tmp)).get("stadtmitte_12")
        if real is not None:
            scenes["stadtmitte_12"] = (real, True)
        for scene, (path, road) in scenes.items():
            for sel in ("primary", "all"):
                sim = SimConfig(sfm_riders=sel)
                rate = max(
                    _vector_rate(path, 10_000, STEPS // 2, "numba", sim=sim, road=road)
                    for _ in range(3)
                )
                print(f"{scene:<14} {'vector sfm_riders=' + sel:<24} {10_000:>8} {rate:>14,.0f}",
                      flush=True)  # fmt: skip
        cars(Path(tmp))


def cars(tmp: Path) -> None:
    """The vector env with reacting cars on the follower scene (``--features``)."""
    import dataclasses

    from vei.config import TrafficConfig, case_preset
    from vei.io.scenario import write_scenario
    from vei.sim.testing import follower_scenario

    folder = write_scenario(follower_scenario(), tmp / "follower")
    n = case_preset("normal")
    for b in (1_000, 10_000):
        for name, react, backend in (("cars replayed", False, "numba"),
                                     ("cars react", True, "numba"),
                                     ("cars react (numpy)", True, "numpy")):  # fmt: skip
            case = dataclasses.replace(n, traffic=TrafficConfig(cars_react=react))
            steps = STEPS // 2 if backend == "numba" else NUMPY_STEPS * 3
            rate = max(_vector_rate(folder, b, steps, backend, case, road=False, low=-8.0,
                                    high=1.0) for _ in range(3))  # fmt: skip
            print(f"{'follower':<14} {'vector ' + name:<24} {b:>8} {rate:>14,.0f}", flush=True)


def _vector_rate(
    folder: Path, b: int, steps: int, backend: str, case: object = "normal",
    sim: object = None, road: bool = True, low: float | None = None, high: float | None = None,
) -> float:  # fmt: skip
    """Env-steps/s of the vector env on ``folder`` (actions uniform in the action space, or
    in [low, high] m/s^2 where given)."""
    from vei.config import SimConfig
    from vei.gym import EnvConfig
    from vei.gym.vector import VeiVectorEnv

    cfg = EnvConfig(source="folder", path=folder, backend=backend, case=case,
                    sim=sim or SimConfig(), road_features=road)  # fmt: skip
    env = VeiVectorEnv(b, cfg)
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    lo = env.action_low if low is None else low
    hi = env.action_high if high is None else high
    env.step(rng.uniform(lo, hi, (b, 1)).astype(np.float32))  # warm-up (compiles once)
    t0 = time.perf_counter()
    for _ in range(steps):
        env.step(rng.uniform(lo, hi, (b, 1)).astype(np.float32))
    return b * steps / (time.perf_counter() - t0)


def _single_rate(folder: Path, steps: int = 500) -> float:
    from vei.gym import EnvConfig
    from vei.gym.env import VeiEnv

    env = VeiEnv(EnvConfig(source="folder", path=folder))
    rng = np.random.default_rng(0)
    env.reset(seed=0)
    t0 = time.perf_counter()
    for _ in range(steps):
        _, _, term, trunc, _ = env.step(rng.uniform(-8.0, 3.0, (1,)).astype(np.float32))
        if term or trunc:
            env.reset()
    return steps / (time.perf_counter() - t0)


def _engine_rate(folder: Path, b: int = 10_000) -> float:
    from vei.config import case_preset
    from vei.io.scenario import read_scenario
    from vei.sim.engine import simulate
    from vei.sim.state import VariantParams, prepare_scenario
    from vei.sim.timeshift import find_time_shift

    scen = read_scenario(folder)
    arrays = prepare_scenario(scen)
    auto = float(find_time_shift(scen))
    params = VariantParams.from_case(
        case_preset("normal-cap"), arrays, b, time_shift_s=auto + np.linspace(-3, 3, b)
    )
    simulate(arrays, params.take(np.arange(10)), record="none", kernel="auto")  # warm-up
    t0 = time.perf_counter()
    simulate(arrays, params, record="none", kernel="auto")
    return b * (arrays.n_steps - 1) / (time.perf_counter() - t0)


def throughput() -> bool:
    """Print the first table; True when the target is met on the demo."""
    print(f"machine: {machine()}")
    met = True
    with tempfile.TemporaryDirectory() as tmp:
        scenes = _scenes(Path(tmp))
        print(f"{'scene':<14} {'what':<24} {'B':>8} {'env-steps/s':>14}")
        for name, folder in scenes.items():
            for b in BATCHES:
                rate = _vector_rate(folder, b, STEPS if b <= 10_000 else STEPS // 4, "numba")
                print(f"{name:<14} {'vector (numba)':<24} {b:>8} {rate:>14,.0f}", flush=True)
                if name == "demo" and b == 10_000:
                    met = rate >= TARGET
                    demo_rate = rate
            if name == "demo":
                for what, case in _feature_cases().items():
                    rate = _vector_rate(folder, 10_000, STEPS, "numba", case)
                    print(
                        f"{name:<14} {'vector ' + what:<24} {10_000:>8} {rate:>14,.0f}", flush=True
                    )
            rate = _vector_rate(folder, 10_000, NUMPY_STEPS, "numpy")
            print(f"{name:<14} {'vector (numpy)':<24} {10_000:>8} {rate:>14,.0f}", flush=True)
            print(f"{name:<14} {'single env':<24} {1:>8} {_single_rate(folder):>14,.0f}")
            rate = _engine_rate(folder)
            print(f"{name:<14} {'engine, built-in CAP':<24} {10_000:>8} {rate:>14,.0f}", flush=True)
    print(
        f"target >= {TARGET:,.0f} env-steps/s at B = 10^4 (demo): "
        f"{'MET' if met else 'NOT MET'} ({demo_rate:,.0f}); {GPUDRIVE}"
    )
    return met


def learn() -> bool:
    """Run examples/gym_cem.py; True when the learned policy beats random and cruising."""
    path = Path(__file__).resolve().parents[1] / "examples" / "gym_cem.py"
    spec = importlib.util.spec_from_file_location("vei_example_gym_cem", path)
    mod = importlib.util.module_from_spec(spec)
    assert spec.loader is not None
    spec.loader.exec_module(mod)
    t0 = time.perf_counter()
    out = mod.train(verbose=True)
    final = out["history"][-1]
    better = final[3] > out["random"] and final[3] > out["cruise"]
    print(
        f"learned (mean policy, held-out): {final[3]:.2f} with {100 * final[4]:.0f} % contacts; "
        f"random {out['random']:.2f}; cruise at v_d {out['cruise']:.2f} with "
        f"{100 * out['cruise_contacts']:.0f} % contacts; {time.perf_counter() - t0:.0f} s"
    )
    return better


def main() -> None:
    """Both tables (``--learn``: the second only; ``--cars``: the reacting cars' rows of
    ``--features`` only)."""
    if "--cars" in sys.argv:
        print(f"machine: {machine()}")
        with tempfile.TemporaryDirectory() as tmp:
            cars(Path(tmp))
        return
    if "--features" in sys.argv:
        features()
        return
    ok = True
    if "--learn" not in sys.argv:
        ok = throughput() and ok
    ok = learn() and ok
    if not ok:
        sys.exit(1)


if __name__ == "__main__":
    main()
