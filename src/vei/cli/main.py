"""The ``vei`` console script: one typer app; command modules register themselves.

User errors (:class:`vei.errors.VeiError`) print one clear message and exit with code 2,
without a traceback. Heavy dependencies are imported inside the commands, so ``vei --help``
stays fast.
"""

from __future__ import annotations

import importlib
import sys

import typer

from vei import __version__
from vei.cli.output import console
from vei.errors import VeiError

#: Modules under vei.cli that define ``register(app)``; each owns its commands.
COMMAND_MODULES: tuple[str, ...] = (
    "datasets_cmd",
    "reconstruct_cmd",
    "maps_cmd",
    "sim_cmd",
    "export_cmd",
    "sweep_cmd",
    "catalogue_cmd",
    "calibrate_cmd",
    "v2x_cmd",
    "risk_cmd",
)

app = typer.Typer(
    name="vei",
    help="Vehicle-e-scooter interactions: reconstruct recordings, make them critical, "
    "close the loop with a collision-avoidance planner, and score every run.",
    no_args_is_help=True,
    add_completion=False,
    pretty_exceptions_enable=False,
)


def _version_callback(value: bool) -> None:
    if value:
        typer.echo(f"vei {__version__}")
        raise typer.Exit()


@app.callback()
def _root(
    version: bool = typer.Option(
        False,
        "--version",
        callback=_version_callback,
        is_eager=True,
        help="Print the version and exit.",
    ),
) -> None:
    """vei command-line interface."""


for _name in COMMAND_MODULES:
    importlib.import_module(f"vei.cli.{_name}").register(app)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the console script; returns the exit code.

    Usage errors are click's own (message + exit 2, in standalone mode); a VeiError raised
    by a command prints one clear line and returns 2; anything else is a bug and keeps its
    traceback. When stderr is not a terminal (a log, CI) a line names what the command is
    doing whenever it has printed nothing for 10 s (:func:`vei.io.progress.heartbeat`).
    Exit codes: :data:`EXIT_CODES`.
    """
    from rich.text import Text

    from vei.io.progress import heartbeat

    args = sys.argv[1:] if argv is None else argv
    command = " ".join(["vei", *[a for a in args[:2] if not a.startswith("-")]])
    try:
        with heartbeat(command):
            app(args=argv, prog_name="vei", standalone_mode=True)
    except SystemExit as exc:
        code = exc.code
        return code if isinstance(code, int) else (0 if code is None else 1)
    except VeiError as exc:
        message = Text.assemble(("error:", "bold red"), " ", str(exc))
        console(stderr=True).print(message, soft_wrap=True)
        return 2
    return 0


#: The exit codes of every command (documented in the README).
EXIT_CODES: dict[int, str] = {
    0: "success",
    1: "a bug (a traceback is printed; please report it)",
    2: "a user error: bad file, row, field or option (one message names it); nothing written",
    3: "partial success: a batch command finished, but some of its items failed (listed)",
    130: "interrupted (Ctrl-C); long jobs resume when run again",
}


if __name__ == "__main__":
    sys.exit(main())
