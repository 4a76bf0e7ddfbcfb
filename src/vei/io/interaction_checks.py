"""Cell and table checks of the interaction format's CSV files (``vei.interaction/1``).

The helpers :func:`vei.io.interaction.read_interaction` builds its tables from: reading a
CSV (text columns as stripped strings), required columns, numeric columns with ranges,
times (``t_s`` or ``timestamp_utc``), track ids and categories, and the plausibility
checks (increasing times, one category per track, latitude/longitude ranges, and whether
the heading and the lateral axis agree with the GPS course). Each raises
:class:`vei.errors.InputError` naming the file, the 1-based data row, the field and what
was expected. Internal to :mod:`vei.io`: the format's public names live in
:mod:`vei.io.interaction`.
"""

from __future__ import annotations

import math
import re
from datetime import datetime
from pathlib import Path

import numpy as np
import pandas as pd

from vei.errors import InputError
from vei.types import CATEGORIES

#: Minimum displacement between two fixes for their course to count [m].
_COURSE_MIN_STEP_M = 0.3
#: Minimum number of course samples before heading/position plausibility checks run.
_COURSE_MIN_SAMPLES = 3
#: Median course disagreement below which an interpretation "agrees" / above which it "disagrees" [deg].
_AGREE_DEG = 20.0
_DISAGREE_DEG = 45.0
#: Same for the swapped-columns test: the exchanged reading must agree closely [deg].
_SWAP_DISAGREE_DEG = 30.0
_SWAP_AGREE_DEG = 10.0

#: Columns read as text (everything else is parsed as numbers).
_STRING_COLUMNS = ("track_id", "category", "timestamp_utc")

_TZ_SUFFIX = re.compile(r"(?:Z|z|[+-]\d{2}(?::?\d{2})?)$")


def _read_csv(path: Path) -> pd.DataFrame:
    """Read a CSV: string columns as stripped strings ('' for empty), others parsed by pandas
    (numbers as float64 with NaN for empty cells; columns holding text stay object)."""
    if not path.is_file():
        raise InputError("file not found", path=path)
    try:
        df = pd.read_csv(
            path,
            dtype={c: str for c in _STRING_COLUMNS},
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
    seen: set[str] = set()
    for col in df.columns:
        if col in seen:
            raise InputError("column appears twice in the header", path=path, field=col)
        seen.add(col)
    for col in _STRING_COLUMNS:
        if col in df.columns:
            df[col] = df[col].fillna("").astype(str).str.strip()
    return df


def _require(df: pd.DataFrame, path: Path, columns: tuple[str, ...]) -> None:
    for col in columns:
        if col not in df.columns:
            raise InputError(
                f"missing column in the header (found: {', '.join(df.columns) or 'none'})",
                path=path,
                field=col,
            )


def _numeric(
    df: pd.DataFrame,
    path: Path,
    col: str,
    *,
    required: bool,
    lo: float | None = None,
    hi: float | None = None,
    unit: str = "",
) -> np.ndarray:
    """Column as float64; empty cells are NaN (an error when ``required``)."""
    if col not in df.columns:
        return np.full(len(df), np.nan)
    raw = df[col]
    if pd.api.types.is_numeric_dtype(raw) and not pd.api.types.is_bool_dtype(raw):
        values = raw.to_numpy(dtype=np.float64)
        text = raw
        bad_text = np.zeros(len(values), dtype=bool)
    else:
        text = raw.where(raw.notna(), "").astype(str).str.strip()
        values = pd.to_numeric(text.where(text != "", None), errors="coerce").to_numpy(
            dtype=np.float64
        )
        bad_text = (
            np.isnan(values) & (text != "").to_numpy() & ~text.str.lower().isin(["nan"]).to_numpy()
        )
    if bad_text.any():
        i = int(np.flatnonzero(bad_text)[0])
        raise InputError(
            f"expected a number{unit}, got {text.iloc[i]!r}", path=path, row=i + 1, field=col
        )
    if required and np.isnan(values).any():
        i = int(np.flatnonzero(np.isnan(values))[0])
        raise InputError(
            f"missing value (NaN or empty); expected a number{unit}",
            path=path,
            row=i + 1,
            field=col,
        )
    inf = np.isinf(values)
    if inf.any():
        i = int(np.flatnonzero(inf)[0])
        raise InputError(
            f"expected a finite number{unit}, got {text.iloc[i]!r}", path=path, row=i + 1, field=col
        )
    with np.errstate(invalid="ignore"):
        out_of_range = np.zeros(len(values), dtype=bool)
        if lo is not None:
            out_of_range |= values < lo
        if hi is not None:
            out_of_range |= values > hi
    if out_of_range.any():
        i = int(np.flatnonzero(out_of_range)[0])
        span = f"[{lo if lo is not None else '-inf'}, {hi if hi is not None else 'inf'}]"
        raise InputError(
            f"value {float(values[i])!r} outside {span}{unit}", path=path, row=i + 1, field=col
        )
    return values


def _times(df: pd.DataFrame, path: Path, start: datetime) -> np.ndarray:
    """t_s [s] from the ``t_s`` column, or from ``timestamp_utc`` (ISO 8601 with timezone)."""
    if "t_s" in df.columns:
        t = _numeric(df, path, "t_s", required=True, unit=" [s]")
        if "timestamp_utc" in df.columns:
            t2 = _timestamps_to_s(df, path, start)
            off = np.abs(t - t2) > 1e-3
            if off.any():
                i = int(np.flatnonzero(off)[0])
                raise InputError(
                    f"disagrees with t_s = {float(t[i])!r} by {t2[i] - t[i]:.6f} s (give one of t_s, timestamp_utc, or consistent ones)",
                    path=path,
                    row=i + 1,
                    field="timestamp_utc",
                )
        return t
    if "timestamp_utc" in df.columns:
        return _timestamps_to_s(df, path, start)
    raise InputError(
        f"missing column in the header: need t_s or timestamp_utc (found: {', '.join(df.columns) or 'none'})",
        path=path,
        field="t_s",
    )


def _timestamps_to_s(df: pd.DataFrame, path: Path, start: datetime) -> np.ndarray:
    text = df["timestamp_utc"]
    empty = (text == "").to_numpy()
    if empty.any():
        i = int(np.flatnonzero(empty)[0])
        raise InputError(
            "missing value; expected an ISO 8601 timestamp with timezone",
            path=path,
            row=i + 1,
            field="timestamp_utc",
        )
    naive = ~text.str.contains(_TZ_SUFFIX).to_numpy()
    if naive.any():
        i = int(np.flatnonzero(naive)[0])
        raise InputError(
            f"{text.iloc[i]!r} has no timezone (naive); write e.g. '{text.iloc[i]}Z' for UTC",
            path=path,
            row=i + 1,
            field="timestamp_utc",
        )
    ts = pd.to_datetime(text, format="ISO8601", utc=True, errors="coerce")
    bad = ts.isna().to_numpy()
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise InputError(
            f"{text.iloc[i]!r} is not an ISO 8601 timestamp",
            path=path,
            row=i + 1,
            field="timestamp_utc",
        )
    delta = ts - pd.Timestamp(start)
    return (delta.dt.total_seconds()).to_numpy(dtype=np.float64)


def _strings(df: pd.DataFrame, path: Path, col: str, *, what: str) -> np.ndarray:
    values = df[col].to_numpy(dtype=object)
    empty = df[col].to_numpy() == ""
    if empty.any():
        i = int(np.flatnonzero(empty)[0])
        raise InputError(f"missing value; expected {what}", path=path, row=i + 1, field=col)
    return values.astype(str)


def _categories(df: pd.DataFrame, path: Path) -> np.ndarray:
    cat = _strings(df, path, "category", what=f"one of {', '.join(CATEGORIES)}")
    unknown = ~np.isin(cat, CATEGORIES)
    if unknown.any():
        i = int(np.flatnonzero(unknown)[0])
        raise InputError(
            f"unknown category {str(cat[i])!r}; expected one of {', '.join(CATEGORIES)}",
            path=path,
            row=i + 1,
            field="category",
        )
    return cat


def _check_increasing(
    t: np.ndarray, path: Path, rows: np.ndarray | None = None, *, label: str = ""
) -> None:
    """Times strictly increasing (rows: 1-based file rows of t's entries)."""
    if t.size < 2:
        return
    d = np.diff(t)
    bad = d <= 0
    if bad.any():
        k = int(np.flatnonzero(bad)[0]) + 1
        row = int(rows[k]) if rows is not None else k + 1
        prev_row = int(rows[k - 1]) if rows is not None else k
        kind = "duplicate time" if d[k - 1] == 0 else "time goes backwards"
        raise InputError(
            f"{kind}{label}: t_s = {float(t[k])!r} after {float(t[k - 1])!r} at row {prev_row}; times must strictly increase",
            path=path,
            row=row,
            field="t_s",
        )


def _check_tracks(track: np.ndarray, cat: np.ndarray, t: np.ndarray, path: Path) -> None:
    """Per track: strictly increasing times in file order and one category."""
    order = np.argsort(track, kind="stable")
    rows = order + 1
    tr_sorted = track[order]
    bounds = np.flatnonzero(tr_sorted[1:] != tr_sorted[:-1]) + 1
    for seg in np.split(np.arange(len(order)), bounds):
        idx = order[seg]
        tid = str(track[idx[0]])
        _check_increasing(t[idx], path, rows[seg], label=f" in track {tid!r}")
        cats = cat[idx]
        if (cats != cats[0]).any():
            k = int(np.flatnonzero(cats != cats[0])[0])
            raise InputError(
                f"track {tid!r} changes category from {str(cats[0])!r} (row {idx[0] + 1}) to {str(cats[k])!r}; "
                "one category per track",
                path=path,
                row=int(idx[k]) + 1,
                field="category",
            )


def _check_latlon(lat: np.ndarray, lon: np.ndarray, path: Path) -> None:
    for name, values, limit in (("lat_deg", lat, 90.0), ("lon_deg", lon, 180.0)):
        bad = np.abs(values) > limit
        if bad.any():
            i = int(np.flatnonzero(bad)[0])
            hint = ""
            if (
                name == "lat_deg"
                and np.mean(bad) > 0.5
                and np.all(np.abs(lon) <= 90.0)
                and np.all(np.abs(lat) <= 180.0)
            ):
                hint = (
                    "; lat_deg and lon_deg look swapped (lon_deg holds values that fit a latitude)"
                )
            raise InputError(
                f"value {float(values[i])!r} outside [-{limit:g}, {limit:g}] deg{hint}",
                path=path,
                row=i + 1,
                field=name,
            )


def _course_deg(lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Course [deg cw from north] between consecutive fixes that moved, and the index of each start fix."""
    from pyproj import Geod

    geod = Geod(ellps="WGS84")
    az, _, dist = geod.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])
    moved = np.asarray(dist) >= _COURSE_MIN_STEP_M
    return np.asarray(az)[moved], np.flatnonzero(moved)


def _angle_diff_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return np.abs((a - b + 180.0) % 360.0 - 180.0)


def _check_heading_and_axes(
    lat: np.ndarray, lon: np.ndarray, heading: np.ndarray, path: Path
) -> None:
    """Use the course over ground to catch radians-as-degrees headings and swapped lat/lon."""
    if np.isnan(heading).all() or lat.size < 2:
        return
    course, idx = _course_deg(lat, lon)
    h = heading[idx]
    ok = np.isfinite(h)
    course, h, idx = course[ok], h[ok], idx[ok]
    if course.size < _COURSE_MIN_SAMPLES:
        return
    as_given = float(np.median(_angle_diff_deg(course, h)))
    finite = heading[np.isfinite(heading)]
    if as_given > _DISAGREE_DEG and np.all(np.abs(finite) <= 2.0 * math.pi + 1e-9):
        as_rad = float(np.median(_angle_diff_deg(course, np.degrees(h))))
        if as_rad < _AGREE_DEG:
            raise InputError(
                f"heading looks like radians, not degrees: all values lie within +-2*pi and the course "
                f"over ground agrees with them read as radians (median {as_rad:.1f} deg off) but not as "
                f"degrees (median {as_given:.1f} deg off); expected degrees clockwise from north",
                path=path,
                row=int(idx[0]) + 1,
                field="heading_deg",
            )
    if as_given > _SWAP_DISAGREE_DEG and np.all(np.abs(lon) <= 90.0):
        sw_course, sw_idx = _course_deg(lon, lat)
        sw_h = heading[sw_idx]
        ok = np.isfinite(sw_h)
        if ok.sum() >= _COURSE_MIN_SAMPLES:
            swapped = float(np.median(_angle_diff_deg(sw_course[ok], sw_h[ok])))
            if swapped < _SWAP_AGREE_DEG:
                raise InputError(
                    f"lat_deg and lon_deg look swapped: the course over ground disagrees with heading_deg "
                    f"(median {as_given:.1f} deg off) but agrees when the two columns are exchanged "
                    f"(median {swapped:.1f} deg off)",
                    path=path,
                    row=int(sw_idx[ok][0]) + 1,
                    field="lat_deg",
                )
