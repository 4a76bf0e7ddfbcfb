"""Reading and checking the CSV tables of track datasets (inD family, SinD).

Every problem is an :class:`vei.errors.InputError` naming the file, the 1-based data row
(header excluded) and the column, and saying what was expected: the same messages as the
interaction format's reader (:mod:`vei.io.interaction_checks`, whose numeric check this
module reuses).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from vei.errors import InputError
from vei.io.interaction_checks import _numeric


def read_table(path: Path, *, text_columns: tuple[str, ...] = ()) -> pd.DataFrame:
    """A CSV with a header line: ``text_columns`` as stripped strings ('' for empty), the
    others parsed by pandas (numbers as float64 / int64, empty cells NaN).

    Raises:
        InputError: missing, empty or unreadable file, a column named twice.
    """
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        df = pd.read_csv(
            path,
            dtype={c: str for c in text_columns},
            keep_default_na=False,
            na_values=[""],
            encoding="utf-8-sig",
            skipinitialspace=True,
        )
    except pd.errors.EmptyDataError:
        raise InputError("empty file (expected a header line and data rows)", path=path) from None
    except (pd.errors.ParserError, UnicodeDecodeError, ValueError) as exc:
        raise InputError(f"not a readable CSV file: {exc}", path=path) from None
    df.columns = [str(c).strip() for c in df.columns]
    if len(set(df.columns)) != len(df.columns):
        dup = next(c for c in df.columns if list(df.columns).count(c) > 1)
        raise InputError("column appears twice in the header", path=path, field=dup)
    for col in text_columns:
        if col in df.columns:
            df[col] = df[col].fillna("").astype(str).str.strip()
    if df.empty:
        raise InputError("no data rows", path=path)
    return df


def require(df: pd.DataFrame, path: Path, columns: tuple[str, ...], *, layout: str) -> None:
    """InputError naming the first column of ``columns`` missing from the header."""
    for col in columns:
        if col not in df.columns:
            raise InputError(
                f"missing column in the header ({layout}; found: {', '.join(df.columns) or 'none'})",
                path=path,
                field=col,
            )


def numbers(
    df: pd.DataFrame,
    path: Path,
    col: str,
    *,
    required: bool = True,
    lo: float | None = None,
    hi: float | None = None,
    unit: str = "",
) -> np.ndarray:
    """Column as float64 [N]: not a number, infinite, outside [lo, hi] or (``required``)
    empty -> InputError naming the row and column."""
    return _numeric(df, path, col, required=required, lo=lo, hi=hi, unit=unit)


def integers(df: pd.DataFrame, path: Path, col: str, *, lo: float | None = None) -> np.ndarray:
    """Column of whole numbers as int64 [N] (InputError on a fraction)."""
    v = numbers(df, path, col, lo=lo)
    frac = v != np.round(v)
    if frac.any():
        i = int(np.flatnonzero(frac)[0])
        raise InputError(
            f"expected a whole number, got {float(v[i])!r}", path=path, row=i + 1, field=col
        )
    return v.astype(np.int64)


def texts(df: pd.DataFrame, path: Path, col: str, *, what: str) -> np.ndarray:
    """Column of non-empty strings [N] (InputError on an empty cell)."""
    values = df[col].fillna("").astype(str).str.strip().to_numpy(dtype=object)
    empty = values == ""
    if empty.any():
        i = int(np.flatnonzero(empty)[0])
        raise InputError(f"missing value; expected {what}", path=path, row=i + 1, field=col)
    return values


def check_increasing(track: np.ndarray, order_key: np.ndarray, path: Path, col: str) -> None:
    """Within each track (rows in file order) ``order_key`` must strictly increase;
    InputError naming the first row where it does not."""
    order = np.argsort(track, kind="stable")
    tr, key = track[order], order_key[order]
    same = tr[1:] == tr[:-1]
    bad = same & (np.diff(key) <= 0)
    if bad.any():
        i = int(order[np.flatnonzero(bad)[0] + 1])
        raise InputError(
            f"{col} {key[np.flatnonzero(bad)[0] + 1]!r} does not increase within track "
            f"{tr[np.flatnonzero(bad)[0] + 1]!r} (duplicate or backwards); expected strictly "
            "increasing values per track",
            path=path,
            row=i + 1,
            field=col,
        )
