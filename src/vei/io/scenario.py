"""Scenario folders: ``scenario.json`` + ``trajectories.parquet`` (+ ``keyframes.parquet``).

``scenario.json`` (format ``vei.scenario/1``)::

    {"format": "vei.scenario/1", "id": ..., "projection": "+proj=tmerc ...",
     "origin": {"lat_deg": .., "lon_deg": ..}, "start_time_utc": "...Z", "rate_hz": 20.0,
     "bounds": {"south_deg", "west_deg", "north_deg", "east_deg"},
     "agents": [{"agent_id", "category", "length_m", "width_m", "source_track_id"}],
     "primary_threat": "escooter_7" | null, "maps": {"opendrive": "map.xodr", ...},
     ...every key of Scenario.extra (reconstruction settings, threat, errors)...}

``trajectories.parquet`` has exactly :data:`vei.types.TRAJECTORY_COLUMNS`;
``keyframes.parquet`` (optional) at least t_s, agent_id, x_m, y_m, yaw_rad. The folder is
written atomically (assembled next to the target, then renamed into place).
"""

from __future__ import annotations

import json
import math
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pandas as pd

from vei.errors import InputError
from vei.geo.frame import Bounds, LocalFrame
from vei.io.atomic import atomic_dir, write_json, write_parquet
from vei.types import CATEGORIES, EGO_CATEGORY, TRAJECTORY_COLUMNS, AgentInfo, Scenario

SCENARIO_FORMAT = "vei.scenario/1"
SCENARIO_JSON = "scenario.json"
TRAJECTORIES_PARQUET = "trajectories.parquet"
KEYFRAMES_PARQUET = "keyframes.parquet"
#: Keys of scenario.json that are not Scenario.extra.
_CORE_KEYS = (
    "format",
    "id",
    "projection",
    "origin",
    "start_time_utc",
    "rate_hz",
    "bounds",
    "agents",
    "primary_threat",
    "maps",
)
_KEYFRAME_REQUIRED = ("t_s", "agent_id", "x_m", "y_m", "yaw_rad")


def _utc_text(dt: datetime) -> str:
    if dt.tzinfo is None:
        raise InputError("start_time_utc must be timezone-aware", field="start_time_utc")
    return dt.astimezone(UTC).isoformat(timespec="microseconds").replace("+00:00", "Z")


def scenario_json(scenario: Scenario) -> dict:
    """The scenario.json document of a scenario (core keys first, then extra)."""
    doc = {
        "format": SCENARIO_FORMAT,
        "id": scenario.id,
        "projection": scenario.projection,
        "origin": {"lat_deg": scenario.origin_lat_deg, "lon_deg": scenario.origin_lon_deg},
        "start_time_utc": _utc_text(scenario.start_time_utc),
        "rate_hz": scenario.rate_hz,
        "bounds": dict(scenario.bounds),
        "agents": [
            {
                "agent_id": a.agent_id,
                "category": a.category,
                "length_m": a.length_m,
                "width_m": a.width_m,
                "source_track_id": a.source_track_id,
            }
            for a in scenario.agents
        ],
        "primary_threat": scenario.primary_threat,
        "maps": dict(scenario.maps),
    }
    clash = set(scenario.extra) & set(_CORE_KEYS)
    if clash:
        raise ValueError(f"Scenario.extra must not redefine core keys: {sorted(clash)}")
    doc.update(scenario.extra)
    return doc


def write_scenario(scenario: Scenario, folder: str | Path, extra_files: dict | None = None) -> Path:
    """Write a scenario folder atomically (replacing an existing one).

    Args:
        scenario: the scenario.
        folder: target folder.
        extra_files: optional {relative name: callable(path)} writers run inside the
            temporary folder before it is renamed into place (e.g. a figure, a map file).
    Returns:
        The folder path.
    """
    folder = Path(folder)
    doc = scenario_json(scenario)
    traj = scenario.trajectories
    missing = [c for c in TRAJECTORY_COLUMNS if c not in traj.columns]
    if missing:
        raise ValueError(f"trajectories lack columns {missing}")
    with atomic_dir(folder) as tmp:
        write_json(tmp / SCENARIO_JSON, doc)
        write_parquet(
            tmp / TRAJECTORIES_PARQUET, traj[list(TRAJECTORY_COLUMNS)].reset_index(drop=True)
        )
        if scenario.keyframes is not None:
            write_parquet(tmp / KEYFRAMES_PARQUET, scenario.keyframes.reset_index(drop=True))
        for name, writer in (extra_files or {}).items():
            writer(tmp / name)
    return folder


def _get(doc: dict, key: str, path: Path, kind: type | tuple[type, ...], what: str):
    if key not in doc:
        raise InputError(f"missing key; expected {what}", path=path, field=key)
    value = doc[key]
    if not isinstance(value, kind) or isinstance(value, bool) and kind is not bool:
        raise InputError(f"expected {what}, got {value!r}", path=path, field=key)
    return value


def _finite(value: object, path: Path, field: str, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InputError(f"expected {what}, got {value!r}", path=path, field=field)
    return float(value)


def read_scenario(folder: str | Path) -> Scenario:
    """Read and validate a scenario folder.

    Args:
        folder: folder with scenario.json and trajectories.parquet (keyframes.parquet optional).
    Returns:
        Scenario (root = folder).
    Raises:
        InputError: naming the file and field (and row, for tables) of the first problem.
    """
    folder = Path(folder)
    jpath = folder / SCENARIO_JSON
    if not jpath.is_file():
        raise InputError(
            "no scenario.json here; expected a scenario folder (vei reconstruct --out)", path=folder
        )
    try:
        doc = json.loads(jpath.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise InputError(f"not valid JSON: {exc}", path=jpath) from exc
    if not isinstance(doc, dict):
        raise InputError("expected a JSON object", path=jpath)
    fmt = _get(doc, "format", jpath, str, f"'{SCENARIO_FORMAT}'")
    if fmt != SCENARIO_FORMAT:
        raise InputError(
            f"unsupported format {fmt!r}; expected {SCENARIO_FORMAT!r}", path=jpath, field="format"
        )
    sid = _get(doc, "id", jpath, str, "a string id")
    proj = _get(doc, "projection", jpath, str, "a '+proj=tmerc' string")
    try:
        frame = LocalFrame.from_proj_string(proj)
    except InputError as exc:
        raise InputError(exc.detail, path=jpath, field="projection") from exc
    origin = _get(doc, "origin", jpath, dict, "{lat_deg, lon_deg}")
    lat0 = _finite(origin.get("lat_deg"), jpath, "origin.lat_deg", "latitude in degrees")
    lon0 = _finite(origin.get("lon_deg"), jpath, "origin.lon_deg", "longitude in degrees")
    if abs(lat0 - frame.origin_lat_deg) > 1e-7 or abs(lon0 - frame.origin_lon_deg) > 1e-7:
        raise InputError(
            "origin differs from the projection's +lat_0/+lon_0", path=jpath, field="origin"
        )
    start_text = _get(doc, "start_time_utc", jpath, str, "an ISO 8601 UTC time")
    try:
        start = datetime.fromisoformat(start_text.replace("Z", "+00:00"))
    except ValueError as exc:
        raise InputError(
            f"not an ISO 8601 time: {start_text!r}", path=jpath, field="start_time_utc"
        ) from exc
    if start.tzinfo is None:
        raise InputError("time zone missing (expected ...Z)", path=jpath, field="start_time_utc")
    rate = _finite(doc.get("rate_hz"), jpath, "rate_hz", "a rate in Hz > 0")
    if rate <= 0:
        raise InputError(f"expected a rate in Hz > 0, got {rate}", path=jpath, field="rate_hz")
    bdoc = _get(doc, "bounds", jpath, dict, "{south_deg, west_deg, north_deg, east_deg}")
    try:
        bounds = Bounds.from_dict(bdoc).as_dict()
    except (KeyError, TypeError, ValueError, InputError) as exc:
        raise InputError(f"invalid bounds: {exc}", path=jpath, field="bounds") from exc
    agents = _read_agents(_get(doc, "agents", jpath, list, "a list of agents"), jpath)
    ids = {a.agent_id for a in agents}
    primary = doc.get("primary_threat")
    if primary is not None and primary not in ids:
        raise InputError(
            f"primary threat {primary!r} is not an agent", path=jpath, field="primary_threat"
        )
    maps = doc.get("maps", {})
    if not isinstance(maps, dict) or not all(isinstance(v, str) for v in maps.values()):
        raise InputError("expected {kind: relative file name}", path=jpath, field="maps")
    traj = _read_trajectories(folder / TRAJECTORIES_PARQUET, ids)
    kpath = folder / KEYFRAMES_PARQUET
    keyframes = _read_keyframes(kpath, ids) if kpath.exists() else None
    extra = {k: v for k, v in doc.items() if k not in _CORE_KEYS}
    return Scenario(
        id=sid,
        projection=proj,
        origin_lat_deg=lat0,
        origin_lon_deg=lon0,
        start_time_utc=start,
        rate_hz=rate,
        bounds=bounds,
        agents=agents,
        primary_threat=primary,
        trajectories=traj,
        keyframes=keyframes,
        maps=dict(maps),
        extra=extra,
        root=folder,
    )


def _read_agents(items: list, path: Path) -> tuple[AgentInfo, ...]:
    out = []
    seen = set()
    for i, item in enumerate(items):
        where = f"agents[{i}]"
        if not isinstance(item, dict):
            raise InputError("expected an object", path=path, field=where)
        aid = item.get("agent_id")
        if not isinstance(aid, str) or not aid:
            raise InputError(
                f"expected a non-empty agent_id, got {aid!r}", path=path, field=f"{where}.agent_id"
            )
        if aid in seen:
            raise InputError(f"duplicate agent_id {aid!r}", path=path, field=f"{where}.agent_id")
        seen.add(aid)
        cat = item.get("category")
        if cat not in (EGO_CATEGORY, *CATEGORIES):
            raise InputError(
                f"unknown category {cat!r}; expected one of {(EGO_CATEGORY, *CATEGORIES)}",
                path=path,
                field=f"{where}.category",
            )
        length = _finite(item.get("length_m"), path, f"{where}.length_m", "a length in m > 0")
        width = _finite(item.get("width_m"), path, f"{where}.width_m", "a width in m > 0")
        if length <= 0 or width <= 0:
            raise InputError("dimensions must be > 0", path=path, field=f"{where}.length_m")
        src = item.get("source_track_id")
        if src is not None and not isinstance(src, str):
            raise InputError(
                f"expected a string or null, got {src!r}",
                path=path,
                field=f"{where}.source_track_id",
            )
        out.append(AgentInfo(aid, cat, length, width, src))
    return tuple(out)


def _read_table(path: Path) -> pd.DataFrame:
    if not path.is_file():
        raise InputError("file missing", path=path)
    try:
        return pd.read_parquet(path, engine="pyarrow")
    except Exception as exc:  # pyarrow raises several types for corrupt files
        raise InputError(f"not a readable Parquet file: {exc}", path=path) from exc


def _check_numeric(df: pd.DataFrame, path: Path, cols: tuple[str, ...]) -> None:
    for c in cols:
        values = pd.to_numeric(df[c], errors="coerce").to_numpy(dtype=np.float64)
        bad = np.flatnonzero(~np.isfinite(values))
        if bad.size:
            raise InputError(
                f"expected a finite number, got {df[c].iloc[bad[0]]!r}",
                path=path,
                row=int(bad[0]) + 1,
                field=c,
            )


def _check_agents(df: pd.DataFrame, path: Path, ids: set[str]) -> None:
    unknown = ~df["agent_id"].isin(ids)
    if unknown.any():
        i = int(np.flatnonzero(unknown.to_numpy())[0])
        raise InputError(
            f"agent {df['agent_id'].iloc[i]!r} is not listed in scenario.json",
            path=path,
            row=i + 1,
            field="agent_id",
        )


def _read_trajectories(path: Path, ids: set[str]) -> pd.DataFrame:
    df = _read_table(path)
    for c in TRAJECTORY_COLUMNS:
        if c not in df.columns:
            raise InputError(
                f"missing column; expected {list(TRAJECTORY_COLUMNS)}", path=path, field=c
            )
    _check_numeric(df, path, ("t_s", "x_m", "y_m", "yaw_rad", "speed_mps"))
    _check_agents(df, path, ids)
    neg = np.flatnonzero(df["speed_mps"].to_numpy(dtype=np.float64) < 0)
    if neg.size:
        raise InputError("speed must be >= 0", path=path, row=int(neg[0]) + 1, field="speed_mps")
    for aid, grp in df.groupby("agent_id", sort=False):
        t = grp["t_s"].to_numpy(dtype=np.float64)
        bad = np.flatnonzero(np.diff(t) <= 0)
        if bad.size:
            row = int(grp.index[bad[0] + 1]) + 1
            raise InputError(
                f"times of agent {aid!r} not strictly increasing", path=path, row=row, field="t_s"
            )
    return df[list(TRAJECTORY_COLUMNS)]


def _read_keyframes(path: Path, ids: set[str]) -> pd.DataFrame:
    df = _read_table(path)
    for c in _KEYFRAME_REQUIRED:
        if c not in df.columns:
            raise InputError(
                f"missing column; expected at least {list(_KEYFRAME_REQUIRED)}", path=path, field=c
            )
    _check_numeric(df, path, ("t_s", "x_m", "y_m", "yaw_rad"))
    _check_agents(df, path, ids)
    return df
