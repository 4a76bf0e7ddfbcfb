"""Benchmark + report: the closed loop inside esmini vs the built-in engine.

On the synthetic demo and, where the data is found, the real recording
stadtmitte_12_audi_geradeaus_03 (imported at 1 Hz and reconstructed, outside the timing):
the paper's five configurations on the built-in engine (one batch) and on esmini (through
libesminiLib.so, one run after the other), with the side-by-side table of
:func:`vei.experiments.backend_compare.format_comparison` and the wall time per simulated
step on each backend, plus the size of esmini's log per run. Needs esmini ($VEI_ESMINI,
else ../shared/tools/esmini).

    python -m benchmarks backends
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

REAL = "stadtmitte_12_audi_geradeaus_03"


def _scenarios():
    from vei.experiments.demo_data import demo_interaction
    from vei.recon.pipeline import reconstruct

    yield reconstruct(demo_interaction())
    root = Path(os.environ.get("VEI_DATA_DIR", "../shared/data")) / "trafficmonitoring"
    if not (root / "data" / "measurements").is_dir():
        print(f"(real data not found under {root}: demo only)")
        return
    from vei.datasets.trafficmonitoring import import_scenario
    from vei.io.interaction import read_interaction

    with tempfile.TemporaryDirectory() as tmp:
        import_scenario(root, REAL, Path(tmp) / "i", rate_hz=1.0)
        yield reconstruct(read_interaction(Path(tmp) / "i"))


def main() -> None:
    """Print the comparison table and timings for each scenario."""
    from vei.experiments.backend_compare import compare_backends, format_comparison
    from vei.sim.backends.esmini import EsminiSettings, run_cases_frame

    logs: list[int] = []

    def esmini(scenario, cases, time_shift_s, sim):
        from vei.sim.backends.base import run_backend
        from vei.sim.backends.esmini import EsminiBackend

        backend = EsminiBackend(EsminiSettings())
        frame = run_backend(backend, scenario, list(cases), time_shift_s=time_shift_s, sim=sim)
        logs.extend(r["log_bytes"] for r in backend.reports)
        return frame

    esmini.__name__ = "esmini"
    assert run_cases_frame  # the registry's runner is the same loop
    for scenario in _scenarios():
        logs.clear()
        cmp = compare_backends(scenario, backend=esmini)
        print(format_comparison(cmp))
        steps = int(cmp.other.frame.query("agent_id == 'ego'").groupby("config").size().sum())
        print(
            f"\nsteps simulated: {steps} (5 configurations); wall per step: builtin "
            f"{1e3 * cmp.reference_s / steps:.3f} ms (incl. the automatic time shift), "
            f"esmini {1e3 * cmp.other_s / steps:.3f} ms; esmini log per run: "
            f"{min(logs)}-{max(logs)} bytes; agree: {cmp.agree}\n"
        )


if __name__ == "__main__":
    main()
