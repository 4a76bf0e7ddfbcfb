"""Reader and writer of the interaction format v1 (``vei.interaction/1``).

An interaction is a folder (spec: ``docs/interaction-format.md``)::

    interaction.json     format, id, source, start_time_utc, y_axis, [annotation_rate_hz, notes]
    ego.csv              t_s | timestamp_utc, lat_deg, lon_deg, [heading_deg, speed_mps]
    annotations.csv      t_s | timestamp_utc, track_id, category, x_m, y_m, [yaw_deg, length_m, width_m]
                         (frame 'world': lat_deg, lon_deg, [heading_deg] instead of x_m, y_m, [yaw_deg])
    ground_truth.csv     optional: t_s | timestamp_utc, track_id, category, lat_deg, lon_deg

:func:`read_interaction` validates everything and raises :class:`vei.errors.InputError`
naming the file, the 1-based data row (header excluded), the field and what was expected.
Extra CSV columns are allowed and ignored: the returned tables hold exactly the columns
documented on :class:`vei.types.Interaction`. :func:`write_interaction` writes a folder
atomically and validates it before it appears, so a failed write leaves nothing behind.
The cell and table checks the reader is built from live in :mod:`vei.io.interaction_checks`.
"""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from vei.errors import InputError
from vei.io.atomic import atomic_dir
from vei.io.interaction_checks import (
    _categories,
    _check_heading_and_axes,
    _check_increasing,
    _check_latlon,
    _check_tracks,
    _numeric,
    _read_csv,
    _require,
    _strings,
    _times,
)
from vei.types import Interaction, InteractionMeta

#: Value of the ``format`` key of interaction.json.
FORMAT = "vei.interaction/1"

META_FILE = "interaction.json"
EGO_FILE = "ego.csv"
ANNOTATIONS_FILE = "annotations.csv"
GROUND_TRUTH_FILE = "ground_truth.csv"

#: Columns of the returned tables, in order (required + optional, filled with NaN).
EGO_COLUMNS: tuple[str, ...] = ("t_s", "lat_deg", "lon_deg", "heading_deg", "speed_mps")
ANNOTATION_COLUMNS: tuple[str, ...] = (
    "t_s",
    "track_id",
    "category",
    "x_m",
    "y_m",
    "yaw_deg",
    "length_m",
    "width_m",
)
#: Columns of the returned annotations of a world-frame interaction (``frame = world``).
WORLD_ANNOTATION_COLUMNS: tuple[str, ...] = (
    "t_s",
    "track_id",
    "category",
    "lat_deg",
    "lon_deg",
    "heading_deg",
    "length_m",
    "width_m",
)
GROUND_TRUTH_COLUMNS: tuple[str, ...] = ("t_s", "track_id", "category", "lat_deg", "lon_deg")
#: Values of interaction.json's optional ``frame`` key.
FRAMES: tuple[str, ...] = ("ego", "world")

_META_REQUIRED = ("format", "id", "source", "start_time_utc", "y_axis")
_META_OPTIONAL = ("annotation_rate_hz", "notes", "frame", "origin_lat_deg", "origin_lon_deg")

#: Times closer than this are "equal" when checking annotations against the GPS span [s].
TIME_TOLERANCE_S = 1e-6


# ----------------------------------------------------------------------------- metadata


def parse_utc(
    text: Any, *, path: Path | None = None, field: str = "start_time_utc", row: int | None = None
) -> datetime:
    """Parse an ISO 8601 timestamp with a timezone into an aware UTC datetime.

    Raises InputError when it is not a string, not ISO 8601, or has no timezone (naive).
    """
    if not isinstance(text, str):
        raise InputError(
            f"expected an ISO 8601 timestamp string with timezone, got {text!r}",
            path=path,
            row=row,
            field=field,
        )
    s = text.strip()
    try:
        dt = datetime.fromisoformat(s)
    except ValueError:
        raise InputError(
            f"{text!r} is not an ISO 8601 timestamp (expected e.g. '2021-02-09T12:40:35.690Z')",
            path=path,
            row=row,
            field=field,
        ) from None
    if dt.tzinfo is None or dt.utcoffset() is None:
        raise InputError(
            f"{text!r} has no timezone (naive); state it explicitly, e.g. '{s}Z' for UTC or "
            f"'{s}+01:00' for CET",
            path=path,
            row=row,
            field=field,
        )
    return dt.astimezone(UTC)


def _read_meta(path: Path) -> InteractionMeta:
    if not path.is_file():
        raise InputError(f"missing {META_FILE} (every interaction folder needs one)", path=path)
    try:
        raw = json.loads(path.read_text(encoding="utf-8-sig"))
    except json.JSONDecodeError as exc:
        raise InputError(
            f"not valid JSON: {exc.msg} at line {exc.lineno}, column {exc.colno}",
            path=path,
            row=exc.lineno,
        ) from None
    except UnicodeDecodeError:
        raise InputError("not UTF-8 text", path=path) from None
    except RecursionError:
        raise InputError(
            "JSON nested too deeply (expected a flat object of the keys in docs/interaction-format.md)",
            path=path,
        ) from None
    if not isinstance(raw, dict):
        raise InputError(f"expected a JSON object, got {type(raw).__name__}", path=path)
    for key in _META_REQUIRED:
        if key not in raw:
            raise InputError(
                f"missing key (required: {', '.join(_META_REQUIRED)})", path=path, field=key
            )
    unknown = sorted(set(raw) - set(_META_REQUIRED) - set(_META_OPTIONAL))
    if unknown:
        raise InputError(
            f"unknown key (allowed: {', '.join(_META_REQUIRED + _META_OPTIONAL)}); put free text in 'notes'",
            path=path,
            field=unknown[0],
        )
    if raw["format"] != FORMAT:
        raise InputError(f"expected {FORMAT!r}, got {raw['format']!r}", path=path, field="format")
    for key in ("id", "source"):
        if not isinstance(raw[key], str) or not raw[key].strip():
            raise InputError(f"expected a non-empty string, got {raw[key]!r}", path=path, field=key)
    start = parse_utc(raw["start_time_utc"], path=path, field="start_time_utc")
    if raw["y_axis"] not in ("left", "right"):
        raise InputError(
            f"expected 'left' or 'right', got {raw['y_axis']!r}", path=path, field="y_axis"
        )
    rate = raw.get("annotation_rate_hz")
    if rate is not None:
        if (
            isinstance(rate, bool)
            or not isinstance(rate, int | float)
            or not math.isfinite(rate)
            or rate <= 0
        ):
            raise InputError(
                f"expected a positive number [Hz] or null, got {rate!r}",
                path=path,
                field="annotation_rate_hz",
            )
        rate = float(rate)
    notes = raw.get("notes", "")
    if notes is None:
        notes = ""
    if not isinstance(notes, str):
        raise InputError(f"expected a string, got {type(notes).__name__}", path=path, field="notes")
    frame = raw.get("frame", "ego")
    if frame not in FRAMES:
        raise InputError(
            f"expected one of {', '.join(map(repr, FRAMES))}, got {frame!r}",
            path=path,
            field="frame",
        )
    origin = _read_origin(raw, path, frame)
    return InteractionMeta(
        id=raw["id"],
        source=raw["source"],
        start_time_utc=start,
        y_axis=raw["y_axis"],
        annotation_rate_hz=rate,
        notes=notes,
        frame=frame,
        origin_lat_deg=origin[0],
        origin_lon_deg=origin[1],
    )


def _read_origin(raw: dict, path: Path, frame: str) -> tuple[float | None, float | None]:
    """The optional plane origin of a world-frame interaction (both keys or neither)."""
    keys = ("origin_lat_deg", "origin_lon_deg")
    given = [k in raw and raw[k] is not None for k in keys]
    if not any(given):
        return None, None
    if frame != "world":
        key = keys[given.index(True)]
        raise InputError(
            'a plane origin is only allowed with "frame": "world"', path=path, field=key
        )
    if not all(given):
        raise InputError(
            "give both origin_lat_deg and origin_lon_deg, or neither",
            path=path,
            field=keys[given.index(False)],
        )
    out = []
    for key, limit in zip(keys, (90.0, 180.0), strict=True):
        v = raw[key]
        if (
            isinstance(v, bool)
            or not isinstance(v, int | float)
            or not math.isfinite(v)
            or abs(v) > limit
        ):
            raise InputError(
                f"expected a number in [-{limit:g}, {limit:g}] [deg], got {v!r}",
                path=path,
                field=key,
            )
        out.append(float(v))
    return out[0], out[1]


# ----------------------------------------------------------------------------- tables


def _read_ego(path: Path, start: datetime) -> pd.DataFrame:
    df = _read_csv(path)
    _require(df, path, ("lat_deg", "lon_deg"))
    t = _times(df, path, start)
    if len(df) < 2:
        raise InputError(
            f"the ego track has {len(df)} fix(es); expected at least 2 GPS fixes",
            path=path,
            row=len(df) or None,
            field="t_s",
        )
    lat = _numeric(df, path, "lat_deg", required=True, unit=" [deg]")
    lon = _numeric(df, path, "lon_deg", required=True, unit=" [deg]")
    _check_latlon(lat, lon, path)
    heading = _numeric(df, path, "heading_deg", required=False, lo=-360.0, hi=360.0, unit=" [deg]")
    speed = _numeric(df, path, "speed_mps", required=False, lo=0.0, unit=" [m/s]")
    _check_increasing(t, path)
    _check_heading_and_axes(lat, lon, heading, path)
    return pd.DataFrame(
        {"t_s": t, "lat_deg": lat, "lon_deg": lon, "heading_deg": heading, "speed_mps": speed}
    )


def _read_annotations(path: Path, start: datetime, ego_t: np.ndarray) -> pd.DataFrame:
    df = _read_csv(path)
    _require(df, path, ("track_id", "category", "x_m", "y_m"))
    t = _times(df, path, start)
    if len(df) == 0:
        raise InputError(
            "no annotations: expected at least one annotated road user (one data row)",
            path=path,
            field="track_id",
        )
    track = _strings(df, path, "track_id", what="a track id")
    cat = _categories(df, path)
    x = _numeric(df, path, "x_m", required=True, unit=" [m]")
    y = _numeric(df, path, "y_m", required=True, unit=" [m]")
    yaw = _numeric(df, path, "yaw_deg", required=False, lo=-360.0, hi=360.0, unit=" [deg]")
    length = _positive_size(df, path, "length_m")
    width = _positive_size(df, path, "width_m")
    _check_tracks(track, cat, t, path)
    _check_inside_ego_span(t, ego_t, path)
    out = pd.DataFrame(
        {
            "t_s": t,
            "track_id": pd.Series(track, dtype=object),
            "category": pd.Series(cat, dtype=object),
            "x_m": x,
            "y_m": y,
            "yaw_deg": yaw,
            "length_m": length,
            "width_m": width,
        }
    )
    return out.sort_values(["track_id", "t_s"], kind="stable").reset_index(drop=True)


def _read_world_annotations(path: Path, start: datetime, ego_t: np.ndarray) -> pd.DataFrame:
    """annotations.csv of a world-frame interaction: lat_deg / lon_deg / heading_deg per row."""
    df = _read_csv(path)
    _require(df, path, ("track_id", "category", "lat_deg", "lon_deg"))
    t = _times(df, path, start)
    if len(df) == 0:
        raise InputError(
            "no annotations: expected at least one annotated road user (one data row)",
            path=path,
            field="track_id",
        )
    track = _strings(df, path, "track_id", what="a track id")
    cat = _categories(df, path)
    lat = _numeric(df, path, "lat_deg", required=True, unit=" [deg]")
    lon = _numeric(df, path, "lon_deg", required=True, unit=" [deg]")
    _check_latlon(lat, lon, path)
    heading = _numeric(df, path, "heading_deg", required=False, lo=-360.0, hi=360.0, unit=" [deg]")
    sizes = {
        name: _positive_size(df, path, name) for name in ("length_m", "width_m")
    }  # fmt: skip
    _check_tracks(track, cat, t, path)
    _check_inside_ego_span(t, ego_t, path)
    out = pd.DataFrame(
        {
            "t_s": t,
            "track_id": pd.Series(track, dtype=object),
            "category": pd.Series(cat, dtype=object),
            "lat_deg": lat,
            "lon_deg": lon,
            "heading_deg": heading,
            "length_m": sizes["length_m"],
            "width_m": sizes["width_m"],
        }
    )
    return out.sort_values(["track_id", "t_s"], kind="stable").reset_index(drop=True)


def _positive_size(df: pd.DataFrame, path: Path, name: str) -> np.ndarray:
    v = _numeric(df, path, name, required=False, lo=0.0, unit=" [m]")
    zero = v == 0
    if zero.any():
        raise InputError(
            "expected a positive size [m] (or an empty cell for unknown)",
            path=path,
            row=int(np.flatnonzero(zero)[0]) + 1,
            field=name,
        )
    return v


def _check_inside_ego_span(t: np.ndarray, ego_t: np.ndarray, path: Path) -> None:
    lo, hi = float(ego_t[0]), float(ego_t[-1])
    outside = (t < lo - TIME_TOLERANCE_S) | (t > hi + TIME_TOLERANCE_S)
    if outside.any():
        i = int(np.flatnonzero(outside)[0])
        raise InputError(
            f"t_s = {float(t[i])!r} lies outside the GPS time span [{lo!r}, {hi!r}] s of {EGO_FILE}; "
            "annotations need the ego position at their time",
            path=path,
            row=i + 1,
            field="t_s",
        )


def _read_ground_truth(path: Path, start: datetime) -> pd.DataFrame:
    df = _read_csv(path)
    _require(df, path, ("track_id", "category", "lat_deg", "lon_deg"))
    t = _times(df, path, start)
    if len(df) == 0:
        raise InputError(
            "no rows: expected at least one ground-truth sample (or no file)",
            path=path,
            field="track_id",
        )
    track = _strings(df, path, "track_id", what="a track id")
    cat = _categories(df, path)
    lat = _numeric(df, path, "lat_deg", required=True, unit=" [deg]")
    lon = _numeric(df, path, "lon_deg", required=True, unit=" [deg]")
    _check_latlon(lat, lon, path)
    _check_tracks(track, cat, t, path)
    out = pd.DataFrame(
        {
            "t_s": t,
            "track_id": pd.Series(track, dtype=object),
            "category": pd.Series(cat, dtype=object),
            "lat_deg": lat,
            "lon_deg": lon,
        }
    )
    return out.sort_values(["track_id", "t_s"], kind="stable").reset_index(drop=True)


def read_interaction(folder: str | Path) -> Interaction:
    """Read and validate an interaction folder (format ``vei.interaction/1``).

    Returns an :class:`~vei.types.Interaction` whose tables have exactly the documented
    columns (extra CSV columns are ignored; absent optional columns are NaN):

    - ``ego`` [N_ego rows]: t_s [s], lat_deg, lon_deg [deg], heading_deg [deg cw from true
      north], speed_mps [m/s]; sorted by t_s.
    - ``annotations`` [N_ann rows]: t_s, track_id (str), category, x_m, y_m [m, y per
      meta.y_axis], yaw_deg [deg], length_m, width_m [m]; sorted by (track_id, t_s).
      With ``meta.frame == 'world'``: t_s, track_id, category, lat_deg, lon_deg,
      heading_deg [deg, true, clockwise from north], length_m, width_m.
    - ``ground_truth`` [N_gt rows] or None: t_s, track_id (str), category, lat_deg, lon_deg.

    Times given as ``timestamp_utc`` (ISO 8601 with timezone) are converted to t_s, seconds
    since ``start_time_utc``.

    Raises:
        InputError: naming file, 1-based data row and field, for anything the spec forbids.
    """
    root = Path(folder)
    if not root.is_dir():
        raise InputError(
            "not a folder (expected an interaction folder with interaction.json, ego.csv, annotations.csv)",
            path=root,
        )
    meta = _read_meta(root / META_FILE)
    ego = _read_ego(root / EGO_FILE, meta.start_time_utc)
    read_ann = _read_world_annotations if meta.frame == "world" else _read_annotations
    annotations = read_ann(root / ANNOTATIONS_FILE, meta.start_time_utc, ego["t_s"].to_numpy())
    gt_path = root / GROUND_TRUTH_FILE
    ground_truth = _read_ground_truth(gt_path, meta.start_time_utc) if gt_path.exists() else None
    return Interaction(
        meta=meta, ego=ego, annotations=annotations, ground_truth=ground_truth, root=root
    )


# ----------------------------------------------------------------------------- writer


def format_utc(dt: datetime) -> str:
    """Aware datetime -> ISO 8601 UTC string with microseconds and a 'Z' suffix."""
    if dt.tzinfo is None or dt.utcoffset() is None:
        raise InputError(
            f"start_time_utc {dt!r} has no timezone (naive); expected an aware datetime",
            field="start_time_utc",
        )
    return dt.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _table_for_writing(
    df: pd.DataFrame, columns: tuple[str, ...], required: tuple[str, ...], name: str
) -> pd.DataFrame:
    for col in required:
        if col not in df.columns:
            raise InputError(f"the {name} table lacks the required column", path=name, field=col)
    out = pd.DataFrame(index=df.index)
    for col in columns:
        out[col] = df[col] if col in df.columns else np.nan
    return out.reset_index(drop=True)


def write_interaction(
    interaction: Interaction, folder: str | Path, *, overwrite: bool = True
) -> Path:
    """Write ``interaction`` as a format-v1 folder, atomically; returns the folder.

    The folder is assembled next to the target, read back with :func:`read_interaction`
    (so invalid data is refused with the same messages) and only then renamed into place.
    Floats are written with full (round-trip) precision; NaN as empty cells. Reading the
    result gives back equal tables.

    Raises:
        InputError: the interaction violates the format (nothing is written).
        FileExistsError: ``folder`` exists, is not empty and ``overwrite`` is False.
    """
    target = Path(folder)
    meta = interaction.meta
    doc: dict[str, Any] = {
        "format": FORMAT,
        "id": meta.id,
        "source": meta.source,
        "start_time_utc": format_utc(meta.start_time_utc),
        "y_axis": meta.y_axis,
    }
    if meta.annotation_rate_hz is not None:
        doc["annotation_rate_hz"] = meta.annotation_rate_hz
    if meta.notes:
        doc["notes"] = meta.notes
    if meta.frame != "ego":
        doc["frame"] = meta.frame
    if meta.origin_lat_deg is not None or meta.origin_lon_deg is not None:
        doc["origin_lat_deg"] = meta.origin_lat_deg
        doc["origin_lon_deg"] = meta.origin_lon_deg
    ego = _table_for_writing(interaction.ego, EGO_COLUMNS, ("t_s", "lat_deg", "lon_deg"), EGO_FILE)
    world = meta.frame == "world"
    ann = _table_for_writing(
        interaction.annotations,
        WORLD_ANNOTATION_COLUMNS if world else ANNOTATION_COLUMNS,
        ("t_s", "track_id", "category") + (("lat_deg", "lon_deg") if world else ("x_m", "y_m")),
        ANNOTATIONS_FILE,
    )
    ann["track_id"] = ann["track_id"].astype(str)
    gt = None
    if interaction.ground_truth is not None:
        gt = _table_for_writing(
            interaction.ground_truth, GROUND_TRUTH_COLUMNS, GROUND_TRUTH_COLUMNS, GROUND_TRUTH_FILE
        )
        gt["track_id"] = gt["track_id"].astype(str)
    with atomic_dir(target, overwrite=overwrite) as tmp:
        (tmp / META_FILE).write_text(
            json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8"
        )
        ego.to_csv(tmp / EGO_FILE, index=False, na_rep="", float_format=None)
        ann.to_csv(tmp / ANNOTATIONS_FILE, index=False, na_rep="")
        if gt is not None:
            gt.to_csv(tmp / GROUND_TRUTH_FILE, index=False, na_rep="")
        try:
            read_interaction(tmp)
        except InputError as exc:
            where = None if exc.path is None else target / exc.path.name
            raise InputError(
                f"refusing to write an invalid interaction: {exc.detail}",
                path=where,
                row=exc.row,
                field=exc.field,
            ) from None
    return target
