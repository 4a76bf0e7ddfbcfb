"""The consoles every command prints through: user-provided text stays literal.

rich reads ``[...]`` in a string as markup by default, so a folder named
``/data/runs[final]`` would print as ``/data/runs`` and a YAML error's ``expected ','
or ']'`` would lose its bracket. These consoles have markup (and highlighting, emoji codes)
off: every string, whether a table cell, a path or an error message, is printed as
written; styles are given as ``style=`` arguments, never as markup.
"""

from __future__ import annotations

import sys

from rich.console import Console


def console(*, stderr: bool = False, width: int = 200) -> Console:
    """A console on stdout (or stderr) that prints every string literally.

    Args:
        stderr: write to stderr instead of stdout.
        width: line width when the stream is not a terminal (logs keep wide tables whole);
            on a terminal the terminal's width, with long lines soft-wrapped.
    """
    stream = sys.stderr if stderr else sys.stdout
    kw = {"stderr": stderr, "markup": False, "highlight": False, "emoji": False}
    try:
        tty = stream.isatty()
    except (AttributeError, ValueError):
        tty = False
    return Console(soft_wrap=True, **kw) if tty else Console(width=width, **kw)
