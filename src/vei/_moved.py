"""Old module names of modules that moved (round 3: grouped by idea), kept importable for
one release with a DeprecationWarning.

``import vei.experiments.sweep`` (say) finds nothing on disk any more; the finder below
answers for the old name with a module object that shares the new module's namespace, so
``from vei.experiments.sweep import run_sweep`` keeps working and warns once. Research code
moved out of the package (the reconstruction comparisons, now ``benchmarks/``) has no alias.
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.machinery
import importlib.util
import sys
import types
import warnings

#: Old dotted name -> new dotted name (removed in the release after 0.2).
MOVED: dict[str, str] = {
    "vei.config_metrics": "vei.config.metrics",
    "vei.config_models": "vei.config.models",
    "vei.config_perception": "vei.config.perception",
    "vei.config_settings": "vei.config.settings",
    "vei.experiments.sweep": "vei.sweep.run",
    "vei.experiments.sweep_compare": "vei.sweep.compare",
    "vei.experiments.sweep_critical": "vei.sweep.critical",
    "vei.experiments.sweep_engine": "vei.sweep.evaluator",
    "vei.experiments.sweep_ids": "vei.sweep.ids",
    "vei.experiments.sweep_io": "vei.sweep.io",
    "vei.experiments.sweep_params": "vei.sweep.params",
    "vei.experiments.sweep_runners": "vei.sweep.runners",
    "vei.experiments.sweep_spec": "vei.sweep.spec",
    "vei.experiments.workers": "vei.sweep.workers",
    "vei.experiments.riskmap": "vei.sweep.riskmap",
    "vei.sim.kernel_layout": "vei.sim.kernel.layout",
    # round 4 (issue 33): the time shift sits beside the engine it runs, below sweep
    "vei.experiments.timeshift": "vei.sim.timeshift",
}


class _MovedFinder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    """Finds the old names of :data:`MOVED`; loads each as an alias of its new module."""

    def find_spec(
        self, fullname: str, path: object = None, target: object = None
    ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in MOVED:
            return None
        return importlib.util.spec_from_loader(fullname, self)

    def create_module(self, spec: importlib.machinery.ModuleSpec) -> types.ModuleType:
        return types.ModuleType(spec.name)

    def exec_module(self, module: types.ModuleType) -> None:
        new = MOVED[module.__name__]
        warnings.warn(
            f"{module.__name__} has moved to {new}; the old name will be removed in the "
            "next release",
            DeprecationWarning,
            stacklevel=2,
        )
        target = importlib.import_module(new)
        keep = {"__name__", "__spec__", "__loader__"}
        module.__dict__.update({k: v for k, v in vars(target).items() if k not in keep})
        module.__getattr__ = lambda name: getattr(target, name)  # names added later


def install() -> None:
    """Put the finder on ``sys.meta_path`` (once)."""
    if not any(isinstance(f, _MovedFinder) for f in sys.meta_path):
        sys.meta_path.append(_MovedFinder())
