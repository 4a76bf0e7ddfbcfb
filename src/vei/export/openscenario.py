"""OpenSCENARIO 1.x export of a vei run (replayed or simulated), via scenariogeneration.

What the exported ``.xosc`` holds:

- ``RoadNetwork/LogicFile``: the scenario's OpenDRIVE map, copied next to the ``.xosc``
  and referenced by its bare file name (a path relative to the ``.xosc``, which esmini
  and CARLA ScenarioRunner both resolve against the scenario file's folder: esmini 3.6
  loads it so, checked by the playback tests). The copy's geoReference is written on one
  line without ``+no_defs`` (esmini reports both as unsupported; see _tidy_geo_reference).
- One ``ScenarioObject`` per agent, named by its ``agent_id``, with a ``BoundingBox`` from
  the agent's footprint (the entity's reference point is the box centre: the box's
  ``Center`` is (0, 0, height/2), so the trajectory positions are box centres, the same
  points vei's engine moves). The ego and vehicles are ``car``s; e-scooters and cyclists
  are ``bicycle``s (OpenSCENARIO has no scooter category) told apart by the property
  ``vei:category`` (``escooter`` | ``cyclist`` | ...); pedestrians are ``Pedestrian``s.
  The ``Vehicle``/``Pedestrian`` ``name`` is the CARLA blueprint (ScenarioRunner spawns
  that model) and the ego carries ``Property type=ego_vehicle`` (ScenarioRunner's marker).
- The storyboard (:mod:`vei.export.osc_build`): an agent present from t = 0 starts its
  ``FollowTrajectoryAction`` (a ``Polyline`` with timed vertices,
  ``TimeReference/Timing domainAbsoluteRelative=absolute``: vertex times are simulation
  times, ``followingMode=position``) in ``Init``; an agent that appears later is added
  (``AddEntityAction``) at its first sample time and starts its trajectory then; an agent
  whose samples end before the run does is deleted (``DeleteEntityAction``) at its last
  sample time; so every entity exists only during its own span, in every version.
- ``StopTrigger``: simulation time reaches the last sample time.

Decimation: the vertices are the samples on a ``vertex_rate_hz`` grid (10 Hz by default,
plus the last sample), refined so that the polyline, linearly interpolated in time, stays
within ``max_position_error_m`` (5 cm) and ``max_yaw_error_rad`` (0.05 rad) of every
full-rate sample: where a segment is off by more, its worst sample becomes a vertex too
(an abrupt stop at a collision, say). ``vertex_rate_hz=None`` keeps every sample.
Values are rounded to 0.1 mm, 1e-5 rad and 0.1 ms.

Frame: vei's plane (x east, y north, yaw CCW from +x) is the OpenDRIVE inertial frame of
the map, which is also OpenSCENARIO's world frame: positions are written unchanged.

scenariogeneration keeps the OpenSCENARIO version in class-level state; the export sets
it for the duration of one call, so do not export from several threads at once.
"""

from __future__ import annotations

import math
import re
import shutil
from collections.abc import Mapping, Sequence
from datetime import datetime
from pathlib import Path
from typing import Literal

import numpy as np
import pandas as pd

from vei.errors import ConfigError, DependencyError, InputError
from vei.export.osc_build import (
    ENTITY_MODELS,
    ENTITY_NAMES,
    PROP_AGENT_ID,
    PROP_CATEGORY,
    PROP_SOURCE_TRACK,
    PROP_SPAN,
    BuildOptions,
    EntityModel,
    build_scenario,
    finish_element,
)
from vei.io.atomic import atomic_path
from vei.types import AgentInfo

#: OpenSCENARIO versions the export writes (scenariogeneration >= 0.14 supports 1.0-1.3).
OSC_VERSIONS: tuple[str, ...] = ("1.0", "1.1", "1.2", "1.3")
#: Default version: 1.2 (esmini and most tools read it; use 1.0 for CARLA ScenarioRunner,
#: which accepts only 1.0).
DEFAULT_OSC_VERSION = "1.2"

EgoController = Literal["trajectory", "simulator"]

#: Columns the trajectories table must have (speed_mps optional).
REQUIRED_COLUMNS: tuple[str, ...] = ("t_s", "agent_id", "category", "x_m", "y_m", "yaw_rad")

# Entity models and property names live with the builder; re-exported here.
__all__ = [
    "DEFAULT_OSC_VERSION",
    "ENTITY_MODELS",
    "ENTITY_NAMES",
    "OSC_VERSIONS",
    "PROP_AGENT_ID",
    "PROP_CATEGORY",
    "PROP_SOURCE_TRACK",
    "PROP_SPAN",
    "EntityModel",
    "decimate_indices",
    "export_openscenario",
    "read_openscenario_trajectories",
    "timeseries_to_trajectories",
]


def _xosc():
    try:
        from scenariogeneration import xosc
    except ImportError as exc:  # pragma: no cover - depends on the environment
        raise DependencyError(
            "OpenSCENARIO export needs scenariogeneration: pip install 'vei[export]'"
        ) from exc
    return xosc


def _minor(osc_version: str) -> int:
    if osc_version not in OSC_VERSIONS:
        raise ConfigError(
            f"osc_version must be one of {', '.join(OSC_VERSIONS)}; got {osc_version!r}"
        )
    return int(osc_version.split(".")[1])


def decimate_indices(
    t_s: np.ndarray,
    xy_m: np.ndarray,
    yaw_rad: np.ndarray,
    *,
    vertex_rate_hz: float | None = 10.0,
    max_position_error_m: float = 0.05,
    max_yaw_error_rad: float = 0.05,
) -> np.ndarray:
    """Indices of the samples kept as polyline vertices.

    Args:
        t_s: [N] strictly increasing sample times [s].
        xy_m: [N, 2] positions [m].
        yaw_rad: [N] yaw [rad] (unwrapped internally).
        vertex_rate_hz: base vertex rate [Hz] (> 0), or None to keep every sample.
        max_position_error_m: largest allowed distance [m] between a sample and the
            polyline linearly interpolated at the sample's time (> 0).
        max_yaw_error_rad: same for yaw [rad] (> 0).

    Returns:
        [K] sorted int indices into the samples, first and last included (K >= min(N, 2)).
    """
    t = np.asarray(t_s, dtype=float)
    n = t.size
    if n <= 2 or vertex_rate_hz is None:
        return np.arange(n)
    if vertex_rate_hz <= 0 or max_position_error_m <= 0 or max_yaw_error_rad <= 0:
        raise ConfigError("vertex_rate_hz, max_position_error_m, max_yaw_error_rad must be > 0")
    period = 1.0 / vertex_rate_hz
    slot = np.floor((t - t[0]) / period + 1e-9).astype(np.int64)
    keep = np.zeros(n, dtype=bool)
    keep[0] = True
    keep[1:] = slot[1:] != slot[:-1]
    keep[-1] = True
    xy = np.asarray(xy_m, dtype=float)
    yaw = np.unwrap(np.asarray(yaw_rad, dtype=float))
    for _ in range(n):  # each pass adds at least one vertex or stops
        idx = np.flatnonzero(keep)
        seg = np.searchsorted(idx, np.arange(n), side="right") - 1
        seg = np.clip(seg, 0, idx.size - 2)
        i0, i1 = idx[seg], idx[seg + 1]
        w = (t - t[i0]) / (t[i1] - t[i0])
        pos = xy[i0] + w[:, None] * (xy[i1] - xy[i0])
        ang = yaw[i0] + w * (yaw[i1] - yaw[i0])
        err_p = np.hypot(*(pos - xy).T) / max_position_error_m
        err_a = np.abs(ang - yaw) / max_yaw_error_rad
        err = np.maximum(err_p, err_a)
        err[keep] = 0.0
        if not np.any(err > 1.0):
            break
        # the worst sample of every offending segment becomes a vertex
        bad = err > 1.0
        order = np.lexsort((-err, seg))
        order = order[bad[order]]
        first = np.ones(order.size, dtype=bool)
        first[1:] = seg[order[1:]] != seg[order[:-1]]
        keep[order[first]] = True
    return np.flatnonzero(keep)


def _validate(trajectories: pd.DataFrame, agents: Sequence[AgentInfo]) -> pd.DataFrame:
    missing = [c for c in REQUIRED_COLUMNS if c not in trajectories.columns]
    if missing:
        raise InputError(
            f"trajectories lack column(s) {', '.join(missing)}; expected {', '.join(REQUIRED_COLUMNS)}"
            " [, speed_mps]",
            field=missing[0],
        )
    df = trajectories.copy()
    df["agent_id"] = df["agent_id"].astype(str)
    num = ["t_s", "x_m", "y_m", "yaw_rad"] + (["speed_mps"] if "speed_mps" in df else [])
    for col in num:
        vals = pd.to_numeric(df[col], errors="coerce").to_numpy(dtype=float)
        bad = np.flatnonzero(~np.isfinite(vals))
        if bad.size:
            raise InputError(
                f"not a finite number: {df[col].iloc[bad[0]]!r}", row=int(bad[0]) + 1, field=col
            )
        df[col] = vals
    if (df["t_s"] < 0).any():
        row = int(np.flatnonzero(df["t_s"].to_numpy() < 0)[0]) + 1
        raise InputError("times must be >= 0 s (simulation time)", row=row, field="t_s")
    known = {a.agent_id for a in agents}
    unknown = sorted(set(df["agent_id"]) - known)
    if unknown:
        raise InputError(
            f"agent(s) {', '.join(unknown)} have trajectories but no AgentInfo", field="agent_id"
        )
    dup = df.duplicated(["agent_id", "t_s"])
    if dup.any():
        row = int(np.flatnonzero(dup.to_numpy())[0]) + 1
        raise InputError("duplicate time for one agent", row=row, field="t_s")
    for a in agents:
        if a.category not in ENTITY_MODELS:
            raise InputError(
                f"agent {a.agent_id}: unknown category {a.category!r}; expected one of "
                f"{', '.join(ENTITY_MODELS)}",
                field="category",
            )
        if not (a.length_m > 0 and a.width_m > 0):
            raise InputError(f"agent {a.agent_id}: dimensions must be > 0 m", field="length_m")
    if df.empty:
        raise InputError("trajectories are empty", field="t_s")
    return df.sort_values(["agent_id", "t_s"], kind="stable").reset_index(drop=True)


def export_openscenario(
    trajectories: pd.DataFrame,
    agents: Sequence[AgentInfo],
    out_dir: str | Path,
    *,
    xodr: str | Path | None = None,
    osc_version: str = DEFAULT_OSC_VERSION,
    ego_controller: EgoController = "trajectory",
    name: str = "vei_scenario",
    description: str = "vei scenario",
    author: str = "vei",
    creation_date: datetime | None = None,
    vertex_rate_hz: float | None = 10.0,
    max_position_error_m: float = 0.05,
    max_yaw_error_rad: float = 0.05,
    blueprints: Mapping[str, str] | None = None,
) -> Path:
    """Write ``out_dir/<name>.xosc`` (and a copy of the map) from a run's trajectories.

    Args:
        trajectories: long table, one row per agent per sample; columns t_s [s] (>= 0,
            simulation time), agent_id, category, x_m, y_m [m] (plane, box centre),
            yaw_rad [rad, CCW from +x], optional speed_mps [m/s] (else from positions),
            optional bool ``continuation`` (vei.continuation: run-in / run-out samples;
            an entity that has some carries the property ``vei:recorded_span_s``).
            A run's time series (vei.types.TIMESERIES_COLUMNS) works once filtered to
            one config/variant and to ``active`` rows.
        agents: AgentInfo of every agent in ``trajectories`` (footprints, categories).
        out_dir: output folder (created).
        xodr: the OpenDRIVE map; copied into ``out_dir`` and referenced by file name.
            None: an empty LogicFile path (scenario without a road network).
        osc_version: '1.0' | '1.1' | '1.2' | '1.3'.
        ego_controller: 'trajectory' (the ego follows its timed trajectory) or
            'simulator' (the ego gets only its initial position and speed: the simulator
            or the system under test drives it).
        name: file stem of the .xosc.
        description, author: FileHeader fields.
        creation_date: FileHeader date; None: 1970-01-01T00:00:00 (deterministic files).
        vertex_rate_hz, max_position_error_m, max_yaw_error_rad: decimation (module doc).
        blueprints: CARLA blueprint per category, written as the entity's name
            (defaults: ``ENTITY_NAMES``, the blueprints vei's CARLA backend spawns).

    Returns:
        Path of the written .xosc.
    """
    xosc = _xosc()
    minor = _minor(osc_version)
    if ego_controller not in ("trajectory", "simulator"):
        raise ConfigError(
            f"ego_controller must be 'trajectory' or 'simulator'; got {ego_controller!r}"
        )
    if not name or any(c in name for c in "/\\"):
        raise ConfigError(f"name must be a plain file stem; got {name!r}")
    df = _validate(trajectories, agents)
    bps = dict(ENTITY_NAMES)
    bps.update(blueprints or {})
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    map_name = ""
    if xodr is not None:
        xodr = Path(xodr)
        if not xodr.is_file():
            raise InputError("OpenDRIVE map not found", path=xodr)
        map_name = xodr.name
        target = out_dir / map_name
        if target.resolve() != xodr.resolve():
            with atomic_path(target) as tmp:
                shutil.copyfile(xodr, tmp)
                _tidy_geo_reference(tmp)

    present = [a for a in agents if a.agent_id in set(df["agent_id"])]
    opts = BuildOptions(
        minor=minor,
        ego_controller=ego_controller,
        blueprints=bps,
        map_name=map_name,
        name=name,
        description=description,
        author=author,
        creation_date=creation_date or datetime(1970, 1, 1),
        vertex_rate_hz=vertex_rate_hz,
        max_position_error_m=max_position_error_m,
        max_yaw_error_rad=max_yaw_error_rad,
    )
    # scenariogeneration's version is class-level state: set it, build, restore.
    base = xosc.VersionBase()
    saved = (xosc.VersionBase.version_major, xosc.VersionBase.version_minor)
    base.setVersion(major=1, minor=minor)
    try:
        scenario = build_scenario(xosc, df, present, opts, decimate_indices)
        from scenariogeneration.helpers import prettify

        xml = prettify(finish_element(scenario.get_element(), minor), encoding="utf-8")
    finally:
        xosc.VersionBase.version_major, xosc.VersionBase.version_minor = saved
    path = out_dir / f"{name}.xosc"
    with atomic_path(path) as tmp:
        tmp.write_bytes(xml.encode("utf-8") if isinstance(xml, str) else xml)
    return path


def read_openscenario_trajectories(path: str | Path) -> pd.DataFrame:
    """Read back the timed polyline trajectories and initial poses of an exported .xosc.

    Parses with defusedxml (no entity expansion). Every agent contributes its initial
    pose (the Init ``TeleportAction``, or the ``AddEntityAction`` of an agent that appears
    later; t_s = NaN) and the vertices of its ``FollowTrajectoryAction`` (in Init or in
    its maneuver group; t_s = NaN for a path without timing).

    Returns:
        DataFrame with columns agent_id, category (the entity's ``vei:category`` property,
        '' if absent), t_s [s] (vertex time; NaN for an Init pose), x_m, y_m, yaw_rad,
        kind ('init' | 'vertex'); sorted by agent_id, kind, t_s.
    """
    from defusedxml import ElementTree as SafeET

    path = Path(path)
    try:
        root = SafeET.parse(path).getroot()
    except Exception as exc:  # ParseError, DefusedXmlException, OSError
        raise InputError(f"not a readable OpenSCENARIO file: {exc}", path=path) from exc
    cats: dict[str, str] = {}
    for obj in root.iter("ScenarioObject"):
        cat = ""
        for prop in obj.iter("Property"):
            if prop.get("name") == PROP_CATEGORY:
                cat = prop.get("value", "")
        cats[obj.get("name", "")] = cat
    rows: list[tuple] = []

    def wp(el) -> tuple[float, float, float]:
        w = el.find("WorldPosition")
        if w is None:
            raise InputError("only WorldPosition positions are read back", path=path)
        return float(w.get("x")), float(w.get("y")), float(w.get("h", 0.0))

    init = root.find("Storyboard/Init")
    if init is not None:
        for priv in init.iter("Private"):
            ent = priv.get("entityRef", "")
            for tp in priv.iter("TeleportAction"):
                x, y, h = wp(tp.find("Position"))
                rows.append((ent, cats.get(ent, ""), math.nan, x, y, h, "init"))
            for fta in priv.iter("FollowTrajectoryAction"):
                rows.extend(_vertex_rows(fta, [ent], cats, wp))
    for grp in root.iter("ManeuverGroup"):
        actors = [e.get("entityRef", "") for e in grp.iter("EntityRef")]
        for add in grp.iter("AddEntityAction"):
            x, y, h = wp(add.find("Position"))
            ent = _parent_entity_ref(grp, add) or (actors[0] if actors else "")
            rows.append((ent, cats.get(ent, ""), math.nan, x, y, h, "init"))
        for fta in grp.iter("FollowTrajectoryAction"):
            rows.extend(_vertex_rows(fta, actors, cats, wp))
    out = pd.DataFrame(
        rows, columns=["agent_id", "category", "t_s", "x_m", "y_m", "yaw_rad", "kind"]
    )
    return out.sort_values(["agent_id", "kind", "t_s"], kind="stable").reset_index(drop=True)


_GEO_REF = re.compile(
    rb"<geoReference>\s*<!\[CDATA\[(?P<proj>.*?)\]\]>\s*</geoReference>", re.DOTALL
)


def _tidy_geo_reference(xodr: Path) -> None:
    """Write the map's geoReference PROJ string on one line, without ``+no_defs``.

    netconvert writes it inside a CDATA block with surrounding newlines and a trailing
    ``+no_defs``; esmini splits the string on blanks and reports the empty token and
    ``+no_defs`` as unsupported attributes (two error lines per load). ``+no_defs`` is a
    no-op since PROJ 6 and CARLA reads only ``+lat_0`` / ``+lon_0``: the frame is unchanged.
    """
    data = xodr.read_bytes()
    m = _GEO_REF.search(data)
    if m is None:
        return
    tokens = [t for t in m["proj"].split() if t != b"+no_defs"]
    tidy = b"<geoReference><![CDATA[" + b" ".join(tokens) + b"]]></geoReference>"
    xodr.write_bytes(data[: m.start()] + tidy + data[m.end() :])


def _parent_entity_ref(scope, action) -> str | None:
    """The ``entityRef`` of the ``EntityAction`` holding ``action`` (searched in ``scope``)."""
    for ea in scope.iter("EntityAction"):
        if any(child is action for child in ea):
            return ea.get("entityRef")
    return None


def _vertex_rows(fta, actors, cats, wp) -> list[tuple]:
    """Rows (agent, category, t_s, x, y, yaw, 'vertex') of one FollowTrajectoryAction;
    t_s is NaN on a path without timing (``TimeReference/None``: vertex times, which
    1.0 requires, are ignored)."""
    out = []
    timed = fta.find("TimeReference/Timing") is not None
    for ent in actors:
        for vert in fta.iter("Vertex"):
            x, y, h = wp(vert.find("Position"))
            t = vert.get("time") if timed else None
            out.append(
                (ent, cats.get(ent, ""), math.nan if t is None else float(t), x, y, h, "vertex")
            )
    return out


def timeseries_to_trajectories(
    timeseries: pd.DataFrame, *, config: str | None = None, variant: int | None = None
) -> pd.DataFrame:
    """Rows of one run of a time series (TIMESERIES_COLUMNS) ready for the export.

    Keeps the rows of ``config`` (the only config if None) and ``variant`` (the config's
    only variant if None; a batch of several configs numbers its variants 0, 1, ...)
    where the agent is ``active``; returns columns t_s, agent_id, category, x_m, y_m,
    yaw_rad, speed_mps (and ``continuation`` where the time series has it). InputError if
    the choice is ambiguous or empty.
    """
    df = timeseries
    if "config" in df:
        names = list(dict.fromkeys(df["config"].astype(str)))
        if config is None:
            if len(names) != 1:
                raise InputError(
                    f"time series holds several configs ({', '.join(names)}): choose one",
                    field="config",
                )
            config = names[0]
        elif config not in names:
            raise InputError(
                f"config {config!r} not in the time series ({', '.join(names)})", field="config"
            )
        df = df[df["config"].astype(str) == config]
    if "variant" in df:
        variants = sorted(set(df["variant"].astype(int)))
        if variant is None:
            if len(variants) > 1:
                raise InputError(
                    f"time series holds several variants ({', '.join(map(str, variants))})"
                    " of this config: choose one",
                    field="variant",
                )
            variant = variants[0] if variants else 0
        elif variant not in variants:
            raise InputError(
                f"variant {variant} not in the time series ({', '.join(map(str, variants))})",
                field="variant",
            )
        df = df[df["variant"] == variant]
    if "active" in df:
        df = df[df["active"].astype(bool)]
    cols = ["t_s", "agent_id", "category", "x_m", "y_m", "yaw_rad", "speed_mps", "continuation"]
    return df[[c for c in cols if c in df]].reset_index(drop=True)
