"""Run the V2X case study (:mod:`vei.experiments.v2x_study`) into a folder: the scene, the
comparison, the three sweeps, the figures and summary.json (``vei v2x study``)."""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.experiments.v2x_study import (
    COMPARED,
    compare,
    occluded_crossing,
    occlusion_window,
    sweep_specs,
)


@dataclass(frozen=True)
class StudyResult:
    """What :func:`run_study` wrote.

    Attributes:
        out_dir: the folder. scenario_dir: the scene. comparison: comparison.csv.
        window_s: the occlusion window [s]. sweeps: name -> sweep folder.
        figures: the figure files. summary: summary.json's content.
    """

    out_dir: Path
    scenario_dir: Path
    comparison: Path
    window_s: tuple[float, float]
    sweeps: dict[str, Path]
    figures: tuple[Path, ...]
    summary: dict[str, Any]


def run_study(
    out_dir: str | Path,
    *,
    quick: bool = False,
    workers: int = 1,
    log: Callable[[str], None] | None = None,
    progress: bool = False,
) -> StudyResult:
    """The whole case study into ``out_dir`` (resumable: the sweeps resume).

    Writes scenario/ (the synthetic scene), comparison.csv (every shift from -6 to 3 s at
    0.05 s, or 0.1 s with ``quick``), sweeps/<name>/ (standard sweep folders: `vei run
    --config` of any row reproduces it), figures/*.png and summary.json.

    Args:
        out_dir: output folder. quick: coarser grids (tests, a first look).
        workers: sweep workers. log: progress lines (default: none).
        progress: the sweeps' progress bars (rich; for a terminal).
    """
    from vei.experiments import v2x_figures as figs
    from vei.io.atomic import write_json
    from vei.io.scenario import write_scenario
    from vei.sweep.run import run_sweep
    from vei.sweep.spec import spec_from_dict

    say = log or (lambda _msg: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    scenario = occluded_crossing()
    sc_dir = write_scenario(scenario, out / "scenario")
    step = 0.1 if quick else 0.05
    shifts = np.round(np.arange(-10.0, 0.0 + 1e-9, step), 3)
    say(f"comparison: {len(shifts)} time shifts x {len(COMPARED)} configurations")
    table = compare(scenario, shifts)
    cmp_path = out / "comparison.csv"
    from vei.io.atomic import atomic_path

    with atomic_path(cmp_path) as tmp:
        table.to_csv(tmp, index=False)
    window = occlusion_window(table)
    steps = (0.6, 0.6) if quick else (0.05, 0.025)
    sweeps: dict[str, Path] = {}
    for name, raw in sweep_specs(window, *steps, quick=quick).items():
        spec = spec_from_dict(raw, source=f"v2x study: {name}")
        say(f"sweep {name}: {spec.n_variants()} variants")
        res = run_sweep(sc_dir, spec, out / "sweeps" / name, workers=workers,
                        progress=progress, record_critical=False)  # fmt: skip
        sweeps[name] = res.out_dir
    say("figures")
    paths = figs.write_figures(out / "figures", table, window, sweeps)
    summary = figs.summarise(table, window, sweeps)
    write_json(out / "summary.json", summary)
    return StudyResult(out, sc_dir, cmp_path, window, sweeps, tuple(paths), summary)


def read_results(sweep_dir: Path) -> pd.DataFrame:
    """A study sweep's results.parquet."""
    return pd.read_parquet(Path(sweep_dir) / "results.parquet")


def dumps(summary: dict[str, Any]) -> str:
    """summary.json's text (for the CLI)."""
    return json.dumps(summary, indent=2, sort_keys=True)


__all__ = ["StudyResult", "dumps", "read_results", "run_study"]
