"""The full recording of a sweep's critical variants (and only theirs).

A sweep scores every variant in the compiled kernel's pass without recording time series
(:func:`vei.sim.engine.simulate_metrics`). Once the most critical variants are ranked,
:func:`record_critical` runs just those k variants again with ``record='full'`` -- same
scenario arrays (or reconstruction sample), same per-variant engine parameters
(:meth:`EngineEvaluator.params` of their rows, scored by :meth:`EngineEvaluator.score`)
-- and writes::

    critical/timeseries.parquet   long time series (scenario_id + vei.types.TIMESERIES_COLUMNS;
                                  ``config`` = the variant id), every critical variant
    critical/recorded.json        the variants recorded and whether the recording's metrics
                                  equal the sweep's rows (every metric, by ==)
    critical/<variant_id>_birdseye.png   the bird's-eye figure of ``vei run``
                                  (plot_birdseye_configs) of the first ``n_figures`` variants

The engine is deterministic and batch-invariant, so the recording is the run the sweep
scored: its metrics equal the sweep's row bit for bit (checked here and in a test).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.sweep.evaluator import EngineEvaluator, PreparedScenario
from vei.sweep.spec import SAMPLE_COLUMN
from vei.types import TIMESERIES_COLUMNS

__all__ = [
    "CRITICAL_DIR",
    "critical_up_to_date",
    "mismatches",
    "record_critical",
    "record_variants",
]

#: Sub-folder of a sweep's output folder that holds the critical variants' recordings.
CRITICAL_DIR = "critical"


def critical_up_to_date(out_dir: str | Path, variant_ids: Sequence[str]) -> bool:
    """True when ``out_dir/critical/`` already holds the recording of ``variant_ids``: its
    timeseries.parquet exists, recorded.json lists these ids (same order), and the file is
    newer than results.parquet's sources (every part file; results.parquet itself is
    rewritten from them at each completion). A resumed sweep then skips the recording."""
    import json

    out = Path(out_dir)
    ts, meta = out / CRITICAL_DIR / "timeseries.parquet", out / CRITICAL_DIR / "recorded.json"
    if not (ts.is_file() and meta.is_file()):
        return False
    try:
        listed = json.loads(meta.read_text(encoding="utf-8")).get("variant_ids")
    except (OSError, ValueError):
        return False
    if listed != [str(v) for v in variant_ids]:
        return False
    sources = list((out / "parts").glob("part-*.parquet")) or [out / "results.parquet"]
    newest = max((p.stat().st_mtime for p in sources if p.is_file()), default=math.inf)
    return ts.stat().st_mtime >= newest


def record_variants(
    evaluator: EngineEvaluator, prepared: PreparedScenario, rows: pd.DataFrame
) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Simulate the variants ``rows`` of one scenario with the full recording.

    Args:
        evaluator: the sweep's engine evaluator (base, time-shift reference, sim settings,
            perception, metric names).
        prepared: the scenario as the sweep prepared it.
        rows: [k] rows of the variants table (or of results.parquet: the variants-table
            columns are read, metric columns ignored); a SAMPLE_COLUMN selects the
            reconstruction sample's arrays.

    Returns:
        (frame, summary): the long time series (TIMESERIES_COLUMNS; ``config`` = variant
        id, ``variant`` = the row's position in ``rows``), and the metrics of the
        recording [k rows, ``variant_id`` + ``evaluator.metrics``], scored as the sweep
        scores (vei.metrics.timeseries.as_timeseries_trace + summarize), in ``rows`` order.
    """
    from vei.sim.engine import simulate

    rows = rows.reset_index(drop=True)
    if SAMPLE_COLUMN in rows.columns and prepared.sample_arrays:
        groups = [
            (prepared.sample_arrays[int(k)], g) for k, g in rows.groupby(SAMPLE_COLUMN, sort=False)
        ]
    else:
        groups = [(prepared.arrays, rows)]
    frames, summaries = [], []
    for arrays, grp in groups:
        params = evaluator.params(prepared, arrays, grp)
        result = simulate(arrays, params, record="full", kernel=evaluator.sim.kernel)
        frame = result.to_frame()
        frame["variant"] = grp.index.to_numpy()[frame["variant"].to_numpy()]
        frames.append(frame)
        summary = evaluator.score(result, params)
        summary.insert(0, "variant_id", grp["variant_id"].to_numpy())
        summaries.append(summary.reset_index(drop=True))
    # rows order (the ranking), whatever the samples' grouping; a fresh index so that
    # _mark_continuation's sort_index keeps it
    frame = (
        pd.concat(frames, ignore_index=True)
        .sort_values("variant", kind="stable")
        .reset_index(drop=True)
    )
    summary = pd.concat(summaries, ignore_index=True).set_index("variant_id")
    summary = summary.loc[rows["variant_id"].to_numpy()].reset_index()
    frame = _mark_continuation(frame[list(TIMESERIES_COLUMNS)], evaluator, prepared, rows)
    return frame.reset_index(drop=True), summary


def _mark_continuation(
    frame: pd.DataFrame, evaluator: EngineEvaluator, prepared: PreparedScenario, rows: pd.DataFrame
) -> pd.DataFrame:
    """``frame`` with the bool column ``continuation`` (vei.continuation.flags): which
    samples of each variant are on a road user's run-in or run-out."""
    from vei.continuation import with_continuations
    from vei.continuation.flags import mark_frame
    from vei.io.scenario import read_scenario

    scen = with_continuations(read_scenario(prepared.path), evaluator.sim.continuation)
    params = evaluator.params(prepared, prepared.arrays, rows)
    parts = []
    for k, grp in frame.groupby("variant", sort=False):
        sfm = {str(c) for c in grp["config"].unique()} if params.rider_sfm[int(k)] else set()
        parts.append(
            mark_frame(
                grp,
                scen,
                rider_id=prepared.arrays.rider_id,
                time_shift_s=float(params.time_shift_s[int(k)]),
                sfm_configs=sfm,
            )
        )
    return pd.concat(parts).sort_index(kind="stable") if parts else frame


def _same(a: Any, b: Any) -> bool:
    """== of two metric values, NaN equal to NaN."""
    a = a.item() if hasattr(a, "item") else a
    b = b.item() if hasattr(b, "item") else b
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return bool(a == b)


def mismatches(
    summary: pd.DataFrame, crit: pd.DataFrame, names: Sequence[str]
) -> list[dict[str, Any]]:
    """(variant_id, metric, sweep value, recorded value) of every metric in ``names`` where
    the recording's ``summary`` differs from the sweep's rows ``crit`` (empty: identical)."""
    rec = summary.set_index("variant_id")
    out = []
    for _, row in crit.iterrows():
        vid = row["variant_id"]
        for name in names:
            if name in crit.columns and not _same(row[name], rec.at[vid, name]):
                out.append(
                    {
                        "variant_id": vid,
                        "metric": name,
                        "sweep": repr(row[name]),
                        "recorded": repr(rec.at[vid, name]),
                    }
                )
    return out


def record_critical(
    out_dir: str | Path,
    crit: pd.DataFrame,
    evaluator: Any,
    prepared: dict[str, PreparedScenario],
    *,
    n_figures: int = 5,
) -> Path | None:
    """Record the critical variants ``crit`` and write ``out_dir/critical/`` (module docstring).

    Args:
        out_dir: the sweep's output folder.
        crit: the critical rows in rank order (full rows of results.parquet: variants-table
            columns and metrics), from :func:`vei.sweep.io.most_critical`.
        evaluator: the sweep's evaluator; only an :class:`EngineEvaluator` is re-run (any
            other: nothing is recorded, None returned).
        prepared: the sweep's prepared scenarios (any key; matched by scenario id).
        n_figures: bird's-eye figures for the first n critical variants (0: none).

    Returns:
        the path of timeseries.parquet (kept as it is when :func:`critical_up_to_date`),
        or None when nothing was recorded.
    """
    from vei.io.atomic import write_json, write_parquet

    if not isinstance(evaluator, EngineEvaluator) or crit.empty:
        return None
    out = Path(out_dir) / CRITICAL_DIR
    if critical_up_to_date(out_dir, crit["variant_id"].astype(str).tolist()):
        return out / "timeseries.parquet"
    by_id = {p.scenario_id: p for p in prepared.values()}
    out.mkdir(parents=True, exist_ok=True)
    frames, summaries = [], []
    for sid, rows in crit.groupby("scenario_id", sort=False):
        frame, summary = record_variants(evaluator, by_id[str(sid)], rows)
        frame.insert(0, "scenario_id", str(sid))
        frames.append(frame)
        summaries.append(summary)
    frame = pd.concat(frames, ignore_index=True)
    frame["variant"] = frame["variant"].astype(np.int64)
    path = write_parquet(out / "timeseries.parquet", frame)
    summary = pd.concat(summaries, ignore_index=True)
    bad = mismatches(summary, crit, evaluator.metrics)
    if n_figures > 0:
        # before recorded.json: that file marks the recording complete for a resume
        _figures(out, frame, crit.head(n_figures), by_id)
    write_json(
        out / "recorded.json",
        {
            "variant_ids": crit["variant_id"].astype(str).tolist(),
            "n_rows": len(frame),
            "metrics_equal_sweep": not bad,
            "mismatches": bad,
        },
    )
    if bad:
        import warnings

        warnings.warn(
            f"{len(bad)} metric value(s) of the critical variants' recording differ from the "
            f"sweep's rows (see {out / 'recorded.json'})",
            stacklevel=2,
        )
    return path


def _figures(
    out: Path, frame: pd.DataFrame, crit: pd.DataFrame, by_id: dict[str, PreparedScenario]
) -> None:
    """The bird's-eye figure of ``vei run`` for each row of ``crit``."""
    from vei.io.scenario import read_scenario
    from vei.report.birdseye import scenario_roads
    from vei.report.casestudy_figures import plot_birdseye_configs, save_figure

    scenarios: dict[str, Any] = {}
    for _, row in crit.iterrows():
        sid, vid = str(row["scenario_id"]), str(row["variant_id"])
        if sid not in scenarios:
            scenarios[sid] = read_scenario(by_id[sid].path)
        scen = scenarios[sid]
        runs = frame[(frame["scenario_id"] == sid) & (frame["config"] == vid)]
        fig = plot_birdseye_configs(
            runs,
            other_id=scen.primary_threat,
            keyframes=scen.keyframes,
            roads=scenario_roads(scen),
        )
        save_figure(fig, out / f"{vid}_birdseye.png")
