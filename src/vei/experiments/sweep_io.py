"""Sweep storage: part files, results, the most critical variants, run configurations.

The part files and the resume design are described in :mod:`vei.experiments.sweep`.
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.calibrate.population import RIDER_COLUMN, RIDER_PARAM_COLUMNS
from vei.errors import InputError
from vei.experiments.sweep_spec import SAMPLE_COLUMN, SweepSpec

SWEEP_FORMAT = "vei.sweep/1"
PART_RE = re.compile(r"^part-(\d{6,})\.parquet$")


def _existing_parts(parts_dir: Path) -> list[Path]:
    if not parts_dir.is_dir():
        return []
    return sorted(p for p in parts_dir.iterdir() if PART_RE.match(p.name))


def _clean_temporaries(parts_dir: Path) -> int:
    """Remove temporary files a killed writer left behind (.part-*.tmp); returns how many."""
    n = 0
    if parts_dir.is_dir():
        for p in parts_dir.iterdir():
            if p.name.startswith(".") and p.name.endswith(".tmp"):
                with contextlib.suppress(FileNotFoundError):
                    p.unlink()
                    n += 1
    return n


def done_ids(out_dir: str | Path) -> set[str]:
    """Variant ids already written in ``out_dir/parts`` (every part file is complete).

    Raises:
        InputError: a part file cannot be read (names it).
    """
    import pyarrow.parquet as pq

    ids: set[str] = set()
    for p in _existing_parts(Path(out_dir) / "parts"):
        try:
            col = pq.read_table(p, columns=["variant_id"]).column("variant_id").to_pylist()
        except Exception as exc:  # pyarrow raises several types for a damaged file
            raise InputError(
                f"cannot read sweep part ({exc}); delete it to re-run its chunk", path=p
            ) from exc
        ids.update(col)
    return ids


def assemble_results(out_dir: str | Path, table: pd.DataFrame | None = None) -> pd.DataFrame:
    """All rows of ``out_dir/parts``, de-duplicated by variant_id, sorted by
    (scenario_id, variant_index); restricted to ``table``'s variant ids when given."""
    parts = _existing_parts(Path(out_dir) / "parts")
    if not parts:
        return pd.DataFrame()
    frame = pd.concat([pd.read_parquet(p) for p in parts], ignore_index=True)
    frame = frame.drop_duplicates("variant_id", keep="first")
    if table is not None:
        frame = frame[frame["variant_id"].isin(set(table["variant_id"]))]
    return frame.sort_values(["scenario_id", "variant_index"], kind="stable").reset_index(drop=True)


def most_critical(results: pd.DataFrame, k: int = 20) -> pd.DataFrame:
    """The ``k`` most critical variants: collisions first, then the lowest safety index,
    then the smallest minimum gap (columns that exist are used; ties keep table order)."""
    if results.empty:
        return results
    keys, asc = [], []
    if "collision" in results:
        keys.append("collision")
        asc.append(False)
    for col in ("safety_index", "min_gap_m"):
        if col in results:
            keys.append(col)
            asc.append(True)
    ranked = results.sort_values(keys, ascending=asc, kind="stable") if keys else results
    return ranked.head(k).reset_index(drop=True)


def read_results(out_dir: str | Path) -> pd.DataFrame:
    """results.parquet of a finished sweep.

    Raises:
        InputError: the sweep has not finished (no results.parquet).
    """
    path = Path(out_dir) / "results.parquet"
    if not path.is_file():
        raise InputError(
            "no results.parquet: the sweep has not finished (run it again to resume)", path=path
        )
    return pd.read_parquet(path)


def numeric_metric_columns(results: pd.DataFrame, spec_names: Sequence[str]) -> list[str]:
    """Metric columns of a results table (those that are not variant columns)."""
    fixed = {
        "variant_id",
        "scenario_id",
        "variant_index",
        "seed",
        SAMPLE_COLUMN,
        RIDER_COLUMN,
        *RIDER_PARAM_COLUMNS,
        *spec_names,
    }
    return [
        c for c in results.columns if c not in fixed and np.issubdtype(results[c].dtype, np.number)
    ]


def json_records(frame: pd.DataFrame) -> list[dict[str, Any]]:
    """Rows of a table as JSON-safe dicts (NaN / inf -> None, numpy scalars -> Python)."""
    recs = []
    for row in frame.to_dict("records"):
        clean = {}
        for k, v in row.items():
            if isinstance(v, np.generic):
                v = v.item()
            if isinstance(v, float) and not np.isfinite(v):
                v = None
            clean[k] = v
        recs.append(clean)
    return recs


def write_variant_configs(
    folder: str | Path,
    variants: pd.DataFrame,
    spec: SweepSpec,
    auto_shift_s: float | None,
) -> list[Path]:
    """One run-configuration YAML per variant row: ``folder/<variant_id>.yaml``.

    Each file is a :class:`vei.config.RunConfig` (``vei.config.load_config(path,
    RunConfig)`` reads it back; ``vei run SCENARIO --config FILE`` runs it) with the
    variant's absolute time shift. Returns the paths written.
    """
    import yaml

    from vei.config import config_to_dict
    from vei.experiments.sweep_spec import variant_config
    from vei.io.atomic import write_text

    folder = Path(folder)
    paths = []
    for row in variants.to_dict("records"):
        params = {n: row[n] for n in (*spec.names, *RIDER_PARAM_COLUMNS) if n in row}
        # Named by the variant id, the sweep's label of the variant: the perception's
        # random numbers are keyed by it (vei.policy.perception_random.label_keys).
        cfg = variant_config(params, spec, auto_shift_s=auto_shift_s, name=str(row["variant_id"]))
        doc = config_to_dict(cfg)
        header = (
            f"# vei run configuration of sweep variant {row['variant_id']} "
            f"(scenario {row.get('scenario_id', '?')})\n"
        )
        paths.append(
            write_text(
                folder / f"{row['variant_id']}.yaml", header + yaml.safe_dump(doc, sort_keys=False)
            )
        )
    return paths
