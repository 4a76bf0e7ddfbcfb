"""CLI commands (being written; see issues)."""

import typer


def register(app: typer.Typer) -> None:
    """Add this module's commands to the app."""
