"""Shared check of the sweep tests: ``vei run`` of a written variant config gives the
sweep's own row, every metric bit for bit."""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

import pandas as pd
from typer.testing import CliRunner

from vei.cli.main import app
from vei.sweep.run import DEFAULT_METRICS


def same_value(sweep_value, run_value) -> bool:
    """Bit-identical; a non-finite sweep value equals JSON null (metrics.json writes NaN
    and inf as null)."""
    a = sweep_value.item() if hasattr(sweep_value, "item") else sweep_value
    if a is None or (isinstance(a, float) and not math.isfinite(a)):
        return run_value is None or (
            isinstance(run_value, float) and (math.isnan(run_value) or run_value == a)
        )
    return a == run_value


def assert_runs_equal_sweep(
    scenario: Path, configs: Sequence[Path], results: pd.DataFrame, out_root: Path
) -> int:
    """Run each variant config (named by its variant id) with the ``vei run`` CLI and
    compare every DEFAULT_METRICS value with the sweep's row by ``==``.

    Returns:
        the number of values compared.
    """
    runner = CliRunner()
    compared = 0
    for path in configs:
        out = out_root / path.stem
        res = runner.invoke(
            app, ["run", str(scenario), "--config", str(path), "--out", str(out), "--no-figures"]
        )
        assert res.exit_code == 0, res.output
        metrics = json.loads((out / "metrics.json").read_text())["metrics"]
        row = results[results["variant_id"] == path.stem].iloc[0]
        for name in DEFAULT_METRICS:
            assert same_value(row[name], metrics[name]), (path.stem, name, row[name], metrics[name])
            compared += 1
    return compared
