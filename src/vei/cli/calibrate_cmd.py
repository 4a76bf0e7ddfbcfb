"""``vei calibrate riders|validate|decisions``: fit the social-force rider (and its yield /
go decision) to real rider tracks."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from vei.errors import InputError

_ROOT_HELP = "TrafficMonitoring dataset root (the folder that holds data/measurements)."


def _riders(
    root: Annotated[Path, typer.Option("--root", help=_ROOT_HELP)],
    out: Annotated[Path, typer.Option("--out", help="Output folder (profile, report, figure).")],
    category: Annotated[
        str,
        typer.Option("--category", help="escooter, cyclist or all (fitted per track either way)."),
    ] = "all",
    horizon_s: Annotated[
        float, typer.Option("--horizon-s", help="Closed-loop rollout length of the fit [s].")
    ] = 3.0,
    scenario: Annotated[
        list[str] | None, typer.Option("--scenario", help="Only these scenarios (repeatable).")
    ] = None,
    bootstrap: Annotated[
        int, typer.Option("--bootstrap", help="Resamples of the vehicle-repulsion interval (>= 0).")
    ] = 20,
    no_figure: Annotated[bool, typer.Option("--no-figure", help="Skip the PNG.")] = False,
) -> None:
    """Fit the rider model per track; write the rider profile, the fit report and figures."""
    from vei.calibrate.pipeline import FIGURE_FILE, PROFILE_FILE, REPORT_MD, calibrate_riders

    if bootstrap < 0:
        raise InputError(f"expected >= 0, got {bootstrap}", field="--bootstrap")
    run = calibrate_riders(
        root,
        out,
        category=category,
        horizon_s=horizon_s,
        scenarios=scenario,
        bootstrap=bootstrap,
        figures=not no_figure,
    )
    rep = run.report
    typer.echo(
        f"fitted {rep['n_tracks']} rider tracks ({len(rep['dropped'])} dropped by the filter)"
    )
    for name, pop in rep["populations"].items():
        med = pop["median"]
        typer.echo(
            f"  {name:9s} n={pop['n_tracks']:2d}  v0 {med['v0_mps']:.2f} m/s  tau {med['tau_s']:.2f} s  "
            f"look-ahead {med['lookahead_m']:.2f} m  vmax {med['max_speed_mps']:.2f} m/s  "
            f"amax {med['max_accel_mps2']:.2f} m/s2"
        )
    v = rep["vehicle_repulsion"]
    state = "identified" if v["identified"] else "NOT identified (paper values kept)"
    typer.echo(
        f"  vehicle repulsion: {state}; {v['n_windows']} close windows from {v['n_tracks']} tracks"
    )
    typer.echo(f"profile: {run.out / PROFILE_FILE}")
    typer.echo(f"report:  {run.out / REPORT_MD}")
    if not no_figure:
        typer.echo(f"figure:  {run.out / FIGURE_FILE}")
    typer.echo(f"time:    {run.elapsed_s:.1f} s")


def _validate(
    root: Annotated[Path, typer.Option("--root", help=_ROOT_HELP)],
    out: Annotated[
        Path | None, typer.Option("--out", help="Also write validation.json into this folder.")
    ] = None,
    horizons: Annotated[
        str, typer.Option("--horizons", help="Comma-separated rollout horizons [s].")
    ] = "3,5",
) -> None:
    """Leave-one-scenario-out ADE/FDE table: CV, CA, CS-path, paper SFM, calibrated SFM."""
    import time

    from vei.calibrate.tracks import load_scenes
    from vei.calibrate.validate import validate_loso
    from vei.io.atomic import write_json

    try:
        hs = tuple(float(h) for h in horizons.split(","))
    except ValueError:
        raise InputError(
            f"expected numbers like 3,5; got {horizons!r}", field="--horizons"
        ) from None
    if not hs or any(not (0.5 <= h <= 10.0) for h in hs):
        raise InputError(f"horizons must lie in [0.5, 10] s, got {horizons!r}", field="--horizons")
    t0 = time.perf_counter()
    table = validate_loso(load_scenes(root), hs)
    typer.echo(table.format())
    for h in hs:
        typer.echo(
            f"ADE@{h:g}s: calibrated SFM vs CV {100 * table.gain('SFM calibrated', 'CV', h):+.0f} %, "
            f"vs paper SFM {100 * table.gain('SFM calibrated', 'SFM paper', h):+.0f} %, "
            f"vs CS-path {100 * table.gain('SFM calibrated', 'CS-path', h):+.0f} % (positive = lower error)"
        )
    typer.echo(f"time: {time.perf_counter() - t0:.1f} s")
    if out is not None:
        path = write_json(Path(out) / "validation.json", table.to_dict())
        typer.echo(f"written: {path}")


def _decisions(
    root: Annotated[Path, typer.Option("--root", help=_ROOT_HELP)],
    out: Annotated[
        Path | None,
        typer.Option("--out", help="Also write decisions.json (cases, fit, validation) here."),
    ] = None,
    horizon_s: Annotated[
        float, typer.Option("--horizon-s", help="The rider's decision horizon [s] (> 0).")
    ] = 4.0,
    horizons: Annotated[
        str, typer.Option("--horizons", help="Rollout horizons of the ADE/FDE check [s].")
    ] = "3,5",
) -> None:
    """Yield / go cases of the recorded riders, the gap-acceptance fit, and its
    leave-one-scenario-out validation (decisions, stops, ADE/FDE)."""
    import time

    from vei.calibrate.decision_validate import validate_decisions
    from vei.calibrate.tracks import load_scenes
    from vei.io.atomic import write_json

    if not horizon_s > 0:
        raise InputError(f"expected > 0, got {horizon_s}", field="--horizon-s")
    try:
        hs = tuple(float(h) for h in horizons.split(","))
    except ValueError:
        raise InputError(
            f"expected numbers like 3,5; got {horizons!r}", field="--horizons"
        ) from None
    t0 = time.perf_counter()
    val = validate_decisions(load_scenes(root), hs, decision_horizon_s=horizon_s)
    typer.echo(val.format())
    typer.echo(f"time: {time.perf_counter() - t0:.1f} s")
    if out is not None:
        path = write_json(Path(out) / "decisions.json", val.to_dict())
        typer.echo(f"written: {path}")


def _variation(
    root: Annotated[Path, typer.Option("--root", help=_ROOT_HELP)],
    out: Annotated[
        Path | None,
        typer.Option(
            "--out",
            help="Write the fitted risk spec (YAML) here; the coverage "
            "table goes beside it (<out stem>.coverage.json / .md).",
        ),
    ] = None,
) -> None:
    """Fit the risk spec's variation model (car cruise speed between encounters, the rider's
    speed around its own, bounds) and validate it leaving one recording out."""
    import time

    from vei.calibrate.variation import calibrate_variation, spec_text
    from vei.io.atomic import write_json, write_text

    t0 = time.perf_counter()
    fit, cov = calibrate_variation(root)
    typer.echo(
        f"ego cruise speed: cv {fit.cruise_cv:.4f} between {fit.n_encounters} encounters "
        f"(median {fit.cruise_median_mps:.2f} m/s), max {fit.cruise_max_mps:.2f} m/s"
    )
    typer.echo(
        f"rider speed: sigma_log {fit.rider_sigma_log:.4f} around its own "
        f"({fit.n_windows} windows, {fit.n_riders} tracks); bounds "
        + ", ".join(f"{k} {v:.2f} m/s" for k, v in fit.rider_bounds_mps.items())
    )
    typer.echo(cov.table().rstrip())
    typer.echo(cov.summary())
    if out is not None:
        path = write_text(out, spec_text(fit, cov, Path(root).name))
        stem = path.with_suffix("")
        write_json(stem.with_name(stem.name + ".coverage.json"), cov.to_dict())
        write_text(stem.with_name(stem.name + ".coverage.md"), cov.table())
        typer.echo(f"spec: {path}")
    typer.echo(f"time: {time.perf_counter() - t0:.1f} s")


def register(app: typer.Typer) -> None:
    """Add the ``calibrate`` command group to the app."""
    cal = typer.Typer(help="Fit the rider model to real rider tracks.", no_args_is_help=True)
    cal.command("riders")(_riders)
    cal.command("validate")(_validate)
    cal.command("decisions")(_decisions)
    cal.command("variation")(_variation)
    app.add_typer(cal, name="calibrate")
