"""``vei v2x study`` and ``vei v2x scenario``: the V2X case study (docs/v2x.md)."""

from __future__ import annotations

import sys
import threading
import time
from pathlib import Path
from typing import Annotated

import typer


def register(app: typer.Typer) -> None:
    """Add ``vei v2x study`` and ``vei v2x scenario``."""
    v2x_app = typer.Typer(
        help="V2X: riders' awareness messages to the car; the occluded-crossing case study.",
        no_args_is_help=True,
    )

    @v2x_app.command("scenario")
    def scenario(
        out: Annotated[Path, typer.Option("--out", help="Scenario folder to write (replaced).")],
    ) -> None:
        """Write the V2X study's (synthetic) occluded crossing as a scenario folder."""
        from vei.experiments.v2x_study import occluded_crossing
        from vei.io.scenario import write_scenario

        path = write_scenario(occluded_crossing(), out)
        typer.echo(f"wrote {path} (synthetic occluded crossing: docs/v2x.md)")

    @v2x_app.command("study")
    def study(
        out: Annotated[Path, typer.Option("--out", help="Output folder (resumes its sweeps).")],
        quick: Annotated[
            bool,
            typer.Option("--quick", help="Coarse grids (a first look in about a minute)."),
        ] = False,
        workers: Annotated[int, typer.Option("--workers", help="Sweep worker processes.")] = 1,
    ) -> None:
        """Perception alone vs perception + V2X on the occluded crossing (docs/v2x.md).

        The comparison over time shifts, sweeps of latency x packet delivery, penetration and
        GNSS error, figures (PNG and PDF) and summary.json.
        """
        from vei.experiments.v2x_run import run_study

        start = time.monotonic()
        phase = ["starting"]
        tty = sys.stderr.isatty()

        def log(msg: str) -> None:
            phase[0] = msg
            print(f"[{time.monotonic() - start:6.1f} s] {msg}", file=sys.stderr, flush=True)

        done = threading.Event()

        def heartbeat() -> None:  # a line every 10 s when no progress bar shows
            while not done.wait(10.0):
                print(f"[{time.monotonic() - start:6.1f} s] still working: {phase[0]}",
                      file=sys.stderr, flush=True)  # fmt: skip

        beat = threading.Thread(target=heartbeat, daemon=True)
        if not tty:
            beat.start()
        try:
            res = run_study(out, quick=quick, workers=workers, log=log, progress=tty)
        finally:
            done.set()
        s = res.summary
        typer.echo(f"occlusion window (perception alone collides): "
                   f"{res.window_s[0]:+.2f} .. {res.window_s[1]:+.2f} s time shift")  # fmt: skip
        for label, n in s["collisions_in_window"].items():
            typer.echo(f"  {label}: {n} of {s['shifts_in_window']} shifts collide")
        for path in res.figures:
            typer.echo(f"  figure {path}")
        typer.echo(f"wrote {res.out_dir / 'summary.json'}")

    app.add_typer(v2x_app, name="v2x")
