"""``vei sweep``: batched variant sweeps (grid / random / LHS) and critical-boundary search."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from vei.errors import ConfigError


def _pair(text: str | None, name: str, cast: type = float) -> tuple | None:
    if text is None:
        return None
    parts = [p.strip() for p in text.split(",")]
    if len(parts) != 2:
        raise ConfigError(f"{name} expects two comma-separated values, got {text!r}")
    try:
        return tuple(cast(p) for p in parts)
    except ValueError:
        raise ConfigError(f"{name} expects two {cast.__name__} values, got {text!r}") from None


def interrupted_message(out: Path) -> str:
    """The line printed when a sweep in ``out`` is interrupted: what is done, how to resume.

    Counts the finished part files of ``out/parts`` and their rows (Parquet footers only)
    and, when ``out/sweep.json`` says it, the sweep's total number of variants.
    """
    import json

    import pyarrow.parquet as pq

    from vei.sweep.run import PART_RE

    parts_dir = Path(out) / "parts"
    parts = [p for p in parts_dir.iterdir() if PART_RE.match(p.name)] if parts_dir.is_dir() else []
    rows = 0
    for p in parts:
        try:
            rows += pq.ParquetFile(p).metadata.num_rows
        except (OSError, ValueError):
            pass
    total = ""
    try:
        n = json.loads((Path(out) / "sweep.json").read_text())["n_variants"]
        total = f" of {int(n)}"
    except (OSError, ValueError, KeyError, TypeError):
        pass
    return (
        f"interrupted: {len(parts)} chunk(s) done ({rows}{total} variants) in {out}; "
        "run the same command again to resume"
    )


def sweep(
    scenario: Annotated[
        Path,
        typer.Argument(help="A scenario folder (scenario.json) or a folder of scenario folders."),
    ],
    spec: Annotated[
        Path,
        typer.Option(
            "--spec",
            help="Sweep spec (YAML): design, n_samples, seed, base, parameters (docs/sweeps.md).",
        ),
    ],
    out: Annotated[
        Path, typer.Option("--out", help="Output folder; running again with the same spec resumes.")
    ],
    engine: Annotated[
        str,
        typer.Option(
            "--engine",
            help="local (this machine; --workers processes) or ray (ray.init(num_cpus=workers)).",
        ),
    ] = "local",
    workers: Annotated[
        int, typer.Option("--workers", help="Parallel workers (processes or Ray CPUs), >= 1.")
    ] = 1,
    chunk_size: Annotated[
        int | None,
        typer.Option(
            "--chunk-size",
            help="Variants per engine batch; bounds memory (one chunk per worker). "
            "Default: >= 8 chunks per worker, at most 4096 variants each.",
        ),
    ] = None,
    max_chunks: Annotated[
        int | None,
        typer.Option(
            "--max-chunks", help="Stop after this many chunks (the sweep stays resumable)."
        ),
    ] = None,
    x: Annotated[
        str | None,
        typer.Option(
            "--x", help="Boundary search: parameter on the x axis (e.g. time_shift_s). Needs --y."
        ),
    ] = None,
    y: Annotated[
        str | None,
        typer.Option(
            "--y", help="Boundary search: parameter on the y axis (e.g. ego.cruise_speed_mps)."
        ),
    ] = None,
    x_range: Annotated[
        str | None,
        typer.Option(
            "--x-range", help="Boundary search: MIN,MAX of x (default: its min/max in the spec)."
        ),
    ] = None,
    y_range: Annotated[
        str | None,
        typer.Option(
            "--y-range", help="Boundary search: MIN,MAX of y (default: its min/max in the spec)."
        ),
    ] = None,
    coarse: Annotated[
        str, typer.Option("--coarse", help="Boundary search: coarse grid points NX,NY (>= 2).")
    ] = "9,9",
    levels: Annotated[
        int,
        typer.Option(
            "--levels",
            help="Boundary search: refinement levels (finest step = coarse step / 2^levels).",
        ),
    ] = 4,
    critical: Annotated[
        int,
        typer.Option(
            "--critical",
            help="How many most-critical variants to list and write configs for (>= 1).",
        ),
    ] = 20,
    record_critical: Annotated[  # [H5]
        bool,
        typer.Option(
            "--record-critical/--no-record-critical",
            help="Re-run the critical variants with the full recording "
            "(critical/timeseries.parquet and their bird's-eye figures).",
        ),
    ] = True,
    progress: Annotated[
        bool | None,
        typer.Option(
            "--progress/--no-progress", help="Progress bar (default: when stderr is a terminal)."
        ),
    ] = None,
) -> None:
    """Run many variants of recorded scenarios and find where collisions begin.

    Without --x/--y: a sweep (results.parquet, one row per variant; critical.csv/json;
    configs/ with a `vei run --config` file per critical variant; riskmap.png). With
    --x and --y: an adaptive critical-boundary search in that plane, every other parameter
    fixed by the spec (samples.parquet, boundary.json/csv, riskmap.png, critical.*, configs/).
    """
    from rich.table import Table

    from vei.cli.output import console as make_console
    from vei.sweep.run import find_scenarios, read_results, run_sweep
    from vei.sweep.spec import load_spec

    console = make_console()
    sweep_spec = load_spec(spec)
    if critical < 1:
        raise ConfigError(f"--critical must be >= 1, got {critical}")
    if (x is None) != (y is None):
        raise ConfigError("boundary search needs both --x and --y")
    if x is not None and y is not None:
        from vei.experiments.boundary import search_boundary

        nxy = _pair(coarse, "--coarse", int)
        dirs = find_scenarios(scenario)
        table = Table(title="critical boundary")
        for col in (
            "scenario",
            "evaluated",
            "grid of same resolution",
            "collisions",
            "boundary points",
            "folder",
        ):
            table.add_column(col)
        for d in dirs:
            target = Path(out) if len(dirs) == 1 else Path(out) / d.name
            try:
                res = search_boundary(
                    d,
                    sweep_spec,
                    x,
                    y,
                    target,
                    x_range=_pair(x_range, "--x-range"),
                    y_range=_pair(y_range, "--y-range"),
                    coarse=nxy,  # type: ignore[arg-type]
                    levels=levels,
                    k_critical=critical,
                    progress=progress,
                )
            except KeyboardInterrupt:
                typer.echo(
                    f"interrupted: the boundary search of {d.name} did not finish; it does not "
                    "resume (running the same command again starts it anew)",
                    err=True,
                )
                raise typer.Exit(130) from None
            table.add_row(
                d.name,
                str(res.n_evaluations),
                str(res.grid_evaluations),
                str(int(res.samples["collision"].sum())),
                str(len(res.crossings)),
                str(target),
            )
        console.print(table)
        return
    if x_range or y_range:
        raise ConfigError("--x-range / --y-range need --x and --y (boundary search)")
    try:
        result = run_sweep(
            scenario,
            sweep_spec,
            out,
            engine=engine,
            workers=workers,
            chunk_size=chunk_size,
            progress=progress,
            max_chunks=max_chunks,
            k_critical=critical,
            record_critical=record_critical,  # [H5]
        )
    except KeyboardInterrupt:
        typer.echo(interrupted_message(out), err=True)
        raise typer.Exit(130) from None
    table = Table(title="sweep")
    table.add_column("quantity")
    table.add_column("value")
    table.add_row("variants", str(result.n_variants))
    table.add_row("run now", str(result.n_run))
    table.add_row("done before (resumed)", str(result.n_skipped))
    table.add_row("seconds", f"{result.seconds:.1f}")
    if result.timings:
        table.add_row("phases [s]", ", ".join(f"{k} {v:.1f}" for k, v in result.timings.items()))
    if result.n_run:
        table.add_row("variants/s (prepare to results)", f"{result.variants_per_s:,.0f}")
    if result.n_run + result.n_skipped >= result.n_variants:
        import pyarrow.parquet as pq

        have = set(pq.read_schema(result.results).names)
        wanted = ("collision", "safety_index", "seen_too_late", "impact_speed_mps")
        res = read_results(out, columns=[c for c in wanted if c in have])
        if "collision" in res:
            table.add_row(
                "collisions", f"{int(res['collision'].sum())} ({res['collision'].mean():.1%})"
            )
        if "seen_too_late" in res:  # issue 22: counted apart, never ranked
            from vei.metrics.seen import flag_counts

            fc = flag_counts(res)
            table.add_row(
                "seen too late (not ranked)",
                f"{fc['flagged']} ({fc['flagged_share']:.1%}); collisions among them "
                f"{fc['collisions_flagged']}, unflagged collisions {fc['collisions_unflagged']}",
            )
        if "safety_index" in res:
            table.add_row("mean safety index", f"{res['safety_index'].mean():.3f}")
        table.add_row("results", str(result.results))
    else:
        table.add_row("status", "incomplete: run the same command again to resume")
    console.print(table)


def register(app: typer.Typer) -> None:
    """Add ``vei sweep`` to the app."""
    app.command("sweep")(sweep)
