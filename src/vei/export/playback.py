"""Play an OpenSCENARIO file in esmini (headless) and compare what it played with the file.

The player really runs: ``bin/esmini --headless --osc FILE --fixed_timestep DT --record
run.dat --collision --disable_stdout --logfile_path LOG`` in a work folder, then
``bin/dat2csv`` turns the recording into one row per entity per step. The comparison, per
entity of the file:

- **deviation**: each recorded frame inside the entity's timed trajectory (first to last
  vertex time) against the file's own vertices, linearly interpolated in time [m]; an
  entity whose path has no timing (a simulator-driven ego) is compared with its path (the
  distance from the polyline);
- **presence**: frames recorded outside the entity's own span count as *outside*: the
  span of its timed trajectory (first to last vertex time), so that standing before its
  trajectory begins or after it ends is caught; for an entity without timed trajectory
  the window the file gives it (from 0 when placed in Init, else from its
  ``AddEntityAction``'s condition time, to the step that deletes it, else to the end).
  Steps of the span in which it is missing count as *missing* (esmini evaluates triggers
  before it advances its clock, so an entity added at step T is first recorded at
  T + dt: that one frame is not counted);
- **collisions**: esmini's ``--collision`` reports each new overlap of two bounding boxes
  as a log line ``[t] [warn] Collision between A and B`` (and ``... dissolved`` when it
  ends); every pair is kept with the time it first touched;
- **log**: size in bytes; warnings and errors other than collision lines. Warnings that
  come from the installation and not from the file are kept apart: a headless esmini
  without its ``resources`` folder has no 3D models and no traffic-sign table, so a
  vehicle without ``model3d`` (OpenSCENARIO 1.0 cannot say "no model") makes it warn that
  its default model is missing, and a map with signals makes it warn that
  ``opendrive_traffic_signals.txt`` is missing; a file without a road network makes it
  warn ``No OpenDRIVE file specified``.
"""

from __future__ import annotations

import math
import re
import subprocess
import tempfile
import time
from dataclasses import dataclass, field, fields
from pathlib import Path

import numpy as np
import pandas as pd

from vei.errors import ConfigError, DependencyError, InputError
from vei.esmini import Esmini, find_esmini

#: Default player step [s] (vei's own simulation step).
DEFAULT_DT_S = 0.05
#: Acceptance bounds of a playback (the issue's must-show): per entity [m].
MAX_MEDIAN_DEVIATION_M = 0.05
MAX_DEVIATION_M = 0.3
#: A log larger than this is an issue of its own [bytes] (a healthy 60 s export: ~ 20 kB).
MAX_LOG_BYTES = 1_000_000
#: Tolerance [s] on frame times when testing presence windows.
TIME_TOL_S = 1e-6

_LINE = re.compile(r"^\[(?P<t>[0-9.]*)\]\s*\[(?P<level>[a-z]+)\]\s*(?P<msg>.*)$")
_COLLISION = re.compile(r"^Collision between (?P<a>.+?) and (?P<b>.+?)( dissolved)?$")
#: Messages that come from the installation / the absence of a map, not from the file.
_ASSET = re.compile(r"^(3D model|scene graph file|Traffic sign mapping file) .* not located")
_NO_MAP = re.compile(r"^No OpenDRIVE file specified")


@dataclass(frozen=True)
class LogSummary:
    """What esmini's log says.

    Attributes:
        warnings: warning lines caused by the file (not collisions, not assets / no map).
        errors: error lines.
        install_warnings: missing 3D model / traffic-sign table (the installation's
            resources, not the file).
        no_map: the file names no OpenDRIVE map.
        collisions: (time [s], name a, name b) of every new contact, a < b.
    """

    warnings: tuple[str, ...]
    errors: tuple[str, ...]
    install_warnings: tuple[str, ...]
    no_map: bool
    collisions: tuple[tuple[float, str, str], ...]


def parse_esmini_log(text: str) -> LogSummary:
    """Sort the lines of an esmini log into warnings, errors, asset notes and collisions."""
    warnings, errors, assets, colls = [], [], [], []
    no_map = False
    for line in text.splitlines():
        m = _LINE.match(line.strip())
        if m is None:
            continue
        level, msg = m["level"], m["msg"].strip()
        if level not in ("warn", "error"):
            continue
        c = _COLLISION.match(msg)
        if c is not None:
            if not msg.endswith("dissolved"):
                a, b = sorted((c["a"], c["b"]))
                colls.append((float(m["t"]) if m["t"] else 0.0, a, b))
            continue
        if _ASSET.match(msg):
            assets.append(line.strip())
        elif _NO_MAP.match(msg):
            no_map = True
        elif level == "warn":
            warnings.append(line.strip())
        else:
            errors.append(line.strip())
    return LogSummary(tuple(warnings), tuple(errors), tuple(assets), no_map, tuple(colls))


@dataclass(frozen=True)
class FileEntity:
    """One entity as the file defines it.

    Attributes:
        name: the ScenarioObject name.
        vertices: [K, 4] (t [s] or NaN, x, y, h) of its trajectory (empty: none).
        timed: the trajectory has vertex times.
        start_s: from when it may exist [s]: 0 when placed in Init, else the time its
            AddEntityAction's condition names (it fires at the first step past it).
        end_s: the time its DeleteEntityAction's condition names [s] (inf: never): it is
            deleted at the first step T past it, recorded last at T.
    """

    name: str
    vertices: np.ndarray
    timed: bool
    start_s: float
    end_s: float


def _cond_time(event) -> float:
    """The SimulationTimeCondition value of an event's start trigger [s] (inf if none)."""
    cond = event.find("StartTrigger//SimulationTimeCondition")
    return math.inf if cond is None else float(cond.get("value"))


def read_file_entities(xosc: str | Path) -> dict[str, FileEntity]:
    """The entities of an OpenSCENARIO file with their trajectories and presence windows.

    Trajectory vertices are read where every position is a WorldPosition (what vei
    writes); in other files the entities get no vertices (nothing to compare, presence
    and log are still checked). Raises InputError if the file is not readable XML.
    """
    from defusedxml import ElementTree as SafeET

    from vei.export.openscenario import read_openscenario_trajectories

    xosc = Path(xosc)
    try:
        back = read_openscenario_trajectories(xosc)
    except InputError:  # positions other than WorldPosition (not a vei file): no vertices
        back = pd.DataFrame(columns=["agent_id", "kind", "t_s", "x_m", "y_m", "yaw_rad"])
    try:
        root = SafeET.parse(xosc).getroot()
    except Exception as exc:  # ParseError, DefusedXmlException, OSError
        raise InputError(f"not a readable OpenSCENARIO file: {exc}", path=xosc) from exc
    names = [o.get("name", "") for o in root.iter("ScenarioObject")]
    in_init = set()
    init = root.find("Storyboard/Init")
    if init is not None:
        in_init = {p.get("entityRef", "") for p in init.iter("Private")}
    starts: dict[str, float] = {}
    ends: dict[str, float] = {}
    for ev in root.iter("Event"):
        for ea in ev.iter("EntityAction"):
            ref = ea.get("entityRef", "")
            if ea.find("AddEntityAction") is not None:
                starts[ref] = min(starts.get(ref, math.inf), _cond_time(ev))
            if ea.find("DeleteEntityAction") is not None:
                ends[ref] = min(ends.get(ref, math.inf), _cond_time(ev))
    out = {}
    for name in names:
        vx = back[(back["agent_id"] == name) & (back["kind"] == "vertex")]
        verts = vx[["t_s", "x_m", "y_m", "yaw_rad"]].to_numpy(dtype=float)
        timed = bool(len(verts)) and bool(np.isfinite(verts[:, 0]).all())
        if timed:
            verts = verts[np.argsort(verts[:, 0], kind="stable")]
        start = 0.0 if name in in_init else starts.get(name, math.inf)
        out[name] = FileEntity(name, verts, timed, start, ends.get(name, math.inf))
    return out


@dataclass(frozen=True)
class EntityCheck:
    """The playback of one entity against the file.

    Attributes:
        name: entity name.
        frames: recorded frames of the entity.
        compared: frames compared with the trajectory (inside its timed span, or all for a
            path without timing).
        median_dev_m, max_dev_m: deviation from the file's vertices [m] (NaN: nothing
            compared).
        outside: frames recorded outside its span (module doc).
        missing: steps of its span in which it was not recorded (module doc).
        first_s, last_s: first / last recorded time [s] (NaN: never recorded).
    """

    name: str
    frames: int
    compared: int
    median_dev_m: float
    max_dev_m: float
    outside: int
    missing: int
    first_s: float
    last_s: float


@dataclass(frozen=True)
class PlaybackReport:
    """The outcome of playing one file in esmini.

    Attributes:
        xosc: the played file.
        dt_s: player step [s].
        returncode: esmini's exit status.
        wall_s: wall time of the esmini process [s].
        log_path, log_bytes: esmini's log and its size.
        log: the sorted log (warnings, errors, collisions).
        entities: one check per entity of the file, in file order (empty when esmini
            could not load the file).
        frames: the recording (dat2csv): time, id, name, x, y, h, speed, ... per step.
    """

    xosc: Path
    dt_s: float
    returncode: int
    wall_s: float
    log_path: Path
    log_bytes: int
    log: LogSummary
    entities: tuple[EntityCheck, ...]
    frames: pd.DataFrame = field(repr=False)

    def collision_pairs(self, involving: str | None = None) -> set[frozenset[str]]:
        """Pairs of entity names that touched (optionally only pairs with ``involving``)."""
        pairs = {frozenset((a, b)) for _, a, b in self.log.collisions}
        if involving is not None:
            pairs = {p for p in pairs if involving in p}
        return pairs

    def issues(
        self,
        *,
        max_median_m: float = MAX_MEDIAN_DEVIATION_M,
        max_m: float = MAX_DEVIATION_M,
        max_log_bytes: int = MAX_LOG_BYTES,
    ) -> list[str]:
        """Every way the playback differs from the file ([] when it plays as written)."""
        out = []
        if self.returncode != 0:
            what = "played" if self.entities else "could not play the file"
            out.append(f"esmini {what}: exit status {self.returncode}")
        if self.log_bytes > max_log_bytes:
            out.append(f"esmini's log is {self.log_bytes} bytes (> {max_log_bytes})")
        out.extend(f"esmini warning: {w}" for w in self.log.warnings)
        out.extend(f"esmini error: {e}" for e in self.log.errors)
        for e in self.entities:
            if e.compared and not (e.median_dev_m < max_median_m and e.max_dev_m < max_m):
                out.append(
                    f"{e.name}: played {e.median_dev_m:.3f} m median / {e.max_dev_m:.3f} m max "
                    f"from the file's trajectory (bounds {max_median_m:g} / {max_m:g} m)"
                )
            if e.outside:
                out.append(f"{e.name}: present in {e.outside} frame(s) outside its span")
            if e.missing:
                out.append(f"{e.name}: missing in {e.missing} frame(s) of its span")
        return out

    def table(self) -> pd.DataFrame:
        """One row per entity: frames, compared, median/max deviation, outside, missing."""
        cols = [f.name for f in fields(EntityCheck)]
        return pd.DataFrame([[getattr(e, c) for c in cols] for e in self.entities], columns=cols)


def _seg_dist(p: np.ndarray, path: np.ndarray) -> np.ndarray:
    """[N] distance [m] from points p [N, 2] to the polyline path [K, 2]."""
    if len(path) == 1:
        return np.hypot(*(p - path[0]).T)
    a, b = path[:-1], path[1:]
    ab = b - a
    ll = np.maximum((ab * ab).sum(axis=1), 1e-12)
    ap = p[:, None, :] - a[None, :, :]
    w = np.clip((ap * ab[None]).sum(axis=2) / ll[None], 0.0, 1.0)
    d = ap - w[..., None] * ab[None]
    return np.sqrt((d * d).sum(axis=2)).min(axis=1)


def compare_playback(
    frames: pd.DataFrame, entities: dict[str, FileEntity], dt_s: float, t_last_s: float
) -> tuple[EntityCheck, ...]:
    """Check every file entity's recorded frames (see the module doc).

    Args:
        frames: dat2csv rows (columns time, name, x, y at least).
        entities: :func:`read_file_entities`.
        dt_s: player step [s].
        t_last_s: last recorded time of the run [s].
    """
    grid = np.round(np.arange(0.0, t_last_s + dt_s / 2, dt_s), 9)
    out = []
    for name, ent in entities.items():
        f = frames[frames["name"] == name]
        t = f["time"].to_numpy(dtype=float)
        xy = f[["x", "y"]].to_numpy(dtype=float)
        dev = np.zeros(0)
        if ent.timed and len(ent.vertices):
            vt = ent.vertices[:, 0]
            sel = (t >= vt[0] - TIME_TOL_S) & (t <= vt[-1] + TIME_TOL_S)
            if len(vt) == 1:
                ref = np.repeat(ent.vertices[:, 1:3], int(sel.sum()), axis=0)
            else:
                ref = np.stack(
                    [
                        np.interp(t[sel], vt, ent.vertices[:, 1]),
                        np.interp(t[sel], vt, ent.vertices[:, 2]),
                    ],
                    axis=1,
                )
            dev = np.hypot(*(xy[sel] - ref).T)
        elif len(ent.vertices):
            dev = _seg_dist(xy, ent.vertices[:, 1:3])
        if ent.timed and len(ent.vertices):
            # the entity's own span: its timed trajectory, first to last vertex
            lo, hi = float(ent.vertices[0, 0]), float(ent.vertices[-1, 0])
        else:
            # the file's window: Init / AddEntityAction to the step that deletes it
            lo, hi = ent.start_s, ent.end_s + dt_s - 2 * TIME_TOL_S
        outside = int(((t < lo - TIME_TOL_S) | (t > hi + TIME_TOL_S)).sum())
        window = grid[(grid >= lo - TIME_TOL_S) & (grid <= hi + TIME_TOL_S)]
        if ent.start_s > TIME_TOL_S and window.size:  # added by a trigger: recorded from
            window = window[1:]  # the step after the one that adds it (esmini's order)
        seen = set(np.round(t, 6).tolist())
        missing = int(sum(round(float(w), 6) not in seen for w in window))
        out.append(
            EntityCheck(
                name=name,
                frames=int(len(t)),
                compared=int(dev.size),
                median_dev_m=float(np.median(dev)) if dev.size else math.nan,
                max_dev_m=float(dev.max()) if dev.size else math.nan,
                outside=outside,
                missing=missing,
                first_s=float(t.min()) if t.size else math.nan,
                last_s=float(t.max()) if t.size else math.nan,
            )
        )
    return tuple(out)


def play_xosc(
    xosc: str | Path,
    *,
    esmini: Esmini | str | Path | None = None,
    dt_s: float = DEFAULT_DT_S,
    work_dir: str | Path | None = None,
    timeout_s: float = 300.0,
) -> PlaybackReport:
    """Play ``xosc`` headless in esmini and compare the recording with the file.

    Args:
        xosc: the OpenSCENARIO file (its LogicFile resolves against its folder).
        esmini: an :class:`vei.esmini.Esmini`, its folder, or None (``find_esmini()``).
        dt_s: fixed player step [s] (> 0).
        work_dir: folder for run.dat, run.csv and esmini.log (kept); None: a temporary
            folder removed afterwards (the report's ``log_path`` then no longer exists).
        timeout_s: wall-clock limit of each esmini process [s].

    Returns:
        The :class:`PlaybackReport`.

        A file esmini refuses to load gives a report with a non-zero ``returncode``, no
        entity checks and the log's errors (``issues()`` lists them).

    Raises:
        InputError: the file does not exist or cannot be read. DependencyError: no esmini,
        esmini ran past ``timeout_s``, or dat2csv failed.
    """
    if not (dt_s > 0 and math.isfinite(dt_s)):
        raise ConfigError(f"dt_s must be > 0 s, got {dt_s!r}")
    xosc = Path(xosc).resolve()
    if not xosc.is_file():
        raise InputError("file not found", path=xosc)
    tool = esmini if isinstance(esmini, Esmini) else find_esmini(esmini)
    player, dat2csv = tool.require_player(), tool.require_dat2csv()
    entities = read_file_entities(xosc)
    if work_dir is None:
        with tempfile.TemporaryDirectory(prefix="vei-esmini-") as tmp:
            return _play(xosc, player, dat2csv, entities, dt_s, Path(tmp), timeout_s)
    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    return _play(xosc, player, dat2csv, entities, dt_s, work, timeout_s)


def _play(xosc, player, dat2csv, entities, dt_s, work: Path, timeout_s) -> PlaybackReport:
    dat, csv, log = work / "run.dat", work / "run.csv", work / "esmini.log"
    for p in (dat, csv, log):
        p.unlink(missing_ok=True)
    cmd = [str(player), "--headless", "--osc", str(xosc), "--fixed_timestep", f"{dt_s:g}",
           "--record", str(dat), "--collision", "--disable_stdout",
           "--logfile_path", str(log)]  # fmt: skip
    t0 = time.perf_counter()
    try:
        proc = subprocess.run(
            cmd, cwd=work, capture_output=True, text=True, timeout=timeout_s, check=False
        )
    except subprocess.TimeoutExpired as exc:
        raise DependencyError(f"esmini did not finish {xosc.name} within {timeout_s:g} s") from exc
    wall = time.perf_counter() - t0
    text = log.read_text(encoding="utf-8", errors="replace") if log.is_file() else ""
    summary = parse_esmini_log(text)
    log_bytes = log.stat().st_size if log.is_file() else 0
    if not dat.is_file():  # esmini refused the file: its log says why
        return PlaybackReport(
            xosc=xosc, dt_s=dt_s, returncode=proc.returncode or -1, wall_s=wall,
            log_path=log, log_bytes=log_bytes, log=summary, entities=(),
            frames=pd.DataFrame(columns=["time", "id", "name", "x", "y", "h", "speed"]),
        )  # fmt: skip
    try:
        conv = subprocess.run(
            [str(dat2csv), "--file", str(dat), "--csv", str(csv), "--precision", "6"],
            cwd=work, capture_output=True, text=True, timeout=timeout_s, check=False,
        )  # fmt: skip
    except subprocess.TimeoutExpired as exc:
        raise DependencyError(f"dat2csv did not finish {dat} within {timeout_s:g} s") from exc
    if conv.returncode != 0 or not csv.is_file():
        raise DependencyError(f"dat2csv failed on {dat} (exit status {conv.returncode})")
    frames = pd.read_csv(csv, skipinitialspace=True)
    frames.columns = [c.strip() for c in frames.columns]
    frames["name"] = frames["name"].astype(str).str.strip()
    t_last = float(frames["time"].max()) if len(frames) else 0.0
    checks = compare_playback(frames, entities, dt_s, t_last)
    return PlaybackReport(
        xosc=xosc,
        dt_s=dt_s,
        returncode=proc.returncode,
        wall_s=wall,
        log_path=log,
        log_bytes=log_bytes,
        log=summary,
        entities=checks,
        frames=frames,
    )
