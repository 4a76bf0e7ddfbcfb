"""Compile (or load) a feature set of the engine kernel now, on a small synthetic scene.

A run compiles the kernel's feature set on its first call anyway (announced, and one
process at a time: :mod:`vei.sim.kernel.cache`); :func:`ensure_compiled` does it ahead of
time, for a command that wants the compilation behind it before it starts its work, and
for the benchmark of the compile time per feature set (``python -m benchmarks compile``).
"""

from __future__ import annotations

from typing import Any


def warmup_scene(features: Any) -> tuple[Any, Any, bool]:
    """(arrays, params [1], scored) of a small synthetic scene whose kernel run uses
    exactly ``features`` (a :class:`vei.sim.kernel.Features`)."""
    import numpy as np

    from vei.config import SimConfig, case_preset
    from vei.sim.state import VariantParams, prepare_scenario
    from vei.sim.testing import TrackSpec, crossing_scenario

    others: tuple = ()
    if features.others or features.traffic:  # a car following the ego on its path
        t = np.arange(0, 401) / 20.0
        car = TrackSpec("vehicle", t, -15.0 + 5.6 * t, np.zeros_like(t))
        others = (("car_1", car),)
    sim = SimConfig(kernel="numba", sfm_riders="all" if features.riders else "primary")
    arrays = prepare_scenario(crossing_scenario(others=others), sim)
    case = case_preset("normal-cap")
    if features.policy:  # an ego policy the kernel runs (aeb)
        from dataclasses import replace

        c = case_preset("normal")
        case = replace(c, name="aeb", ego=replace(c.ego, policy="aeb"))
    params = VariantParams.from_case(case, arrays, 1)
    if features.user:  # a user's compiled policy (a function value in the kernel)
        from vei.policy.compiled import CompiledPolicy

        params = params.with_values(policy=CompiledPolicy(_cruise, name="warm-up"))
    params = params.with_values(decide=bool(features.decisions), cars_react=bool(features.traffic))
    return arrays, params, bool(features.metrics)


def _cruise(ego, objs, state):  # type: ignore[no-untyped-def]
    """A compiled policy of the warm-up: no demand (the signature of vei.policy.compiled)."""
    return 0.0


def ensure_compiled(features: Any = None) -> bool:
    """Compile (or load) ``features`` (default: every part) of the compiled kernel now
    when it is cold.

    Returns:
        True when this call compiled it; False when it was cached already, or numba is not
        installed (the NumPy engine needs no compilation).
    """
    from vei.sim import kernel

    feats = kernel.ALL_FEATURES if features is None else features
    if not kernel.is_cold(feats):
        return False
    run_features(feats)
    return True


def run_features(features: Any) -> Any:
    """Run one variant of :func:`warmup_scene` through the compiled kernel (compiling
    ``features`` when cold); returns the features the run used (checked equal)."""
    from vei.errors import ConfigError
    from vei.metrics.config import MetricsConfig
    from vei.metrics.fused_layout import config_vector
    from vei.sim import kernel
    from vei.sim.batch import batch_flags
    from vei.sim.step import initial_state

    arrays, params, scored = warmup_scene(features)
    used = kernel.features_of(arrays, params, scored)
    if used != features:
        raise ConfigError(f"the warm-up scene uses {used.name}, not {features.name}")
    fl = batch_flags(params, arrays.dt_s)
    state = initial_state(arrays, params, fl)
    cfg = config_vector(MetricsConfig()) if scored else None
    kernel.run(arrays, params, state, fl.hist_len, False, cfg)
    return used
