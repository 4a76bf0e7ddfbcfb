"""``vei export commonroad SCENARIO --out DIR [--config NAME|FILE] [--time-shift auto|S] [--check]``.

Writes the recorded trajectories, or the built-in engine's run of a configuration (the
same loading and run as ``vei run``; this layer runs it and hands the trajectories to
:mod:`vei.export.commonroad`, which knows no engine), as a CommonRoad scenario. With
``--check``: reads the file back with commonroad-io (equal to what was written) and runs
CommonRoad's collision checker (commonroad-drivability-checker) on the ego's trajectory,
printing its first collision step next to vei's.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated, Any

import numpy as np
import typer


def _stem(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9_.-]+", "_", text).strip("._") or "vei_scenario"


def vei_first_contact_step(traj: Any, dt_s: float) -> int | None:
    """vei's first ego contact step of a run's time series (the ``collided`` latch of any
    road user), or None; the recorded trajectories (no such column) give None."""
    if "collided" not in traj:
        return None
    hit = traj[traj["collided"].astype(bool) & (traj["agent_id"] != "ego")]
    return None if hit.empty else int(round(float(hit["t_s"].min()) / dt_s))


def run_commonroad_export(
    scenario_dir: Path, out: Path, *, config: str | None, time_shift: str | None
) -> tuple[Path, dict[str, Any]]:
    """Export (see the module docstring); returns the .xml path and facts for printing
    (dt_s, vei_contact_step, ego footprint, name)."""
    from vei.export.commonroad import export_commonroad
    from vei.export.openscenario import timeseries_to_trajectories
    from vei.io.scenario import read_scenario

    scenario = read_scenario(scenario_dir)
    base = scenario.root if scenario.root is not None else Path(scenario_dir)
    rel = scenario.maps.get("opendrive")
    xodr = None if rel is None else base / rel
    contact = None
    tags: tuple[str, ...] = ("URBAN",)
    if config is None:
        traj = scenario.trajectories
        label = "the recorded trajectories"
        name = _stem(scenario.id)
    else:
        from vei.cli.sim_cmd import _load_case
        from vei.experiments.casestudy import run_casestudy

        case, run_cfg = _load_case(config)
        sim = run_cfg.sim if run_cfg is not None else None
        if time_shift is None:
            time_shift = run_cfg.time_shift if run_cfg is not None else "auto"
        result = run_casestudy(
            scenario, cases=[case], time_shift=time_shift, backend="builtin", sim=sim
        )
        frame = result.frame[result.frame["config"] == case.name]
        traj = timeseries_to_trajectories(result.frame, config=case.name)
        label = f"vei run of '{case.name}', rider time shift {result.time_shift_s:+.3f} s"
        name = _stem(f"{scenario.id}_{case.name}")
        tags = ("URBAN", "SIMULATED", "CRITICAL")
        contact = frame
    t = np.sort(traj["t_s"].unique())
    dt_s = float(np.round(np.median(np.diff(t)), 9)) if t.size > 1 else 0.05
    path = export_commonroad(
        traj, list(scenario.agents), out, xodr=xodr, dt_s=dt_s, name=name,
        description=f"vei scenario {scenario.id}: {label}", projection=scenario.projection,
        tags=tags,
    )  # fmt: skip
    ego = scenario.agent("ego")
    facts = {
        "dt_s": dt_s,
        "vei_contact_step": None if contact is None else vei_first_contact_step(contact, dt_s),
        "ego_length_m": ego.length_m,
        "ego_width_m": ego.width_m,
        "name": name,
    }
    return path, facts


def register(export_app: typer.Typer) -> None:
    """Add ``vei export commonroad`` to the ``vei export`` group."""

    @export_app.command("commonroad")
    def commonroad_cmd(
        scenario: Annotated[
            Path,
            typer.Argument(
                help="Scenario folder (scenario.json + trajectories.parquet + map.xodr)."
            ),
        ],
        out: Annotated[
            Path,
            typer.Option(
                "--out", help="Output folder (<name>.xml, <name>_ego.csv, <name>_obstacles.csv)."
            ),
        ],
        config: Annotated[
            str | None,
            typer.Option(
                "--config",
                help="Configuration to run with the built-in engine first (replay, normal, "
                "aggressive, normal-cap, aggressive-cap, replay-speed, or a config file); omit "
                "to export the recorded trajectories.",
            ),
        ] = None,
        time_shift: Annotated[
            str | None,
            typer.Option(
                "--time-shift", help="Rider time shift of --config runs: 'auto' or seconds."
            ),
        ] = None,
        check: Annotated[
            bool,
            typer.Option(
                "--check",
                help="Read the file back with commonroad-io and run CommonRoad's collision "
                "checker on the ego's trajectory (commonroad-drivability-checker).",
            ),
        ] = False,
    ) -> None:
        """Write SCENARIO (or a configuration's run of it) as a CommonRoad scenario."""
        from rich.console import Console

        path, facts = run_commonroad_export(scenario, out, config=config, time_shift=time_shift)
        con = Console(markup=False, highlight=False)
        con.print(f"wrote {path}", soft_wrap=True)
        if facts["vei_contact_step"] is not None:
            k = facts["vei_contact_step"]
            con.print(f"vei: first ego contact at step {k} (t = {k * facts['dt_s']:.2f} s)")
        elif config is not None:
            con.print("vei: no ego contact")
        if check:
            import pandas as pd

            from vei.export.commonroad import first_collision_step, read_commonroad

            scen, problems = read_commonroad(path)
            ego = pd.read_csv(path.with_name(f"{facts['name']}_ego.csv"))
            k = first_collision_step(scen, ego, facts["ego_length_m"], facts["ego_width_m"])
            where = (
                "no collision"
                if k is None
                else f"first collision at step {k} (t = {k * facts['dt_s']:.2f} s)"
            )
            con.print(f"CommonRoad ({len(scen.lanelet_network.lanelets)} lanelets, "
                      f"{len(scen.dynamic_obstacles)} obstacles, {len(problems.planning_problem_dict)} "
                      f"planning problem): {where}")  # fmt: skip
