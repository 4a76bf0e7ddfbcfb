"""Sweep storage: part files, results, the most critical variants, run configurations.

The part files and the resume design are described in :mod:`vei.sweep.run`.
"""

from __future__ import annotations

import contextlib
import re
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.calibrate.columns import RIDER_COLUMN, RIDER_PARAM_COLUMNS
from vei.errors import InputError
from vei.sweep.spec import SAMPLE_COLUMN, SweepSpec

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


def _read_part(path: Path, columns: list[str] | None = None) -> Any:
    """One part file as a pyarrow Table without pandas metadata (parts are concatenated)."""
    import pyarrow.parquet as pq

    return pq.read_table(path, columns=columns).replace_schema_metadata(None)


def _bounds(path: Path) -> tuple[str, int, int] | None:
    """(scenario id, first and last variant_index) of a part file, from its footer's
    statistics (no data read); None when it spans scenarios or has no statistics."""
    import pyarrow.parquet as pq

    md = pq.ParquetFile(path).metadata
    cols = {md.schema.column(i).name: i for i in range(md.num_columns)}
    if md.num_rows == 0 or not {"scenario_id", "variant_index"} <= set(cols):
        return None
    sids: set[str] = set()
    lo, hi = None, None
    for r in range(md.num_row_groups):
        rg = md.row_group(r)
        ss = rg.column(cols["scenario_id"]).statistics
        si = rg.column(cols["variant_index"]).statistics
        if ss is None or si is None or not ss.has_min_max or not si.has_min_max:
            return None
        sids.update((ss.min, ss.max))
        lo = si.min if lo is None else min(lo, si.min)
        hi = si.max if hi is None else max(hi, si.max)
    if len(sids) != 1 or lo is None or hi is None:
        return None
    return next(iter(sids)), int(lo), int(hi)


def _in_order(parts: list[Path]) -> list[Path] | None:
    """The parts in result order when their rows can be streamed as they are: each holds
    one scenario, and ordered by (scenario id, first variant_index) their index ranges do
    not overlap (footer statistics only). None when not (the caller then loads,
    de-duplicates and sorts)."""
    bounds = [(b, p) for p in parts if (b := _bounds(p)) is not None]
    if len(bounds) != len(parts):
        return None
    bounds.sort(key=lambda bp: (bp[0][0], bp[0][1]))
    for (a, _), (b, _) in zip(bounds, bounds[1:], strict=False):
        if (a[0], a[2]) >= (b[0], b[1]):
            return None
    return [p for _, p in bounds]


class _Unordered(Exception):
    """A part's rows were not as its footer promised (streaming gives way to sorting)."""


def write_results(
    out_dir: str | Path, target: str | Path, table: pd.DataFrame | None = None
) -> int:
    """Write every row of ``out_dir/parts`` to the Parquet file ``target`` (atomically):
    de-duplicated by variant_id, sorted by (scenario_id, variant_index), restricted to
    ``table``'s variant ids when given; returns the number of rows.

    Parts that are in order (a sweep run in one go, or resumed: new parts fill the gaps)
    are streamed one at a time, each read once, so memory holds one part and not the whole
    result; otherwise (duplicates, overlaps, foreign rows) the rows are loaded,
    de-duplicated and sorted (:func:`assemble_table`). No dictionary encoding: with snappy
    alone the file is as small (measured: 3 % smaller on a 10^5-variant sweep) and ~20 %
    faster to write.
    """
    from concurrent.futures import ThreadPoolExecutor

    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc
    import pyarrow.parquet as pq

    from vei.io.atomic import atomic_path

    parts = _existing_parts(Path(out_dir) / "parts")
    ids = None if table is None else pa.array(table["variant_id"].to_numpy(object), pa.string())
    ordered = _in_order(parts) if parts else []
    if ordered:
        schema = pa.unify_schemas(
            [pq.read_schema(p).remove_metadata() for p in ordered], promote_options="default"
        )
        try:
            n, written = 0, []
            with (
                atomic_path(target) as tmp,
                pq.ParquetWriter(tmp, schema, use_dictionary=False) as writer,
                ThreadPoolExecutor(1) as reader,  # reads the next part while one is written
            ):
                nxt = reader.submit(_read_part, ordered[0])
                for i in range(len(ordered)):
                    part, p = nxt.result(), ordered[i]
                    if i + 1 < len(ordered):
                        nxt = reader.submit(_read_part, ordered[i + 1])
                    if np.any(np.diff(part["variant_index"].to_numpy()) <= 0):
                        raise _Unordered(p)
                    part = part.select(schema.names).cast(schema)
                    writer.write_table(part)
                    written.extend(part["variant_id"].chunks)
                    n += part.num_rows
                # one lookup table for all rows (not one per part)
                vid = pa.chunked_array(written, schema.field("variant_id").type)
                lookup = None if ids is None else ids.cast(vid.type)
                if lookup is not None and not pc.all(pc.is_in(vid, value_set=lookup)).as_py():
                    raise _Unordered(target)
            return n
        except _Unordered:
            pass
    whole = assemble_table(out_dir, ids)
    with atomic_path(target) as tmp:
        pq.write_table(whole, tmp, use_dictionary=False)
    return whole.num_rows


def assemble_table(out_dir: str | Path, ids: Any = None) -> Any:
    """All rows of ``out_dir/parts`` as one pyarrow Table, de-duplicated by variant_id
    (first kept), restricted to the variant ids ``ids`` (pyarrow array) when given, sorted
    by (scenario_id, variant_index)."""
    import numpy as np
    import pyarrow as pa
    import pyarrow.compute as pc

    parts = _existing_parts(Path(out_dir) / "parts")
    if not parts:
        return pa.table({})
    whole = pa.concat_tables([_read_part(p) for p in parts], promote_options="default")
    vid = whole["variant_id"]
    if pc.count_distinct(vid).as_py() != whole.num_rows:
        first = ~pd.Index(vid.to_numpy(zero_copy_only=False)).duplicated(keep="first")
        whole = whole.filter(pa.array(np.asarray(first)))
    if ids is not None:
        whole = whole.filter(pc.is_in(whole["variant_id"], value_set=ids))
    return whole.sort_by([("scenario_id", "ascending"), ("variant_index", "ascending")])


def assemble_results(out_dir: str | Path, table: pd.DataFrame | None = None) -> pd.DataFrame:
    """All rows of ``out_dir/parts``, de-duplicated by variant_id, sorted by
    (scenario_id, variant_index); restricted to ``table``'s variant ids when given."""
    import pyarrow as pa

    if not _existing_parts(Path(out_dir) / "parts"):
        return pd.DataFrame()
    ids = None if table is None else pa.array(table["variant_id"].to_numpy(object), pa.string())
    return assemble_table(out_dir, ids).to_pandas()


def most_critical(results: pd.DataFrame, k: int = 20) -> pd.DataFrame:
    """The ``k`` most critical variants: collisions first, then the lowest safety index,
    then the smallest minimum gap (columns that exist are used; NaN last; ties keep table
    order). Runs flagged ``seen_too_late`` (no planner could have reacted: the rider was
    first seen too late, vei.metrics.seen) never rank before an unflagged one: they come
    last, so they are listed only when fewer than ``k`` runs are unflagged. Ranks numeric
    keys with one stable ``numpy.lexsort`` (no sorted copy of a 10^6-row table)."""
    if results.empty:
        return results
    keys, asc = [], []
    if "seen_too_late" in results:
        keys.append("seen_too_late")
        asc.append(True)
    if "collision" in results:
        keys.append("collision")
        asc.append(False)
    for col in ("safety_index", "min_gap_m"):
        if col in results:
            keys.append(col)
            asc.append(True)
    if not keys:
        return results.head(k).reset_index(drop=True)
    cols = [results[c] for c in keys]
    if not all(pd.api.types.is_numeric_dtype(c) or pd.api.types.is_bool_dtype(c) for c in cols):
        ranked = results.sort_values(keys, ascending=asc, kind="stable")
        return ranked.head(k).reset_index(drop=True)
    # lexsort: last key primary; descending = negated (NaN stays NaN and sorts last)
    arrays = [
        c.to_numpy(np.float64, na_value=np.nan) * (1.0 if a else -1.0)
        for c, a in zip(cols, asc, strict=True)
    ]
    order = np.lexsort(arrays[::-1])
    return results.iloc[order[:k]].reset_index(drop=True)


def read_results(out_dir: str | Path, columns: Sequence[str] | None = None) -> pd.DataFrame:
    """results.parquet of a finished sweep (only ``columns`` when given).

    Raises:
        InputError: the sweep has not finished (no results.parquet).
    """
    path = Path(out_dir) / "results.parquet"
    if not path.is_file():
        raise InputError(
            "no results.parquet: the sweep has not finished (run it again to resume)", path=path
        )
    return pd.read_parquet(path, columns=None if columns is None else list(columns))


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
    reach_speed_mps: float | None = None,
) -> list[Path]:
    """One run-configuration YAML per variant row: ``folder/<variant_id>.yaml``.

    Each file is a :class:`vei.config.RunConfig` (``vei.config.load_config(path,
    RunConfig)`` reads it back; ``vei run SCENARIO --config FILE`` runs it) with the
    variant's absolute time shift. Returns the paths written.
    """
    import yaml

    from vei.config import config_to_dict
    from vei.io.atomic import write_text
    from vei.sweep.spec import variant_config

    # libyaml's emitter when PyYAML has it (10x faster, same documents)
    dumper = getattr(yaml, "CSafeDumper", yaml.SafeDumper)
    folder = Path(folder)
    paths = []
    for row in variants.to_dict("records"):
        params = {n: row[n] for n in (*spec.names, *RIDER_PARAM_COLUMNS) if n in row}
        # Named by the variant id, the sweep's label of the variant: the perception's
        # random numbers are keyed by it (vei.policy.perception_random.label_keys).
        cfg = variant_config(
            params,
            spec,
            auto_shift_s=auto_shift_s,
            name=str(row["variant_id"]),
            reach_speed_mps=reach_speed_mps,
        )
        doc = config_to_dict(cfg)
        header = (
            f"# vei run configuration of sweep variant {row['variant_id']} "
            f"(scenario {row.get('scenario_id', '?')})\n"
        )
        paths.append(
            write_text(
                folder / f"{row['variant_id']}.yaml",
                header + yaml.dump(doc, Dumper=dumper, sort_keys=False),
            )
        )
    return paths
