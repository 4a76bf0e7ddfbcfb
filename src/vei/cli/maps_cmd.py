"""``vei map fetch`` and ``vei map build``: OpenStreetMap region -> .osm -> OpenDRIVE.

Heavy work (osmium, netconvert, carla, xmlschema) is imported inside the commands.
"""

from __future__ import annotations

import contextlib
import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated

import typer

from vei.errors import InputError


def _parse_floats(text: str, n: int, option: str) -> list[float]:
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != n:
        raise InputError(
            f"{option} expects {n} comma-separated numbers, got {text!r}", field=option
        )
    try:
        return [float(p) for p in parts]
    except ValueError as exc:
        raise InputError(f"{option} expects numbers, got {text!r}", field=option) from exc


def _bounds_from_options(
    bbox: str | None, interaction: Path | None, scenario: Path | None, margin_m: float
):
    from vei.geo import Bounds

    given = [x is not None for x in (bbox, interaction, scenario)]
    if sum(given) != 1:
        raise InputError("give exactly one of --bbox, --interaction, --scenario")
    if bbox is not None:
        s, w, n, e = _parse_floats(bbox, 4, "--bbox")
        return Bounds(s, w, n, e)
    if interaction is not None:
        from vei.io.interaction import read_interaction

        inter = read_interaction(interaction)
        return Bounds.around(
            inter.ego["lat_deg"].to_numpy(), inter.ego["lon_deg"].to_numpy(), margin_m=margin_m
        )
    assert scenario is not None
    path = scenario / "scenario.json" if scenario.is_dir() else scenario
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise InputError(f"cannot read scenario: {exc}", path=path) from exc
    except json.JSONDecodeError as exc:
        raise InputError(f"invalid JSON: {exc}", path=path) from exc
    b = doc.get("bounds") if isinstance(doc, dict) else None
    keys = ("south_deg", "west_deg", "north_deg", "east_deg")
    if not isinstance(b, dict) or any(k not in b for k in keys):
        raise InputError(
            f"scenario.json needs 'bounds' with {', '.join(keys)}", path=path, field="bounds"
        )
    try:
        return Bounds(*(float(b[k]) for k in keys))
    except (TypeError, ValueError) as exc:
        raise InputError(f"bounds must be numbers: {exc}", path=path, field="bounds") from exc


@contextlib.contextmanager
def _status(message: str) -> Iterator[None]:
    """A rich spinner on stderr while external tools run (only when stderr is a terminal)."""
    if not sys.stderr.isatty():
        yield
        return
    from vei.cli.output import console

    with console(stderr=True).status(message):
        yield


def register(app: typer.Typer) -> None:
    """Add ``vei map fetch`` and ``vei map build``."""
    map_app = typer.Typer(
        help="Road maps: fetch an OpenStreetMap region, build OpenDRIVE that CARLA loads.",
        no_args_is_help=True,
    )

    @map_app.command("fetch")
    def fetch(
        out: Annotated[Path, typer.Option("--out", help="Output OSM XML file (e.g. map.osm).")],
        bbox: Annotated[
            str | None,
            typer.Option("--bbox", help="Region as S,W,N,E in degrees (south, west, north, east)."),
        ] = None,
        interaction: Annotated[
            Path | None,
            typer.Option(
                "--interaction", help="Interaction folder: the region around its ego GPS track."
            ),
        ] = None,
        scenario: Annotated[
            Path | None,
            typer.Option("--scenario", help="Scenario folder (or scenario.json): its 'bounds'."),
        ] = None,
        source: Annotated[
            str,
            typer.Option(
                "--source",
                help="'overpass', a local extract (.osm, .osm.gz, .osm.bz2, .osm.pbf) to crop, or 'auto' "
                "($VEI_OSM_SOURCE, else overpass).",
            ),
        ] = "auto",
        margin_m: Annotated[
            float,
            typer.Option(
                "--margin-m", help="With --interaction: margin around the ego track, in metres."
            ),
        ] = 100.0,
        overpass_url: Annotated[
            str | None,
            typer.Option(
                "--overpass-url",
                help="Overpass API endpoint (default $VEI_OVERPASS_URL or overpass-api.de).",
            ),
        ] = None,
        timeout_s: Annotated[
            float, typer.Option("--timeout-s", help="Overpass request timeout, in seconds.")
        ] = 90.0,
        retries: Annotated[
            int,
            typer.Option("--retries", help="Overpass retries on HTTP 429/5xx and network errors."),
        ] = 3,
    ) -> None:
        """Get the OSM road network of a region into an .osm file (crop keeps complete ways)."""
        from vei.maps.attach import MapConfig, resolve_source
        from vei.maps.fetch import fetch_osm

        bounds = _bounds_from_options(bbox, interaction, scenario, margin_m)
        cfg = MapConfig.from_env(**({"overpass_url": overpass_url} if overpass_url else {}))
        resolved = resolve_source(source)
        fetch_osm(
            bounds,
            out,
            source=resolved,
            overpass_url=cfg.overpass_url,
            timeout_s=timeout_s,
            retries=retries,
        )
        from vei.maps import safexml

        counts = {"node": 0, "way": 0, "relation": 0}
        for elem in safexml.iter_elements(out, set(counts)):
            counts[elem.tag] += 1
        typer.echo(
            f"wrote {out}: {counts['way']} ways, {counts['node']} nodes, {counts['relation']} relations "
            f"(source {resolved}, bbox {bounds.as_sw_ne()})"
        )

    @map_app.command("build")
    def build(
        source: Annotated[
            Path,
            typer.Argument(
                help="An .osm/.osm.gz/.osm.bz2/.osm.pbf, a SUMO .net.xml(.gz) or an .xodr."
            ),
        ],
        out: Annotated[Path, typer.Option("--out", help="Output OpenDRIVE file (e.g. map.xodr).")],
        origin: Annotated[
            str | None,
            typer.Option(
                "--origin",
                help="LAT,LON of the tmerc plane's origin in degrees (the scenario origin); default: centre of the data.",
            ),
        ] = None,
        converter: Annotated[
            str,
            typer.Option(
                "--converter",
                help="'netconvert' (SUMO, default) or 'carla' (carla.Osm2Odr, OSM sources only).",
            ),
        ] = "netconvert",
        traffic_lights: Annotated[
            bool,
            typer.Option(
                "--traffic-lights/--no-traffic-lights",
                help="Build traffic lights from OSM signal nodes.",
            ),
        ] = False,
        carla_check: Annotated[
            bool,
            typer.Option(
                "--carla-check/--no-carla-check",
                help="Load the result in carla.Map offline and count waypoints.",
            ),
        ] = True,
        strict: Annotated[
            bool,
            typer.Option(
                "--strict", help="Exit with an error when the OpenDRIVE output violates the XSD."
            ),
        ] = False,
    ) -> None:
        """Convert SOURCE to OpenDRIVE in a tmerc plane; validate against the XSD; check in CARLA."""
        from vei.errors import DependencyError
        from vei.maps.build import build_opendrive
        from vei.maps.validate import carla_check as run_carla_check
        from vei.maps.validate import validate_opendrive

        org = None
        if origin is not None:
            lat, lon = _parse_floats(origin, 2, "--origin")
            org = (lat, lon)
        result = build_opendrive(
            source, out, origin=org, converter=converter, traffic_lights=traffic_lights
        )
        typer.echo(
            f"wrote {result.opendrive} ({result.converter}, {result.elapsed_s:.2f} s; "
            f"{len(result.warnings)} converter warnings)"
        )
        if result.sumo_net is not None:
            typer.echo(f"wrote {result.sumo_net} (SUMO network of the same map)")
        typer.echo(f"geoReference: {result.proj_string}")
        with _status("validating against the OpenDRIVE XSD ..."):
            report = validate_opendrive(result.opendrive)
        if report.valid:
            typer.echo(
                f"XSD: valid OpenDRIVE {report.version} ({report.schema}, {report.validator})"
            )
        else:
            typer.echo(
                f"XSD: {len(report.issues)} violation(s) of OpenDRIVE {report.version} ({report.schema}):"
            )
            for what, count in list(report.summary().items())[:10]:
                typer.echo(f"  {count} x {what}")
        if carla_check:
            try:
                with _status("loading the map in carla.Map ..."):
                    info = run_carla_check(result.opendrive)
            except DependencyError as exc:
                typer.echo(f"CARLA check skipped: {exc}")
            else:
                typer.echo(
                    f"CARLA: map loads; {info['waypoints']} waypoints (2 m) on {info['lanes']} lanes of "
                    f"{info['roads']} roads; origin {info['origin_lat_deg']:.7f}, {info['origin_lon_deg']:.7f}"
                )
        if strict and not report.valid:
            raise InputError(
                f"OpenDRIVE output violates the XSD ({len(report.issues)} issue(s))",
                path=result.opendrive,
            )

    app.add_typer(map_app, name="map")
