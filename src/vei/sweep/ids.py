"""Variant ids and seeds of a sweep: one at a time (:func:`variant_id`) and a whole design
at once (:func:`variant_ids`, the same ids ~10x faster, for 10^6-variant sweeps).

A variant id is 16 hex digits of SHA-256 over a canonical JSON text of the scenario id
and the variant's parameters (sorted by name, sorted keys, no spaces)::

    {"params":{"ego.cruise_speed_mps":"3.0","time_shift_s":"-3.0"},"scenario":"demo"}

Numbers enter as the ``repr`` of their float value (exact: the same values always give
the same id; 3 and 3.0 are one value), booleans as JSON booleans, anything else as its
``str``. The seed of a variant is drawn from its id and the spec's seed
(:func:`variant_seed`). Only the standard library, NumPy and pandas are imported.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pandas as pd


def canonical(value: Any) -> Any:
    """A parameter value as it enters a variant id: bool, the ``repr`` of a float, or str."""
    if isinstance(value, bool | np.bool_):
        return bool(value)
    if isinstance(value, int | float | np.integer | np.floating):
        return repr(float(value))
    return str(value)


def variant_id(scenario_id: str, params: Mapping[str, Any]) -> str:
    """Stable id of a variant: 16 hex digits of SHA-256 over the scenario id and parameters.

    Floats enter by ``repr`` (exact), so the same values always give the same id.
    """
    payload = json.dumps(
        {"scenario": scenario_id, "params": {k: canonical(v) for k, v in sorted(params.items())}},
        sort_keys=True,
        separators=(",", ":"),
    )
    return hashlib.sha256(payload.encode()).hexdigest()[:16]


def variant_seed(vid: str, spec_seed: int) -> int:
    """Per-variant seed in [0, 2**31): from the variant id and the spec seed (stable)."""
    h = hashlib.sha256(f"{vid}:{spec_seed}".encode()).digest()
    return int.from_bytes(h[:4], "little") & 0x7FFFFFFF


def _encoded_column(name: str, values: pd.Series) -> list[str]:
    """``"name":<canonical JSON value>`` of every row of one parameter column [N]."""
    head = json.dumps(name) + ":"
    arr = values.to_numpy()
    if arr.dtype.kind in "fiub":
        # Distinct bit patterns (floats: -0.0 and 0.0 differ, as their repr does), each
        # encoded once; NaN payloads all print 'nan'.
        if arr.dtype.kind == "f":
            arr = arr.astype(np.float64)
            keys = arr.view(np.int64)
        else:
            keys = arr
        uniq, first, codes = np.unique(keys, return_index=True, return_inverse=True)
        enc = [head + json.dumps(canonical(arr[i].item())) for i in first]
        return [enc[c] for c in codes.ravel()]
    memo: dict[tuple[type, Any], str] = {}
    out = []
    for v in arr:
        try:
            key = (type(v), v)
            s = memo.get(key)
        except TypeError:  # unhashable: encode it each time
            key, s = None, None
        if s is None:
            s = head + json.dumps(canonical(v))
            if key is not None:
                memo[key] = s
        out.append(s)
    return out


def variant_ids(scenario_id: str, points: pd.DataFrame) -> list[str]:
    """:func:`variant_id` of every row of ``points`` [N rows, one column per parameter],
    in row order; equal to ``[variant_id(scenario_id, row) for row in records]``."""
    n = len(points)
    tail = "}," + json.dumps("scenario") + ":" + json.dumps(scenario_id) + "}"
    head = "{" + json.dumps("params") + ":{"
    cols = [_encoded_column(c, points[c]) for c in sorted(points.columns)]
    if not cols:
        text = (head + tail).encode()
        return [hashlib.sha256(text).hexdigest()[:16]] * n
    sha = hashlib.sha256
    if len(cols) == 1:
        bodies: Sequence[str] = cols[0]
    else:
        bodies = [",".join(parts) for parts in zip(*cols, strict=True)]
    return [sha((head + b + tail).encode()).hexdigest()[:16] for b in bodies]


def variant_seeds(ids: Sequence[str], spec_seed: int) -> np.ndarray:
    """:func:`variant_seed` of every id [N] as int64."""
    sha = hashlib.sha256
    suffix = f":{spec_seed}"
    head = b"".join([sha((v + suffix).encode()).digest()[:4] for v in ids])
    return np.frombuffer(head, dtype="<u4").astype(np.int64) & 0x7FFFFFFF


#: Columns of a variants table that are not parameters of its variants (so not in the id).
UNNAMED_COLUMNS: tuple[str, ...] = ("scenario_id", "variant_index")


def name_variants(rows: pd.DataFrame, spec_seed: int) -> pd.DataFrame:
    """Rows of a variants table without their names, named: ``variant_id`` inserted first
    and ``seed`` after ``variant_index`` (the columns of ``variants_table(...,
    named=True)``).

    Args:
        rows: [N rows] columns scenario_id, variant_index, then every parameter of the
            variant (the columns its id is taken over); one or several scenarios.
        spec_seed: the sweep spec's seed (:func:`variant_seed`).
    Returns:
        a new DataFrame [N rows], same index; ids equal :func:`variant_id` of each row's
        parameters (:func:`variant_ids`).
    """
    params = rows.drop(columns=list(UNNAMED_COLUMNS))
    sids = rows["scenario_id"].to_numpy(object)
    if len(rows) and (sids == sids[0]).all():
        ids = variant_ids(str(sids[0]), params)
    else:  # several scenarios: each its own
        ids = [""] * len(rows)
        for sid, pos in pd.Series(range(len(rows))).groupby(sids, sort=False):
            for p, v in zip(pos, variant_ids(str(sid), params.iloc[pos.to_numpy()]), strict=True):
                ids[p] = v
    out = rows.copy(deep=False)
    out.insert(0, "variant_id", ids)
    out.insert(3, "seed", variant_seeds(ids, spec_seed))
    return out
