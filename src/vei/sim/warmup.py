"""Compile the engine kernel once, in this process, before a command starts its workers.

A sweep or catalogue with N worker processes would otherwise have each worker compile the
kernel at the same time (N x 1-3 minutes of CPU, silent). :func:`ensure_compiled` runs the
kernel once on a small synthetic scene when :func:`vei.sim.kernel.is_cold` says that this
machine and installation have no machine code of it yet (announced while it compiles);
workers started afterwards load it from numba's cache in about a second.
"""

from __future__ import annotations


def ensure_compiled() -> bool:
    """Compile (or load) the compiled kernel now when it is cold.

    Returns:
        True when this call compiled it; False when it was cached already, or numba is not
        installed (the NumPy engine needs no compilation).
    """
    from vei.sim import kernel

    if not kernel.is_cold():
        return False
    from vei.config import SimConfig, case_preset
    from vei.sim.engine import simulate_metrics
    from vei.sim.state import VariantParams, prepare_scenario
    from vei.sim.testing import crossing_scenario

    arrays = prepare_scenario(crossing_scenario(), SimConfig(kernel="numba"))
    one = VariantParams.from_case(case_preset("normal-cap"), arrays, 1)
    simulate_metrics(arrays, one, names=("collision",), kernel="numba")
    return True
