"""OpenDRIVE from OSM, a SUMO network or an existing .xodr, in the scenario's tmerc plane.

The converter is SUMO ``netconvert`` (PyPI ``eclipse-sumo``), the tool CARLA's own OSM import
(``carla.Osm2Odr``) is built from, run with CARLA's option set (see
:data:`NETCONVERT_OSM_OPTIONS` and docs/maps.md) and ``--proj`` equal to
``LocalFrame(lat, lon).proj_string``: the OpenDRIVE ``geoReference`` and the scenario frame
are one plane (``--offset.disable-normalization`` keeps netconvert from shifting it).

Sources:

* ``.osm`` / ``.osm.gz`` (netconvert reads them); ``.osm.pbf`` / ``.osm.bz2`` are first
  converted to ``.osm`` XML with osmium (netconvert reads no PBF);
* a SUMO network ``.net.xml(.gz)`` (e.g. in UTM with a ``netOffset``) and an OpenDRIVE file
  in another frame are *re-projected*: netconvert writes them as plain XML in geographic
  coordinates (``--proj.plain-geo``, 9 decimals), then rebuilds them with the tmerc ``--proj``
  (checked numerically in the tests: nodes land within millimetres of their geodetic
  position). Pedestrian crossings are dropped on the way, because netconvert writes them as
  OpenDRIVE 1.5 ``outline`` objects that a 1.4 file may not hold;
* an ``.xodr`` already in the requested frame (or with no origin requested) is validated and
  copied unchanged.

``converter="carla"`` runs ``carla.Osm2Odr.convert`` of the carla 0.9.16 client package
instead (OSM sources only): the exact tool the paper used; its output is validated too and
the schema deviations reported.
"""

from __future__ import annotations

import contextlib
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from vei.errors import BackendError, ConfigError, DependencyError, InputError
from vei.geo import Bounds, LocalFrame
from vei.io.atomic import write_bytes
from vei.maps import safexml
from vei.maps.fetch import check_osm_xml, is_osm_path, osm_data_bounds

#: OSM highway types kept: CARLA's Osm2Odr default (vehicle roads; no service, footway, cycleway).
CARLA_WAY_TYPES: tuple[str, ...] = (
    "motorway",
    "motorway_link",
    "trunk",
    "trunk_link",
    "primary",
    "primary_link",
    "secondary",
    "secondary_link",
    "tertiary",
    "tertiary_link",
    "unclassified",
    "residential",
)
#: Lane width where OSM gives none [m]: CARLA's Osm2OdrSettings.default_lane_width.
DEFAULT_LANE_WIDTH_M = 3.35

#: netconvert options for OSM input (CARLA 0.9.16's Osm2Odr set, minus --osm.crossings; see docs/maps.md).
NETCONVERT_OSM_OPTIONS: tuple[str, ...] = (
    "--geometry.remove",  # merge geometry-only nodes: fewer, longer OpenDRIVE roads
    "--ramps.guess",  # add acceleration / deceleration lanes at motorway ramps
    "--edges.join",  # merge parallel edges connecting the same nodes
    "--junctions.join",  # one junction for clusters of close OSM nodes (dual carriageways)
    "--roundabouts.guess",  # roundabout right of way
    "--keep-edges.by-type",
    ",".join(f"highway.{t}" for t in CARLA_WAY_TYPES),
    "--tls.discard-simple",  # drop signals that are not at a junction (e.g. pedestrian lights)
    "--tls.join",  # one controller for the signals of one (joined) junction
    "--sidewalks.guess",  # sidewalk lanes beside urban roads (where riders may be)
    "--osm.sidewalks",  # ... and from OSM sidewalk=* tags
    "--default.lanewidth",
    f"{DEFAULT_LANE_WIDTH_M:g}",
    "--offset.disable-normalization",  # keep the tmerc origin: geoReference == scenario frame
)
#: Extra netconvert options when traffic lights are wanted (guess them from OSM signal nodes).
NETCONVERT_TLS_OPTIONS: tuple[str, ...] = ("--tls.guess-signals",)
#: Options that drop traffic lights (CARLA's generate_traffic_lights = False).
NETCONVERT_NO_TLS_OPTIONS: tuple[str, ...] = ("--tls.discard-loaded",)
#: Seconds netconvert may run per call.
NETCONVERT_TIMEOUT_S = 600.0

CONVERTERS = ("netconvert", "carla")


@dataclass(frozen=True)
class MapBuildResult:
    """What :func:`build_opendrive` wrote and how.

    Attributes:
        opendrive: the .xodr written.
        sumo_net: the SUMO .net.xml built alongside (netconvert only), else None.
        origin_lat_deg, origin_lon_deg: origin of the tmerc plane [deg].
        proj_string: the geoReference written (== LocalFrame(origin).proj_string).
        converter: 'netconvert', 'carla' or 'copy' (an .xodr re-used unchanged).
        source_kind: 'osm', 'sumo-net' or 'opendrive'.
        commands: the external commands run (argument lists), for the record.
        warnings: converter warnings (stderr lines starting with 'Warning').
        elapsed_s: wall time of the conversion [s].
    """

    opendrive: Path
    sumo_net: Path | None
    origin_lat_deg: float
    origin_lon_deg: float
    proj_string: str
    converter: str
    source_kind: str
    commands: tuple[tuple[str, ...], ...] = ()
    warnings: tuple[str, ...] = field(default=(), repr=False)
    elapsed_s: float = 0.0

    @property
    def frame(self) -> LocalFrame:
        """The plane of the map."""
        return LocalFrame(self.origin_lat_deg, self.origin_lon_deg)


def source_kind(path: str | Path) -> str:
    """'osm', 'sumo-net' or 'opendrive' from the file name; InputError otherwise."""
    name = Path(path).name.lower()
    if name.endswith((".net.xml", ".net.xml.gz")):
        return "sumo-net"
    if name.endswith(".xodr"):
        return "opendrive"
    if is_osm_path(name):
        return "osm"
    raise InputError(
        "map source must be .osm, .osm.gz, .osm.bz2, .osm.pbf, .net.xml(.gz) or .xodr", path=path
    )


def netconvert_binary() -> str:
    """Path of SUMO's netconvert (from PyPI eclipse-sumo via sumolib, else $SUMO_HOME/bin, else PATH)."""
    try:
        import sumolib

        exe = sumolib.checkBinary("netconvert")
    except ImportError:
        exe = "netconvert"
    if os.path.isabs(exe) and os.path.exists(exe):
        return exe
    found = shutil.which(exe)
    if found is None:
        raise DependencyError("SUMO netconvert not found: pip install 'vei[maps]' (eclipse-sumo)")
    return found


def _netconvert_env(exe: str) -> dict[str, str]:
    """Environment for netconvert: SUMO_HOME and the PROJ database of its bundled libproj."""
    env = dict(os.environ)
    home = Path(exe).resolve().parent.parent
    if (home / "data").is_dir():
        env.setdefault("SUMO_HOME", str(home))
        proj = home / "data" / "proj"
        if (proj / "proj.db").is_file():
            env["PROJ_LIB"] = str(proj)
            env["PROJ_DATA"] = str(proj)
    return env


def run_netconvert(
    args: list[str], *, timeout_s: float = NETCONVERT_TIMEOUT_S
) -> tuple[list[str], list[str]]:
    """Run netconvert with ``args``; returns (command, warning lines).

    Raises:
        BackendError: non-zero exit, crash or timeout, with the tail of netconvert's stderr.
    """
    exe = netconvert_binary()
    cmd = [exe, *args]
    try:
        proc = subprocess.run(
            cmd,
            capture_output=True,
            text=True,
            timeout=timeout_s,
            env=_netconvert_env(exe),
            check=False,
        )
    except subprocess.TimeoutExpired as exc:
        raise BackendError(f"netconvert did not finish within {timeout_s:g} s") from exc
    lines = (proc.stderr or "").splitlines() + (proc.stdout or "").splitlines()
    warnings = [ln for ln in lines if ln.startswith("Warning")]
    if proc.returncode != 0:
        errors = [ln for ln in lines if ln.startswith("Error")] or lines[-15:]
        if any("No edges loaded" in ln for ln in errors):
            raise InputError(
                "no road to convert: netconvert loaded no edge (no highway of the kept types in the region?)"
            )
        why = (
            f"crashed (signal {-proc.returncode})"
            if proc.returncode < 0
            else f"exit code {proc.returncode}"
        )
        if proc.returncode == 139:
            why = "crashed (segmentation fault)"
        raise BackendError(f"netconvert failed, {why}:\n" + "\n".join(errors[-15:]))
    return cmd, warnings


def _default_origin(src: Path, kind: str) -> tuple[float, float]:
    """Centre of the data's bounds: OSM header/node extent, SUMO origBoundary, xodr geoReference."""
    if kind == "osm":
        return osm_data_bounds(src).center
    if kind == "sumo-net":
        for elem in safexml.iter_elements(src, {"location"}):
            proj = elem.get("projParameter", "!")
            orig = elem.get("origBoundary", "")
            if proj == "!":
                raise InputError(
                    "the SUMO network has no geo-reference (projParameter '!')", path=src
                )
            vals = [float(v) for v in orig.split(",")]
            if len(vals) != 4:
                raise InputError(f"bad origBoundary {orig!r}", path=src, field="location")
            west, south, east, north = vals
            return Bounds(south, west, north, east).center
        raise InputError("the SUMO network has no <location> element", path=src)
    from vei.maps.validate import read_header

    _, _, geo = read_header(src)
    if geo is None:
        raise InputError("the OpenDRIVE file has no geoReference; give --origin", path=src)
    frame = LocalFrame.from_proj_string(geo)
    return frame.origin_lat_deg, frame.origin_lon_deg


def _to_osm_xml(src: Path, dst: Path) -> Path:
    """Convert a .pbf / .bz2 extract to plain .osm XML with osmium (netconvert reads neither)."""
    from vei.maps.fetch import _osmium

    osmium = _osmium()
    writer = osmium.SimpleWriter(osmium.io.File(str(dst), "osm"), overwrite=True)
    try:
        for obj in osmium.FileProcessor(str(src)):
            if obj.is_node():
                writer.add_node(obj)
            elif obj.is_way():
                writer.add_way(obj)
            elif obj.is_relation():
                writer.add_relation(obj)
    except RuntimeError as exc:
        raise InputError(f"cannot read OSM extract: {exc}", path=src) from exc
    finally:
        writer.close()
    return dst


_CROSSING = re.compile(r"<crossing\b[^>]*?/>|<crossing\b.*?</crossing>", re.S)


def _drop_crossings(con_file: Path) -> None:
    if con_file.is_file():
        text = con_file.read_text(encoding="utf-8")
        con_file.write_text(_CROSSING.sub("", text), encoding="utf-8")


def _geo_boundary_args(clip: Bounds | None) -> list[str]:
    if clip is None:
        return []
    return [
        "--keep-edges.in-geo-boundary",
        f"{clip.west_deg},{clip.south_deg},{clip.east_deg},{clip.north_deg}",
    ]


def build_opendrive(
    source: str | Path,
    out: str | Path,
    *,
    origin: tuple[float, float] | None = None,
    converter: str = "netconvert",
    traffic_lights: bool = False,
    clip: Bounds | None = None,
    sumo_net_out: str | Path | None = None,
    timeout_s: float = NETCONVERT_TIMEOUT_S,
) -> MapBuildResult:
    """Build an OpenDRIVE map in the tmerc plane centred on ``origin``.

    Args:
        source: .osm / .osm.gz / .osm.bz2 / .osm.pbf, SUMO .net.xml(.gz), or .xodr.
        out: the .xodr to write (atomically).
        origin: (lat_deg, lon_deg) of the plane; default: the centre of the data's bounds
            (OSM: header box or node extent; SUMO: origBoundary; xodr: its geoReference).
        converter: 'netconvert' (default) or 'carla' (carla.Osm2Odr, OSM sources only).
        traffic_lights: build traffic lights from OSM signal nodes (default off, like the
            paper's CARLA maps: the scenario replays recorded traffic, not signal phases).
        clip: keep only edges inside these bounds (netconvert ``--keep-edges.in-geo-boundary``);
            the OSM crop already limits the region, this is for large SUMO networks.
        sumo_net_out: also write netconvert's SUMO network here (default: beside ``out`` as
            ``<stem>.net.xml``; netconvert only).
        timeout_s: limit per netconvert call [s].
    Returns:
        A :class:`MapBuildResult`. Validation is separate: see :mod:`vei.maps.validate`.
    Raises:
        InputError (bad/unsafe source), ConfigError (converter), DependencyError (tool
        missing), BackendError (converter failed; its stderr included).
    """
    src = Path(source)
    out = Path(out)
    if converter not in CONVERTERS:
        raise ConfigError(f"converter must be one of {CONVERTERS}, got {converter!r}")
    if not src.is_file():
        raise InputError("map source not found", path=src)
    kind = source_kind(src)
    if kind == "osm":
        check_osm_xml(src)
    else:
        safexml.check_file(src)
    if converter == "carla" and kind != "osm":
        raise ConfigError("--converter carla converts OSM files only (carla.Osm2Odr)")
    lat, lon = origin if origin is not None else _default_origin(src, kind)
    frame = LocalFrame(float(lat), float(lon))
    t0 = time.perf_counter()

    if kind == "opendrive":
        from vei.maps.validate import read_header

        _, _, geo = read_header(src)
        same = False
        if geo is not None:
            try:
                have = LocalFrame.from_proj_string(geo)
                same = (
                    abs(have.origin_lat_deg - frame.origin_lat_deg) < 1e-9
                    and abs(have.origin_lon_deg - frame.origin_lon_deg) < 1e-9
                )
            except InputError:
                same = False
        if origin is None or same:
            write_bytes(out, src.read_bytes())
            return MapBuildResult(
                out,
                None,
                frame.origin_lat_deg,
                frame.origin_lon_deg,
                geo or frame.proj_string,
                "copy",
                kind,
                (),
                (),
                time.perf_counter() - t0,
            )
        if geo is None:
            raise InputError("cannot re-project an OpenDRIVE file without geoReference", path=src)

    net_out = (
        Path(sumo_net_out) if sumo_net_out is not None else out.with_name(out.stem + ".net.xml")
    )
    commands: list[tuple[str, ...]] = []
    warnings: list[str] = []
    with tempfile.TemporaryDirectory(prefix="vei-map-") as tmpdir:
        tmp = Path(tmpdir)
        xodr_tmp = tmp / "map.xodr"
        net_tmp = tmp / "map.net.xml"
        osm_input = src
        if kind == "osm" and (src.name.lower().endswith((".pbf", ".bz2"))):
            osm_input = _to_osm_xml(src, tmp / "source.osm")
        if converter == "carla":
            warnings += _carla_convert(osm_input, xodr_tmp, frame, traffic_lights=traffic_lights)
            commands.append(("carla.Osm2Odr.convert", frame.proj_string))
        elif kind == "osm":
            args = [
                "--osm-files", str(osm_input),
                "--proj", frame.proj_string,
                *NETCONVERT_OSM_OPTIONS,
                *(NETCONVERT_TLS_OPTIONS if traffic_lights else NETCONVERT_NO_TLS_OPTIONS),
                *_geo_boundary_args(clip),
                "--aggregate-warnings", "5",
                "--opendrive-output", str(xodr_tmp),
                "--output-file", str(net_tmp),
            ]  # fmt: skip
            cmd, warn = run_netconvert(args, timeout_s=timeout_s)
            commands.append(tuple(cmd))
            warnings += warn
        else:
            # Re-project: plain XML in lon/lat, then rebuild in the tmerc plane.
            load = ["--sumo-net-file" if kind == "sumo-net" else "--opendrive-files", str(src)]
            if kind == "opendrive":
                # netconvert's own OpenDRIVE schema rejects the CDATA geoReference that it writes
                # itself; the file was already checked by safexml (and is validated after).
                load += ["--xml-validation", "never"]
            prefix = tmp / "plain"
            cmd, warn = run_netconvert(
                [*load, *_geo_boundary_args(clip), "--plain-output-prefix", str(prefix),
                 "--proj.plain-geo", "--precision.geo", "9", "--aggregate-warnings", "5"],
                timeout_s=timeout_s,
            )  # fmt: skip
            commands.append(tuple(cmd))
            warnings += warn
            _drop_crossings(Path(f"{prefix}.con.xml"))
            args = []
            for opt, suffix in (
                ("-n", "nod"),
                ("-e", "edg"),
                ("-x", "con"),
                ("-i", "tll"),
                ("-t", "typ"),
            ):
                f = Path(f"{prefix}.{suffix}.xml")
                if f.is_file():
                    args += [opt, str(f)]
            args += [
                "--xml-validation", "never",  # netconvert's own plain output, written just now
                "--proj", frame.proj_string,
                "--offset.disable-normalization",
                *([] if traffic_lights else NETCONVERT_NO_TLS_OPTIONS),
                "--aggregate-warnings", "5",
                "--opendrive-output", str(xodr_tmp),
                "--output-file", str(net_tmp),
            ]  # fmt: skip
            cmd, warn = run_netconvert(args, timeout_s=timeout_s)
            commands.append(tuple(cmd))
            warnings += warn
        if not xodr_tmp.is_file() or xodr_tmp.stat().st_size == 0:
            raise BackendError(f"{converter} wrote no OpenDRIVE output for {src}")
        root_tag = safexml.check_file(xodr_tmp)
        if root_tag != "OpenDRIVE":
            raise BackendError(f"{converter} output is not OpenDRIVE (root <{root_tag}>)")
        if sum(1 for _ in safexml.iter_elements(xodr_tmp, {"road"})) == 0:
            raise InputError(
                "the map has no road after conversion (no highway of the kept types in the region?)",
                path=src,
            )
        write_bytes(out, xodr_tmp.read_bytes())
        net_written: Path | None = None
        if net_tmp.is_file():
            write_bytes(net_out, net_tmp.read_bytes())
            net_written = net_out
    return MapBuildResult(
        out,
        net_written,
        frame.origin_lat_deg,
        frame.origin_lon_deg,
        frame.proj_string,
        converter,
        kind,
        tuple(commands),
        tuple(warnings),
        time.perf_counter() - t0,
    )


def _carla_convert(osm: Path, out: Path, frame: LocalFrame, *, traffic_lights: bool) -> list[str]:
    """carla.Osm2Odr.convert with the plane's proj string, no centring, CARLA's way types.

    Returns the converter's warning lines (captured from the native stdout/stderr)."""
    try:
        import carla
    except ImportError as exc:
        raise DependencyError(
            "--converter carla needs the carla client package: pip install 'vei[carla]'"
        ) from exc
    settings = carla.Osm2OdrSettings()
    settings.proj_string = frame.proj_string
    settings.center_map = False  # keep the origin: the geoReference is written only uncentred
    settings.use_offsets = False
    settings.generate_traffic_lights = bool(traffic_lights)
    settings.all_junctions_with_traffic_lights = False
    settings.default_lane_width = DEFAULT_LANE_WIDTH_M
    settings.set_osm_way_types(list(CARLA_WAY_TYPES))
    text = osm.read_text(encoding="utf-8")
    with _captured_fds() as captured:
        try:
            xodr = carla.Osm2Odr.convert(text, settings)
        except RuntimeError as exc:
            raise BackendError(f"carla.Osm2Odr.convert failed: {exc}") from exc
    if not xodr:
        raise BackendError("carla.Osm2Odr.convert returned nothing")
    out.write_text(xodr, encoding="utf-8")
    return [ln for ln in captured if ln.startswith("Warning")]


@contextlib.contextmanager
def _captured_fds() -> Iterator[list[str]]:
    """Capture what native code writes to file descriptors 1 and 2 (the lines, after exit)."""
    lines: list[str] = []
    sys.stdout.flush()
    sys.stderr.flush()
    with tempfile.TemporaryFile() as sink:
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            yield lines
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            for fd in saved:
                os.close(fd)
            sink.seek(0)
            lines.extend(sink.read().decode("utf-8", "replace").splitlines())
