"""``vei export openscenario`` and ``vei export check``: standard scenario files out of vei.

``vei export openscenario SCENARIO --out DIR`` writes ``DIR/<scenario id>.xosc`` and a copy
of the scenario's OpenDRIVE map; without ``--config`` the recorded (replayed) trajectories,
with ``--config NAME`` the run of that configuration on the built-in engine.
``vei export check FILE.xosc`` validates a file against the official XSD of its version,
runs the ASAM Quality Checker on it and, where esmini is found (``--esmini DIR``,
``$VEI_ESMINI``, ``../shared/tools/esmini``), plays it headless and compares every entity's
played path with the file's own vertices (vei.export.playback). Reports go into
``--report-dir`` or a new temporary folder, never beside the input.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated

import typer
from rich.console import Console

from vei.cli.output import console


def _safe_stem(text: str) -> str:
    stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._")
    return stem or "vei_scenario"


def replay_trajectories(scenario):  # type: ignore[no-untyped-def]
    """The trajectories the replay export plays: the recorded ones with every road user's
    run-in and run-out (vei.continuation, default settings), over the recorded span
    [0, last recorded time] (continuation samples outside it are left out)."""
    from vei.continuation import recorded_rows, with_continuations

    cont = with_continuations(scenario)
    traj = cont.trajectories
    t_end = float(recorded_rows(traj)["t_s"].max())
    t = traj["t_s"].to_numpy(dtype=float)
    return traj[(t >= -1e-9) & (t <= t_end + 1e-9)].reset_index(drop=True)


def export_scenario(
    scenario_dir: Path,
    out_dir: Path,
    *,
    config: str | None = None,
    time_shift: str | None = None,
    osc_version: str = "1.2",
    ego_controller: str = "trajectory",
    vertex_rate_hz: float | None = 10.0,
) -> Path:
    """Export a scenario folder's replay (config None) or a simulated run; returns the .xosc.

    Args:
        scenario_dir: scenario folder (scenario.json + trajectories.parquet [+ map]).
        out_dir: output folder.
        config: None (recorded trajectories) or a configuration name / file, run with the
            built-in engine exactly as ``vei run`` does.
        time_shift: 'auto' or seconds, for ``config`` runs; None: the run file's, else 'auto'.
        osc_version, ego_controller, vertex_rate_hz: see export_openscenario.
    """
    from vei.export.openscenario import export_openscenario, timeseries_to_trajectories
    from vei.io.scenario import read_scenario

    scenario = read_scenario(scenario_dir)
    xodr = None
    if "opendrive" in scenario.maps:
        base = scenario.root if scenario.root is not None else Path(scenario_dir)
        xodr = base / scenario.maps["opendrive"]
    if config is None:
        traj = replay_trajectories(scenario)
        label = "replay of the recorded trajectories with their run-ins and run-outs"
        name = _safe_stem(scenario.id)
    else:
        # the same configuration loading and engine run as `vei run`
        from vei.cli.sim_cmd import _load_case
        from vei.experiments.casestudy import run_casestudy

        case, run_cfg = _load_case(config)
        sim = run_cfg.sim if run_cfg is not None else None
        if time_shift is None:
            time_shift = run_cfg.time_shift if run_cfg is not None else "auto"
        result = run_casestudy(
            scenario, cases=[case], time_shift=time_shift, backend="builtin", sim=sim
        )
        config_name = case.name
        traj = timeseries_to_trajectories(result.frame, config=config_name)
        label = f"vei run of configuration '{config_name}', rider time shift {result.time_shift_s:+.2f} s"
        name = _safe_stem(f"{scenario.id}_{config_name}")
    return export_openscenario(
        traj,
        list(scenario.agents),
        out_dir,
        xodr=xodr,
        osc_version=osc_version,
        ego_controller=ego_controller,  # type: ignore[arg-type]
        name=name,
        description=f"vei scenario {scenario.id}: {label}",
        creation_date=scenario.start_time_utc,
        vertex_rate_hz=vertex_rate_hz,
    )


def register(app: typer.Typer) -> None:
    """Add ``vei export openscenario`` and ``vei export check``."""
    export_app = typer.Typer(
        name="export",
        help="Export scenarios to standard formats (OpenSCENARIO 1.x + OpenDRIVE) and check them.",
        no_args_is_help=True,
    )

    @export_app.command("openscenario")
    def openscenario_cmd(
        scenario: Annotated[
            Path,
            typer.Argument(
                help="Scenario folder (scenario.json + trajectories.parquet, map if any)."
            ),
        ],
        out: Annotated[
            Path, typer.Option("--out", help="Output folder for the .xosc and the map copy.")
        ],
        config: Annotated[
            str | None,
            typer.Option(
                "--config",
                help="Configuration to simulate with the built-in engine before exporting "
                "(replay, normal, aggressive, normal-cap, aggressive-cap, replay-speed, or a "
                "config file). Omit to export the recorded (replayed) trajectories.",
            ),
        ] = None,
        time_shift: Annotated[
            str | None,
            typer.Option(
                "--time-shift",
                help="Rider time shift for --config runs: 'auto' or seconds "
                "(default: the run file's time_shift, else auto).",
            ),
        ] = None,
        osc_version: Annotated[
            str,
            typer.Option(
                "--osc-version",
                help="OpenSCENARIO version: 1.0, 1.1, 1.2 or 1.3. CARLA ScenarioRunner reads 1.0 only; "
                "the ASAM checker's reference checks apply from 1.2 on.",
            ),
        ] = "1.2",
        ego_controller: Annotated[
            str,
            typer.Option(
                "--ego-controller",
                help="'trajectory': the ego follows its timed trajectory; 'simulator': the ego gets its "
                "initial pose and speed and its path without timing, and the simulator's speed "
                "control (or the system under test) drives it along the path: cruise speed from "
                "when the recording moves, stop at the path's end.",
            ),
        ] = "trajectory",
        vertex_rate_hz: Annotated[
            float,
            typer.Option(
                "--vertex-rate-hz",
                help="Base rate of trajectory vertices [Hz] (refined where the polyline would be off "
                "by > 5 cm or 0.05 rad); 0 keeps every sample.",
            ),
        ] = 10.0,
        check: Annotated[
            bool,
            typer.Option(
                "--check",
                help="Check the result after writing (XSD, ASAM Quality Checker and, where "
                "esmini is found, a playback); reports go into a temporary folder.",
            ),
        ] = False,
    ) -> None:
        """Write SCENARIO as OpenSCENARIO (.xosc) + OpenDRIVE (.xodr) into --out."""
        from vei.errors import ConfigError

        if vertex_rate_hz < 0:
            raise ConfigError(f"--vertex-rate-hz must be >= 0, got {vertex_rate_hz}")
        path = export_scenario(
            scenario,
            out,
            config=config,
            time_shift=time_shift,
            osc_version=osc_version,
            ego_controller=ego_controller,
            vertex_rate_hz=vertex_rate_hz if vertex_rate_hz > 0 else None,
        )
        typer.echo(f"wrote {path}")
        if check:
            code = _check(path, qc_bin=None, run_qc=True, play=True, esmini=None, report_dir=None)
            if code:
                raise SystemExit(code)  # typer.Exit is swallowed by main() (standalone_mode=False)

    @export_app.command("check")
    def check_cmd(
        file: Annotated[Path, typer.Argument(help="The .xosc file to check.")],
        qc_bin: Annotated[
            Path | None,
            typer.Option(
                "--qc-bin",
                help="qc_openscenario executable or its folder (default: $VEI_QC_BIN, PATH, .tools/qc/bin).",
            ),
        ] = None,
        qc: Annotated[
            bool,
            typer.Option(
                "--qc/--no-qc", help="Run the ASAM Quality Checker (besides the XSD validation)."
            ),
        ] = True,
        play: Annotated[
            bool,
            typer.Option(
                "--play/--no-play",
                help="Play the file headless in esmini (where found) and compare every entity's "
                "played path with the file's vertices.",
            ),
        ] = True,
        esmini: Annotated[
            Path | None,
            typer.Option(
                "--esmini",
                help="esmini folder (holding bin/esmini); default: $VEI_ESMINI, else "
                "../shared/tools/esmini. Given (option or $VEI_ESMINI) and not found: exit 2; "
                "else, not found: the playback is skipped.",
            ),
        ] = None,
        report_dir: Annotated[
            Path | None,
            typer.Option(
                "--report-dir",
                help="Folder for the reports (.xqar, esmini's recording, log and playback.csv); "
                "default: a new temporary folder (never beside FILE).",
            ),
        ] = None,
        dt_s: Annotated[
            float, typer.Option("--dt", help="esmini's fixed step for the playback [s].")
        ] = 0.05,
    ) -> None:
        """Check FILE: official OpenSCENARIO XSD, ASAM Quality Checker, esmini playback.

        A checker that is not found is skipped (said so) unless it was asked for
        (--qc-bin / $VEI_QC_BIN, --esmini). Exit code 0: no issue; 1: issues found
        (listed); 2: the file, or a checker that was asked for, is missing.
        """
        code = _check(
            file,
            qc_bin=qc_bin,
            run_qc=qc,
            play=play,
            esmini=esmini,
            report_dir=report_dir,
            dt_s=dt_s,
        )
        if code:
            raise SystemExit(code)  # typer.Exit is swallowed by main() (standalone_mode=False)

    # vei export commonroad (issue 26), in its own module
    from vei.cli.commonroad_cmd import register as register_commonroad

    register_commonroad(export_app)
    app.add_typer(export_app, name="export")


def _check(
    path: Path,
    *,
    qc_bin: Path | None,
    run_qc: bool,
    play: bool,
    esmini: Path | None,
    report_dir: Path | None,
    dt_s: float = 0.05,
) -> int:
    import os
    import tempfile

    from vei.errors import ConfigError, DependencyError, InputError
    from vei.export.validate import declared_version, validate_openscenario

    out = console()
    if not path.is_file():
        raise InputError("file not found", path=path)
    if not dt_s > 0:
        raise ConfigError(f"--dt must be > 0 s, got {dt_s}")
    if report_dir is None:
        report_dir = Path(tempfile.mkdtemp(prefix="vei-check-"))
    report_dir.mkdir(parents=True, exist_ok=True)
    version = declared_version(path)
    errors = validate_openscenario(path)
    out.print(f"XSD (OpenSCENARIO {version}): {len(errors)} error(s)", highlight=False)
    for e in errors[:10]:
        out.print(f"  {e}", highlight=False, soft_wrap=True)
    if len(errors) > 10:
        out.print(f"  ... and {len(errors) - 10} more", highlight=False)
    ok = not errors
    if run_qc:
        from vei.export.qc import find_qc_openscenario, run_qc_openscenario

        try:
            exe = find_qc_openscenario(qc_bin)
        except DependencyError as exc:
            if qc_bin is not None or os.environ.get("VEI_QC_BIN"):
                raise  # asked for explicitly: missing is an error (exit 2)
            exe = None
            out.print(f"ASAM Quality Checker: skipped ({exc})", highlight=False, soft_wrap=True)
        if exe is not None:
            report = run_qc_openscenario(
                path, qc_bin=exe, result_file=report_dir / f"{path.name}.xqar"
            )
            out.print(f"ASAM Quality Checker: {report.summary()}", highlight=False, soft_wrap=True)
            out.print(f"result: {report.result_file}", highlight=False)
            ok = ok and report.ok
    if play:
        from vei.esmini import find_esmini

        try:
            tool = find_esmini(esmini)
            tool.require_player()
            tool.require_dat2csv()
        except DependencyError as exc:
            if esmini is not None or os.environ.get("VEI_ESMINI"):
                raise  # asked for explicitly: missing is an error (exit 2)
            tool = None
            out.print(f"esmini playback: skipped ({exc})", highlight=False, soft_wrap=True)
        if tool is not None:
            ok = _play(path, tool, report_dir, dt_s, out) and ok
    out.print(f"reports: {report_dir}", highlight=False, soft_wrap=True)
    return 0 if ok else 1


def _play(path: Path, tool, report_dir: Path, dt_s: float, out: Console) -> bool:
    from vei.export.playback import play_xosc
    from vei.io.atomic import write_text

    rep = play_xosc(path, esmini=tool, dt_s=dt_s, work_dir=report_dir / "esmini")
    table = rep.table()
    write_text(report_dir / "playback.csv", table.to_csv(index=False))
    issues = rep.issues()
    pairs = sorted(" - ".join(sorted(p)) for p in rep.collision_pairs())
    worst = (
        f"worst median / max deviation {table['median_dev_m'].max():.3f} / "
        f"{table['max_dev_m'].max():.3f} m"
        if table["compared"].sum()
        else "nothing compared"
    )
    out.print(
        f"esmini playback (step {dt_s:g} s, {rep.wall_s:.2f} s, log {rep.log_bytes} bytes): "
        f"{len(issues)} issue(s); {len(table)} entities, {worst}; "
        f"collisions: {', '.join(pairs) if pairs else 'none'}",
        highlight=False,
        soft_wrap=True,
    )
    for i in issues:
        out.print(f"  {i}", highlight=False, soft_wrap=True)
    for w in rep.log.install_warnings[:1]:
        out.print(
            f"  note: {len(rep.log.install_warnings)} warning(s) about the esmini installation's "
            f"resources, e.g. {w}",
            highlight=False,
            soft_wrap=True,
        )
    return not issues
