"""``vei catalogue``: the ranked risk catalogue of a dataset; ``vei report``: its HTML report."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer


def catalogue(
    dataset: Annotated[
        Path,
        typer.Argument(
            help="A TrafficMonitoring root (holding data/measurements) or a folder of "
            "interaction folders."
        ),
    ],
    out: Annotated[
        Path,
        typer.Option(
            "--out", help="Catalogue folder; running again with the same settings resumes."
        ),
    ],
    settings: Annotated[
        Path | None,
        typer.Option(
            "--settings",
            help="YAML/JSON: rule, sweep, cases, annotation_rate_hz, recon, map_source, "
            "max_encounters_per_recording, figures (docs/catalogue.md).",
        ),
    ] = None,
    recording: Annotated[
        list[str] | None,
        typer.Option("--recording", help="Only this recording (repeatable); default: all."),
    ] = None,
    engine: Annotated[
        str, typer.Option("--engine", help="local (processes on this machine) or ray.")
    ] = "local",
    workers: Annotated[
        int, typer.Option("--workers", help="Parallel workers (processes or Ray CPUs), >= 1.")
    ] = 1,
    n_variants: Annotated[
        int | None,
        typer.Option("--n-variants", help="Sweep variants per encounter (overrides the settings)."),
    ] = None,
    no_sweep: Annotated[
        bool, typer.Option("--no-sweep", help="Case study only, no sweep per encounter.")
    ] = False,
    map_source: Annotated[
        Path | None,
        typer.Option(
            "--map", help="Local OSM extract, SUMO net or .xodr giving every recording its map."
        ),
    ] = None,
    no_figures: Annotated[
        bool, typer.Option("--no-figures", help="No PNG/PDF figures per encounter.")
    ] = False,
    report: Annotated[
        bool,
        typer.Option(
            "--report/--no-report",
            help="Write report.html (and report_files/ beside it) at the end.",
        ),
    ] = True,
    top: Annotated[int, typer.Option("--top", help="Rows of the ranked table printed.")] = 10,
    road_users: Annotated[
        str | None,
        typer.Option(
            "--road-users",
            help="TrafficMonitoring import: 'riders' (default) or 'all' (also vehicles and "
            "pedestrians), as vei import trafficmonitoring --road-users.",
        ),
    ] = None,
    interp: Annotated[
        str | None,
        typer.Option(
            "--interp",
            help="Reconstruction interpolation (auto, cubic, linear, smoothing, kalman), as "
            "vei reconstruct --interp (overrides the settings' recon.interp; default auto).",
        ),
    ] = None,
) -> None:
    """Find, simulate, sweep, score and rank every car-rider encounter of a dataset."""
    import time

    from vei.catalogue import load_catalogue_config, run_catalogue
    from vei.cli import output
    from vei.errors import ConfigError

    t0 = time.perf_counter()
    overrides: dict = {"figures": False if no_figures else None}
    if map_source is not None:
        overrides["map_source"] = str(map_source)
    overrides["road_users"] = road_users
    config = load_catalogue_config(settings, **overrides)
    if interp is not None:
        import dataclasses

        config = dataclasses.replace(config, recon={**config.recon, "interp": interp})
    if no_sweep or n_variants is not None:
        import dataclasses

        sweep = None
        if not no_sweep:
            if n_variants < 1:
                raise ConfigError(f"--n-variants must be >= 1, got {n_variants}")
            sweep = dict(config.sweep or {})
            if sweep.get("design") == "grid":
                raise ConfigError("--n-variants needs a random or lhs sweep design")
            sweep["n_samples"] = n_variants
        config = dataclasses.replace(config, sweep=sweep)
    console = output.console()
    try:
        result = run_catalogue(
            dataset, out, config, recordings=recording or None, engine=engine, workers=workers
        )
    except KeyboardInterrupt:
        from vei.catalogue.store import done_encounters

        n_done = len(done_encounters(Path(out))) if Path(out).is_dir() else 0
        typer.echo(
            f"interrupted: {n_done} encounter(s) done in {out}; "
            "run the same command again to resume",
            err=True,
        )
        raise typer.Exit(130) from None
    _print_result(console, result, top)
    if report:
        from vei.catalogue.report_data import write_report

        path = write_report(out)
        console.print(f"report: {path}")
    console.print(f"wall time: {time.perf_counter() - t0:.1f} s")
    if not result.complete:
        n_rec, n_enc = len(result.failed_recordings), len(result.failed_encounters)
        console.print(
            f"partial: {n_rec} recording(s) and {n_enc} encounter(s) failed (listed above); "
            "exit code 3",
            style="yellow",
        )
        raise typer.Exit(3)


def _print_result(console, result, top: int) -> None:
    from rich.table import Table

    table = Table(title="recordings")
    for col in ("recording", "status", "encounters", "reason"):
        table.add_column(col)
    for d in result.recordings:
        table.add_row(
            d["recording"],
            d["status"],
            ", ".join(e["rider_id"] for e in d.get("encounters", [])) or "-",
            d.get("reason", ""),
        )
    console.print(table)
    for f in result.failed_encounters:
        console.print(f"encounter failed {f['encounter_id']}: {f['reason']}", style="red")
    enc = result.encounters
    if len(enc):
        by = "expected harm" if "risk_expected_harm" in enc else "criticality"  # issue 23
        t = Table(title=f"encounters ranked by {by} (top {min(top, len(enc))} of {len(enc)})")
        cols = (
            ("rank", "rank", "{:d}"),
            ("encounter_id", "encounter", "{}"),
            ("category", "rider", "{}"),
            ("rec_path_distance_m", "route dist [m]", "{:.2f}"),
            ("rec_pet_s", "PET [s]", "{:.2f}"),
            ("rec_min_gap_m", "rec. gap [m]", "{:.2f}"),
            ("time_shift_auto_s", "shift [s]", "{:.2f}"),
            ("n_configs", "configs", "{:d}"),
            ("collision_share", "collision share", "{:.3f}"),
            ("mean_safety_index", "mean SI", "{:.3f}"),
            ("worst_min_gap_m", "worst gap [m]", "{:.2f}"),
            ("casestudy_collisions", "case-study collisions", "{:d}"),
        )
        if by == "expected harm":  # issue 23: the risk estimate with its 95 % intervals
            enc = enc.assign(
                _harm=[_ci(r, "risk_expected_harm") for r in enc.to_dict("records")],
                _p=[_ci(r, "risk_p_collision") for r in enc.to_dict("records")],
                _pr=[_ci(r, "risk_p_collision_recorded") for r in enc.to_dict("records")],
            )
            cols = (*cols[:3], ("_harm", "expected harm [95 % CI]", "{}"),
                    ("_p", "P(collision) [95 % CI]", "{}"), *cols[3:])  # fmt: skip
            if "risk_p_collision_recorded" in enc:  # issue 31: what the recording supports
                cols = (*cols[:5], ("_pr", "P(on recorded) [95 % CI]", "{}"), *cols[5:])
        if "recorded_collision_share" in enc:  # issue 31: what the recorded behaviour supports
            enc = enc.assign(
                _rec=[_share_ci(r, "recorded_collision_share") for r in enc.to_dict("records")]
            )
            i = [c for c, *_ in cols].index("collision_share") + 1
            cols = (*cols[:i], ("_rec", "on recorded [95 % CI]", "{}"),
                    ("collisions_on_recorded", "of collisions on recorded", "{:.0%}"),
                    *cols[i:])  # fmt: skip
        for c, head, _ in cols:
            t.add_column(
                head,
                justify="left" if c in ("encounter_id", "category") else "right",
                no_wrap=c == "encounter_id",
            )
        for rec in enc.head(top).to_dict("records"):
            t.add_row(*(fmt.format(rec[c]) if rec[c] == rec[c] else "-" for c, _, fmt in cols))
        console.print(t)
    console.print(
        f"{len(result.rows)} rows (encounter x configuration) in {result.out_dir / 'catalogue.parquet'}; "
        f"{result.n_done_before} encounter(s) done by an earlier run; "
        f"status {'complete' if result.complete else 'partial'}"
    )


def _share_ci(rec: dict, name: str) -> str:
    """'0.120 [0.081, 0.170]' (a share of configurations with its 95 % interval)."""
    v, lo, hi = rec.get(name), rec.get(f"{name}_lo"), rec.get(f"{name}_hi")
    return "-" if v is None or v != v else f"{v:.3f} [{lo:.3f}, {hi:.3f}]"


def _ci(rec: dict, name: str) -> str:
    """'2.6e-04 [2.2e-04, 3.1e-04]', or '< 1.8e-03' with only an upper bound."""
    v, lo, hi = rec.get(name), rec.get(f"{name}_lo"), rec.get(f"{name}_hi")
    if v is None or v != v:
        return f"< {hi:.1e}" if hi is not None and hi == hi else "-"
    return f"{v:.1e} [{lo:.1e}, {hi:.1e}]"


def report_cmd(
    catalogue_dir: Annotated[
        Path, typer.Argument(help="A catalogue folder (vei catalogue --out).")
    ],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Index page (default CATALOGUE_DIR/report.html; its scripts go to <name>_files/ beside it).",
        ),
    ] = None,
) -> None:
    """Write the HTML report of a catalogue: an index page and one script per encounter beside it, loaded on demand (works offline from the folder)."""
    from vei.catalogue.report_data import write_report

    path = write_report(catalogue_dir, out)
    typer.echo(f"report: {path}")


def register(app: typer.Typer) -> None:
    """Add ``vei catalogue`` and ``vei report`` to the app."""
    app.command("catalogue")(catalogue)
    app.command("report")(report_cmd)
