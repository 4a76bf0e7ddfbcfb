"""Benchmark: what the engine costs a Python policy per call, at B = 10^4 (issue 34.3).

A policy that stays in Python (a learned model, torch, a user's NumPy rule) runs the
engine's NumPy step loop: every step, :class:`vei.sim.observe.PolicyDriver` builds one
:class:`vei.policy.observation.Observation` of the whole batch ([B, N] arrays: the
ground truth, perception delay / sensor model if configured), calls ``policy.act(obs,
state)`` once, and maps the returned PolicyAction to the demand. Measured here on the
built-in demo (ego + one social-force e-scooter, 25 s at 20 Hz = 500 steps), B = 10^4
variants of the ``normal`` case with the policy in the ego's seat, ``simulate(record=
"none")``, after a warm-up run:

- ``step``: wall time of the whole run / steps [ms per step];
- ``driver``: time inside ``PolicyDriver.act`` per call [ms]: observation + the policy's
  own ``act`` + the action's mapping;
- ``policy``: time inside the policy's ``act`` per call [ms];
- ``overhead``: driver - policy [ms per call], and per variant [ns]: what the engine
  spends per call to hand the batch to Python and take its actions back.

Policies: ``zero`` (returns a = 0: its own time is ~nothing), ``my-policy``
(examples/my_policy.py:MyPolicy, a vectorised NumPy TTC rule) and ``gym-linear``
(examples/gym_trained_policy.py:LinearGymPolicy: the vector env's observation vector
rebuilt from the Observation, then a linear map). For scale: the built-in ``paper-cap``
(``normal-cap``) in the compiled kernel, the same B and span, per step; each policy's
simulations per second as a ratio to paper-cap's (measured first, in the same run).

    python -m benchmarks python_policy
"""

from __future__ import annotations

import importlib.util
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

B = 10_000
ROOT = Path(__file__).resolve().parents[1]


class ZeroPolicy:
    """Demands 0 m/s^2 for every variant: the call itself, nothing else."""

    def init_state(self, batch_size: int) -> None:
        """No memory."""
        return None

    def act(self, obs: Any, state: Any) -> tuple[Any, Any]:
        """a = 0 [B]."""
        from vei.policy.base import PolicyAction

        return PolicyAction(accel_mps2=np.zeros(obs.batch_size)), state


def _example_class(file: str, name: str) -> type:
    path = ROOT / "examples" / file
    spec = importlib.util.spec_from_file_location(f"vei_bench_{path.stem}", path)
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod
    spec.loader.exec_module(mod)
    return getattr(mod, name)


class _Timer:
    """Wraps a callable, adding its wall time [s] and call count."""

    def __init__(self, fn: Any) -> None:
        self.fn, self.total, self.calls = fn, 0.0, 0

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return self.fn(*args, **kwargs)
        finally:
            self.total += time.perf_counter() - t0
            self.calls += 1


def _params(arrays: Any, policy: Any, b: int) -> Any:
    from vei.config import case_preset
    from vei.sim.params import EGO_POLICY, VariantParams

    base = VariantParams.from_case(case_preset("normal"), arrays, b)
    return base.with_values(
        ego_mode=np.full(b, EGO_POLICY, dtype=base.ego_mode.dtype),
        policy=np.array([policy] * b, dtype=object),
        perception=np.array([None] * b, dtype=object),
    )


def measure(arrays: Any, policy: Any, b: int = B) -> dict[str, float]:
    """Per-step figures [s] of one policy (module docstring) at batch b."""
    from vei.sim import observe
    from vei.sim.engine import simulate

    params = _params(arrays, policy, b)
    simulate(arrays, params.take(np.arange(min(b, 64))), record="none")  # warm-up
    driver = _Timer(observe.PolicyDriver.act)
    own = _Timer(type(policy).act)
    old_driver, old_own = observe.PolicyDriver.act, type(policy).act
    observe.PolicyDriver.act = lambda self, st: driver(self, st)  # type: ignore[method-assign]
    type(policy).act = lambda self, obs, state: own(self, obs, state)  # type: ignore[method-assign]
    try:
        t0 = time.perf_counter()
        simulate(arrays, params, record="none")
        wall = time.perf_counter() - t0
    finally:
        observe.PolicyDriver.act = old_driver  # type: ignore[method-assign]
        type(policy).act = old_own  # type: ignore[method-assign]
    n = max(driver.calls, 1)
    return {
        "steps": float(driver.calls),
        "step": wall / n,
        "driver": driver.total / n,
        "policy": own.total / max(own.calls, 1),
        "overhead": (driver.total - own.total) / n,
    }


def paper_cap_step(arrays: Any, b: int = B) -> float:
    """Wall time per step [s] of normal-cap (the built-in CAP) in the compiled kernel."""
    from vei.config import case_preset
    from vei.sim.engine import simulate
    from vei.sim.params import VariantParams

    params = VariantParams.from_case(case_preset("normal-cap"), arrays, b)
    simulate(arrays, params, record="none", kernel="auto")  # compile / load
    t0 = time.perf_counter()
    simulate(arrays, params, record="none", kernel="auto")
    return (time.perf_counter() - t0) / (arrays.n_steps - 1)


def main() -> None:
    """Print the table (module docstring)."""
    from benchmarks.bench_gym import machine
    from vei.experiments.demo_map import write_demo_scenario
    from vei.io.scenario import read_scenario
    from vei.sim.state import prepare_scenario

    print(f"machine: {machine()}")
    with tempfile.TemporaryDirectory() as tmp:
        arrays = prepare_scenario(read_scenario(write_demo_scenario(Path(tmp) / "demo")))
    policies = {
        "zero": ZeroPolicy(),
        "my-policy": _example_class("my_policy.py", "MyPolicy")(),
        "gym-linear": _example_class("gym_trained_policy.py", "LinearGymPolicy")(),
    }
    print(f"demo, B = {B:,}, {arrays.n_steps - 1} steps, simulate(record='none')")
    cap = paper_cap_step(arrays)
    cap_rate = B / (cap * (arrays.n_steps - 1))
    head = (
        f"{'policy':<12s} {'step ms':>8s} {'driver ms':>10s} {'policy ms':>10s} "
        f"{'overhead ms':>12s} {'ns/variant':>11s} {'sims/s':>8s} {'/ paper-cap':>12s}"
    )
    print(head)
    for name, pol in policies.items():
        m = measure(arrays, pol)
        sims = B / (m["step"] * m["steps"])
        print(
            f"{name:<12s} {1e3 * m['step']:8.2f} {1e3 * m['driver']:10.2f} "
            f"{1e3 * m['policy']:10.2f} {1e3 * m['overhead']:12.2f} "
            f"{1e9 * m['overhead'] / B:11.1f} {sims:8.0f} {sims / cap_rate:12.2f}",
            flush=True,
        )
    print(
        f"{'paper-cap':<12s} {1e3 * cap:8.2f} {'(compiled kernel, no Python per step)':>45s} "
        f"{cap_rate:8.0f} {1.0:12.2f}"
    )


if __name__ == "__main__":
    main()
