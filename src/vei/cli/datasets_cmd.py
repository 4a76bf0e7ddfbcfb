"""``vei import trafficmonitoring`` and ``vei datasets download trafficmonitoring``.

- ``vei import trafficmonitoring --root DIR --scenario NAME --out DIR [--rate-hz 1]``
  writes an interaction folder (format vei.interaction/1) from the public TrafficMonitoring
  dataset and prints a summary (tracks per category, durations, time offsets, and how well
  the car's own camera track agrees with its INS); ``--list`` lists the scenarios of a root.
- ``vei datasets download trafficmonitoring [--dest DIR] [--scenario NAME ...]``
  fetches only the files the importer needs (resumable).
- ``vei import tracks --format ind|sind|av2 --root DIR --out DIR [--ego all|ID]`` writes
  world-frame interaction folders from drone / infrastructure / fleet track datasets, any
  car as the ego (docs/datasets.md).
"""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

#: Default destination of the download, so that VEI_DATA_DIR=data finds it.
DEFAULT_DOWNLOAD_DEST = Path("data") / "trafficmonitoring"


def _import_trafficmonitoring(
    root: Annotated[
        Path,
        typer.Option(
            "--root",
            help="Dataset root: the folder that holds data/measurements "
            "(e.g. what `vei datasets download trafficmonitoring` wrote).",
        ),
    ],
    scenario: Annotated[
        str | None,
        typer.Option(
            "--scenario", help="Scenario name (see --list), e.g. stadtmitte_12_audi_geradeaus_03."
        ),
    ] = None,
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Interaction folder to write (replaced if it exists)."),
    ] = None,
    rate_hz: Annotated[
        float,
        typer.Option(
            "--rate-hz", help="Annotation rate in Hz (the paper annotates at 1 FPS); at most 30."
        ),
    ] = 1.0,
    list_: Annotated[
        bool,
        typer.Option("--list", help="List the scenarios found under --root and exit."),
    ] = False,
    include_ego_track: Annotated[
        bool,
        typer.Option(
            "--include-ego-track",
            help="Also annotate the car's own camera track (category 'vehicle'): a check of time sync and geodesy.",
        ),
    ] = False,
    full_ins: Annotated[
        bool,
        typer.Option(
            "--full-ins",
            help="Keep the whole INS record as the ego track (default: cut to the span the camera covers).",
        ),
    ] = False,
    road_users: Annotated[
        str,
        typer.Option(
            "--road-users",
            help="'riders' (e-scooters and cyclists, the paper's annotations) or 'all' (also "
            "the vehicles and pedestrians the camera tracked: occluders for perception and V2X, "
            "the road users that react: case traffic settings).",
        ),
    ] = "riders",
) -> None:
    """Import a TrafficMonitoring scenario (Ingolstadt) as an interaction folder."""
    from vei.datasets.trafficmonitoring import import_scenario_with_summary, list_scenarios
    from vei.errors import InputError

    if list_:
        for name in list_scenarios(root):
            typer.echo(name)
        return
    if scenario is None or out is None:
        raise InputError(
            "--scenario and --out are required (or use --list)",
            field="--scenario" if scenario is None else "--out",
        )
    s = import_scenario_with_summary(
        root,
        scenario,
        out,
        rate_hz=rate_hz,
        include_ego_track=include_ego_track,
        full_ins=full_ins,
        road_users=road_users,
    )
    from vei.io.interaction import read_interaction

    it = read_interaction(s.out)
    ann = it.annotations
    typer.echo(f"wrote {s.out}")
    typer.echo(
        f"  ego: {len(it.ego)} fixes at 10 Hz over {s.ego_duration_s:.1f} s from "
        f"{s.ins_start_utc.isoformat(timespec='milliseconds')}"
    )
    typer.echo(
        f"  video frame 0 at {s.video_start_utc.isoformat(timespec='milliseconds')} ({s.video_offset_s:+.3f} s)"
    )
    for cat in sorted(set(ann["category"])):
        sub = ann[ann["category"] == cat]
        spans = sub.groupby("track_id")["t_s"].agg(lambda t: t.max() - t.min())
        typer.echo(
            f"  {cat}: {sub['track_id'].nunique()} track(s), {len(sub)} annotations at {rate_hz:g} Hz, "
            f"present t = {sub['t_s'].min():.1f}-{sub['t_s'].max():.1f} s, "
            f"each track {spans.min():.1f}-{spans.max():.1f} s long"
        )
    for tr in s.track_times:
        typer.echo(
            f"    track {tr['track_id']} ({tr['category']}): seen t = {tr['first_s']:.1f}-{tr['last_s']:.1f} s "
            f"({tr['last_s'] - tr['first_s']:.1f} s, {tr['n_annotations']} annotations)"
        )
    if s.own_track_median_m is not None:
        typer.echo(
            f"  car's own camera track vs INS: median {s.own_track_median_m:.2f} m, p95 {s.own_track_p95_m:.2f} m"
        )
    for warning in s.warnings:
        typer.echo(f"warning: {warning}", err=True)


def _import_tracks(
    format_: Annotated[
        str,
        typer.Option(
            "--format",
            help="'ind' (inD, rounD, uniD, exiD: XX_tracks.csv, XX_tracksMeta.csv, "
            "XX_recordingMeta.csv), 'sind' (Veh_smoothed_tracks.csv, Ped_smoothed_tracks.csv) or "
            "'av2' (Argoverse 2 scenario_<id>.parquet + log_map_archive_<id>.json).",
        ),
    ],
    root: Annotated[
        Path,
        typer.Option(
            "--root",
            help="The dataset folder: inD-family data folder, SinD record folder (or a folder of "
            "them), Argoverse 2 scenario folder (or a folder of them).",
        ),
    ],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Folder to write one interaction folder per ego into (<recording>__ego<ID>; "
            "a catalogue dataset as it is).",
        ),
    ] = None,
    recording: Annotated[
        list[str] | None,
        typer.Option(
            "--recording",
            help="Recording to import (repeatable): inD-family 'XX', SinD record folder, AV2 "
            "scenario id; default: every recording under --root (see --list).",
        ),
    ] = None,
    ego: Annotated[
        str,
        typer.Option(
            "--ego",
            help="'all': one interaction per car that comes within reach of a rider "
            "(docs/datasets.md); or one car's track id (av2: 'AV' is the autonomous vehicle).",
        ),
    ] = "all",
    road_users: Annotated[
        str,
        typer.Option(
            "--road-users",
            help="'riders' (e-scooters, bicycles, motorcycles, tricycles: docs/datasets.md) or "
            "'all' (also vehicles and pedestrians).",
        ),
    ] = "riders",
    rate_hz: Annotated[
        float | None,
        typer.Option(
            "--rate-hz",
            help="Annotation rate in Hz (default: every sample of the dataset); with a rate the "
            "full-rate tracks are written as ground truth.",
        ),
    ] = None,
    reach_m: Annotated[
        float,
        typer.Option(
            "--reach-m", help="Same-time car-rider distance that puts a rider in reach [m]."
        ),
    ] = 30.0,
    origin: Annotated[
        str | None,
        typer.Option(
            "--origin",
            help="sind only: LAT,LON [deg] to place the (not geo-referenced) ground frame at; "
            "default 0,0 (a placeholder).",
        ),
    ] = None,
    list_: Annotated[
        bool, typer.Option("--list", help="List the recordings under --root and exit.")
    ] = False,
) -> None:
    """Import world-frame tracks (inD family, SinD, Argoverse 2): any car as the ego."""
    from vei.datasets import av2, ind, sind
    from vei.datasets.world_import import import_tracks
    from vei.datasets.world_tracks import Reach
    from vei.errors import InputError

    formats = {"ind": ind, "sind": sind, "av2": av2}
    if format_ not in formats:
        raise InputError(
            f"--format must be one of {', '.join(formats)}, got {format_!r}", field="--format"
        )
    module = formats[format_]
    names = module.list_recordings(root)
    if list_:
        for name in names:
            typer.echo(name)
        return
    if out is None:
        raise InputError("--out is required (or use --list)", field="--out")
    if origin is not None and format_ != "sind":
        raise InputError("--origin applies to --format sind only", field="--origin")
    chosen = recording or names
    unknown = [r for r in chosen if r not in names]
    if unknown:
        raise InputError(
            f"unknown recording {unknown[0]!r} (see --list)", path=root, field="--recording"
        )
    reach = Reach(gap_m=reach_m)
    total = 0
    for name in chosen:
        if format_ == "sind":
            rec = sind.read_recording(
                root, name, origin_deg=_latlon(origin) if origin else (0.0, 0.0)
            )
        else:
            rec = module.read_recording(root, name)
        written = import_tracks(
            rec, out, ego=ego, road_users=road_users, rate_hz=rate_hz, reach=reach
        )
        total += len(written)
        typer.echo(
            f"{rec.recording}: {rec.tracks['track_id'].nunique()} tracks at {rec.rate_hz:g} Hz, "
            f"{len(written)} interaction(s)"
        )
        for w in written:
            riders = ", ".join(f"{n} {c}" for c, n in w.riders.items() if n)
            gap = "" if w.min_gap_m == float("inf") else f", closest rider {w.min_gap_m:.1f} m"
            typer.echo(f"  {w.folder.name}: ego {w.ego_id}, {w.duration_s:.1f} s, {riders}{gap}")
    typer.echo(f"wrote {total} interaction folder(s) under {out}")


def _latlon(text: str) -> tuple[float, float]:
    from vei.errors import InputError

    try:
        lat, lon = (float(v) for v in text.split(","))
    except ValueError:
        raise InputError(f"expected LAT,LON in degrees, got {text!r}", field="--origin") from None
    if not (-90 <= lat <= 90 and -180 <= lon <= 180):
        raise InputError(f"LAT,LON out of range: {text!r}", field="--origin")
    return lat, lon


def _download_trafficmonitoring(
    dest: Annotated[
        Path,
        typer.Option(
            "--dest",
            help="Dataset root to create or complete (files land in DEST/data/measurements).",
        ),
    ] = DEFAULT_DOWNLOAD_DEST,
    scenario: Annotated[
        list[str] | None,
        typer.Option(
            "--scenario",
            help="Scenario to fetch (repeatable); default: the three vei's tests use. Any scenario of the "
            "repository with a matching file works.",
        ),
    ] = None,
    base_url: Annotated[
        str | None,
        typer.Option(
            "--base-url",
            help="Serve the repository's files from here instead of GitHub (a mirror).",
        ),
    ] = None,
    timeout_s: Annotated[
        float, typer.Option("--timeout-s", help="Network timeout per attempt, in seconds.")
    ] = 30.0,
    retries: Annotated[
        int, typer.Option("--retries", help="Retries per file on transient errors.")
    ] = 3,
    list_known: Annotated[
        bool,
        typer.Option(
            "--list-known", help="List the scenarios known to have matching files and exit."
        ),
    ] = False,
) -> None:
    """Download the TrafficMonitoring files vei's importer needs (resumes; skips complete files)."""
    from vei.datasets.download import (
        TRAFFICMONITORING_BASE_URL,
        TRAFFICMONITORING_SCENARIOS,
        download_trafficmonitoring,
    )
    from vei.errors import ConfigError

    if list_known:
        for name in TRAFFICMONITORING_SCENARIOS:
            typer.echo(name)
        return
    if timeout_s <= 0 or retries < 0:
        raise ConfigError(
            f"--timeout-s must be > 0 and --retries >= 0 (got {timeout_s}, {retries})"
        )
    root = download_trafficmonitoring(
        dest,
        base_url=base_url or TRAFFICMONITORING_BASE_URL,
        scenarios=scenario or None,
        timeout_s=timeout_s,
        retries=retries,
        progress=typer.echo,
    )
    typer.echo(f"dataset root: {root}  (vei import trafficmonitoring --root {root} --list)")


def register(app: typer.Typer) -> None:
    """Add the ``import`` and ``datasets`` command groups to the app."""
    import_app = typer.Typer(
        help="Import public datasets as interaction folders.", no_args_is_help=True
    )
    import_app.command("trafficmonitoring")(_import_trafficmonitoring)
    import_app.command("tracks")(_import_tracks)
    datasets_app = typer.Typer(help="Fetch public datasets.", no_args_is_help=True)
    download_app = typer.Typer(help="Download a public dataset.", no_args_is_help=True)
    download_app.command("trafficmonitoring")(_download_trafficmonitoring)
    datasets_app.add_typer(download_app, name="download")
    app.add_typer(import_app, name="import")
    app.add_typer(datasets_app, name="datasets")
