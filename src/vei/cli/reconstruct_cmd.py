"""``vei reconstruct INTERACTION --out SCENARIO_DIR``: interaction -> world-frame scenario.

Writes the scenario folder (scenario.json, trajectories.parquet, keyframes.parquet,
birdseye.png) atomically and prints one row per reconstructed road user: keyframes, the
method used, peak speed/acceleration, and, where the interaction has ground truth, the
reconstruction error (RMSE, p95, max [m]); then a summary with the primary threat, what
``--interp auto`` chose, and a warning (stderr) for every rider whose reconstructed speed
is implausible.
"""

from __future__ import annotations

import functools
import shutil
import tempfile
import warnings
from pathlib import Path
from typing import Annotated

import typer

from vei.errors import ConfigError


def register(app: typer.Typer) -> None:
    """Add ``vei reconstruct`` to the app."""

    @app.command("reconstruct")
    def reconstruct(
        interaction: Annotated[
            Path,
            typer.Argument(
                help="Interaction folder (format vei.interaction/1: interaction.json, ego.csv, "
                "annotations.csv, optional ground_truth.csv)."
            ),
        ],
        out: Annotated[
            Path,
            typer.Option("--out", "-o", help="Scenario folder to write (replaced if it exists)."),
        ],
        rate_hz: Annotated[
            float,
            typer.Option("--rate-hz", help="Simulation rate of the output trajectories, in Hz."),
        ] = 20.0,
        interp: Annotated[
            str,
            typer.Option(
                "--interp",
                help="Position interpolation between keyframes: 'auto' (default: per track, the "
                "paper's cubic where its keyframes are 0.5 s or more apart, e.g. the paper's "
                "1 FPS, and smoothing where they are denser, e.g. 10-30 Hz tracks), 'cubic' "
                "(the paper's cubic spline), 'linear', 'smoothing' (noise-aware smoothing "
                "spline that keeps rider speeds and accelerations plausible), or 'kalman' (RTS "
                "smoother with the noise estimated from the recording's keyframes: positions "
                "with their 95 % band, uncertainty.png, calibration against ground truth).",
            ),
        ] = "auto",
        noise_m: Annotated[
            float,
            typer.Option(
                "--noise-m",
                help="Keyframe position noise (1 sigma) assumed by --interp smoothing (and by "
                "auto on dense tracks), in metres.",
            ),
        ] = 0.25,
        ego_path: Annotated[
            str,
            typer.Option(
                "--ego-path",
                help="Ego path: 'spline' (cubic spline through the GPS fixes) or 'kalman' "
                "(smoothed with vehicle kinematics: continuous heading and curvature; the "
                "lateral acceleration before/after is reported).",
            ),
        ] = "spline",
        posterior_std_inflation: Annotated[
            str,
            typer.Option(
                "--posterior-std-inflation",
                help="--interp kalman: factor on the rider posterior's std (band, samples): "
                "'calibrated' (1.461, fitted on the shared recordings' camera; 1 with a fixed "
                "noise) or a number > 0 (1 = the model's own covariance; fit one for another "
                "sensor: docs/reconstruction.md).",
            ),
        ] = "calibrated",
        margin_m: Annotated[
            float,
            typer.Option("--margin-m", help="Margin around the trajectories' bounds, in metres."),
        ] = 50.0,
        figure: Annotated[
            bool,
            typer.Option(
                "--figure/--no-figure", help="Write birdseye.png into the scenario folder."
            ),
        ] = True,
        map_source: Annotated[
            str | None,
            typer.Option(
                "--map",
                help="Attach a road map (OpenDRIVE, built with SUMO netconvert in the scenario's "
                "plane): 'auto' (the configured OSM source: $VEI_OSM_SOURCE, else the Overpass "
                "API at $VEI_OVERPASS_URL), 'overpass', or a file: OSM extract (.osm, .osm.pbf), "
                "SUMO network (.net.xml[.gz]) or OpenDRIVE (.xodr). Omit for no map.",
            ),
        ] = None,
        threat: Annotated[
            str | None,
            typer.Option(
                "--threat",
                help="The primary threat (agent id such as escooter_78, or the annotations' track "
                "id 78) instead of the rule's choice (conflicting e-scooters first, then cyclists; "
                "smallest post-encroachment time).",
            ),
        ] = None,
    ) -> None:
        """Reconstruct a scenario from a recorded interaction (paper Section III-B)."""
        from vei.io.interaction import read_interaction
        from vei.io.scenario import write_scenario
        from vei.recon.auto_interp import ImplausibleSpeedWarning
        from vei.recon.pipeline import ReconstructionConfig
        from vei.recon.pipeline import reconstruct as run_reconstruct

        inflation: float | str = posterior_std_inflation
        if posterior_std_inflation != "calibrated":
            try:
                inflation = float(posterior_std_inflation)
            except ValueError:
                raise ConfigError(
                    "--posterior-std-inflation must be 'calibrated' or a number > 0, "
                    f"got {posterior_std_inflation!r}"
                ) from None
        config = ReconstructionConfig(
            rate_hz=rate_hz,
            interp=interp,
            noise_m=noise_m,
            margin_m=margin_m,
            ego_path=ego_path,
            posterior_std_inflation=inflation,
        )
        data = read_interaction(interaction)
        with warnings.catch_warnings():  # printed by print_report from the scenario's record
            warnings.simplefilter("ignore", ImplausibleSpeedWarning)
            scenario = run_reconstruct(data, config, threat=threat)
        out.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=".vei-map-", dir=out.parent) as work:
            writers = {}
            draw_roads = None
            if map_source is not None:
                from vei.maps import draw_roads as draw
                from vei.maps.scenario_map import add_map

                scenario, files, roads = add_map(scenario, Path(work), source=map_source)
                for name, path in files.items():
                    writers[name] = functools.partial(shutil.copyfile, path)
                draw_roads = functools.partial(draw, roads=roads)
            if figure:
                from vei.report.birdseye import plot_birdseye, save_figure

                fig = plot_birdseye(scenario, title=f"{scenario.id} ({interp})", roads=draw_roads)
                writers["birdseye.png"] = functools.partial(save_figure, fig)
                if interp == "kalman" and scenario.primary_threat is not None:
                    band = _uncertainty_figure(scenario, data)
                    if band is not None:
                        writers["uncertainty.png"] = functools.partial(save_figure, band)
            write_scenario(scenario, out, extra_files=writers)
        print_report(scenario, out)


def _uncertainty_figure(scenario, interaction):
    """Bird's-eye view of the primary rider's posterior: mean, 95 % band, 30 samples
    (seed 0), keyframes and, where the interaction has it, the ground truth. None when the
    rider has fewer than 2 keyframes."""
    import numpy as np

    from vei.errors import InputError
    from vei.geo.frame import LocalFrame
    from vei.recon.samples import rider_band, sample_rider
    from vei.report.uncertainty import plot_uncertainty

    try:
        band = rider_band(scenario)
        draws = sample_rider(scenario, 30, 0)
    except InputError:
        return None
    kf = scenario.keyframes[scenario.keyframes["agent_id"] == band.agent_id]
    gt_xy = None
    gt = interaction.ground_truth
    track_id = scenario.agent(band.agent_id).source_track_id
    if gt is not None and track_id is not None:
        rows = gt[gt["track_id"].astype(str) == str(track_id)]
        rows = rows[(rows["t_s"] >= band.t_s[0]) & (rows["t_s"] <= band.t_s[-1])]
        if len(rows):
            frame = LocalFrame.from_proj_string(scenario.projection)
            gx, gy = frame.to_xy(rows["lat_deg"].to_numpy(float), rows["lon_deg"].to_numpy(float))
            gt_xy = np.column_stack([gx, gy])
    ego = scenario.track("ego")
    ego_xy = ego[["x_m", "y_m"]].to_numpy(float)
    # Zoom where the rider's mean path comes closest to the ego's path.
    d = np.hypot(*(band.xy_m[:, None, :] - ego_xy[None, ::5, :]).transpose(2, 0, 1))
    zoom = band.xy_m[int(np.argmin(d.min(axis=1)))]
    return plot_uncertainty(
        agent_id=band.agent_id,
        t_s=band.t_s,
        mean_xy_m=band.xy_m,
        std_m=band.std_m,
        ego_xy_m=ego_xy,
        samples_xy_m=draws.xy_m,
        zoom_xy_m=zoom,
        keyframes_xy_m=kf[["x_m", "y_m"]].to_numpy(float),
        ground_truth_xy_m=gt_xy,
    )


def print_report(scenario, out: Path) -> None:
    """Print the per-track table and the summary of a reconstructed scenario to stdout."""
    from rich.table import Table

    from vei.cli.output import console as make_console

    console = make_console(width=160)
    rec = scenario.extra.get("reconstruction", {})
    errors = scenario.extra.get("reconstruction_error")
    err_by_agent = {r["agent_id"]: r for r in (errors or {}).get("tracks", [])}
    table = Table(title=f"reconstruction of {scenario.id}")
    for col in ("agent", "category", "keyframes", "method", "peak v [m/s]", "peak a [m/s2]"):
        table.add_column(col, justify="left" if col in ("agent", "category", "method") else "right")
    if errors is not None:
        for col in ("n gt", "RMSE [m]", "p95 [m]", "max [m]"):
            table.add_column(col, justify="right")
    for info in rec.get("tracks", []):
        row = [
            info["agent_id"] + (" *" if info["agent_id"] == scenario.primary_threat else ""),
            info["category"],
            str(info["n_keyframes"]),
            info["method"],
            f"{info['peak_speed_mps']:.2f}",
            f"{info['peak_accel_mps2']:.2f}",
        ]
        if errors is not None:
            e = err_by_agent.get(info["agent_id"])
            row += (
                [
                    str(e["n_samples"]),
                    f"{e['rmse_m']:.3f}",
                    f"{e['p95_m']:.3f}",
                    f"{e['max_m']:.3f}",
                ]
                if e
                else ["-", "-", "-", "-"]
            )
        table.add_row(*row)
    console.print(table)
    chosen = scenario.extra.get("threat", {}).get("chosen_by", "rule")
    console.print(
        f"primary threat (*): {scenario.primary_threat or 'none'}"
        + (" (chosen by --threat)" if chosen == "user" else "")
    )
    if errors is not None and errors.get("riders"):
        s = errors["riders"]
        console.print(
            f"riders (e-scooters + cyclists): {s['n_tracks']} tracks, mean RMSE {s['mean_rmse_m']:.3f} m, "
            f"max RMSE {s['max_rmse_m']:.3f} m, p95 {s['p95_m']:.3f} m, max error {s['max_error_m']:.3f} m"
        )
        if s.get("mean_rmse_sg_m") is not None:
            line = f"  vs ground truth denoised (1 s Savitzky-Golay): mean RMSE {s['mean_rmse_sg_m']:.3f} m"
            if s.get("coverage_sg") is not None:
                line += (
                    "; 95 % interval coverage in-sample (noise estimated and coverage "
                    f"scored on this recording) {100 * s['coverage_sg']:.1f} % (denoised), "
                    f"{100 * s['coverage_raw']:.1f} % (raw, with the keyframe noise); held-out "
                    "figure: docs/reconstruction.md, python -m benchmarks recon_accuracy"
                )
            console.print(line)
    noise = rec.get("noise")
    if noise:
        console.print(
            f"kalman noise ({noise['method']}, {noise['n_keyframes']} keyframes of {noise['n_tracks']} "
            f"tracks): sigma {noise['noise_m']:.3f} m, q {noise['accel_psd_m2ps3']:.3f} m^2/s^3, "
            f"posterior std x {noise.get('std_inflation', 1.0):.3f}"
        )
    ego_path = rec.get("ego_path")
    if ego_path:
        b, a = ego_path["before"], ego_path["after"]
        if b["max_abs_lat_accel_mps2"] is not None:
            console.print(
                f"ego path (kalman, moved {ego_path['shift_rms_m']:.3f} m RMS): max |lateral accel| "
                f"{b['max_abs_lat_accel_mps2']:.2f} -> {a['max_abs_lat_accel_mps2']:.2f} m/s^2, "
                f"RMS {b['rms_lat_accel_mps2']:.2f} -> {a['rms_lat_accel_mps2']:.2f} m/s^2, "
                f"max lateral jerk {b['max_lat_jerk_mps3']:.1f} -> {a['max_lat_jerk_mps3']:.1f} m/s^3"
            )
    auto = rec.get("auto_interp")
    if auto:
        console.print(
            f"interpolation auto (median keyframe spacing < {auto['dense_spacing_s']:g} s is "
            f"dense): smoothing for {len(auto['smoothing'])} dense track(s)"
            + (f" ({', '.join(auto['smoothing'])})" if auto["smoothing"] else "")
            + f", the paper's cubic for {len(auto['cubic'])}"
        )
    for w in rec.get("speed_warnings", []):
        typer.echo(f"warning: {w['message']}", err=True)
    dropped = rec.get("dropped_tracks", [])
    if dropped:
        console.print(
            f"left out (no {scenario.rate_hz:g} Hz sample inside their keyframe span): {', '.join(dropped)}"
        )
    map_info = scenario.extra.get("map")
    if map_info:
        console.print(
            f"map: {map_info['opendrive']} (OpenDRIVE {map_info['opendrive_version']}, "
            f"schema {'valid' if map_info['schema_valid'] else 'INVALID'}, source {map_info['source']}); "
            f"ego samples on a drivable lane: {100 * map_info['ego_on_drivable_share']:.1f} %"
        )
    n = scenario.trajectories["agent_id"].nunique()
    console.print(f"wrote {out} ({n} agents at {scenario.rate_hz:g} Hz)")
