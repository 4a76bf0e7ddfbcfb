"""Processes seen through /proc (Linux): which run, which are whose children. For tests that
kill a parent and look for what it leaves behind; psutil is not a dependency."""

from __future__ import annotations

import contextlib
import os
import signal
import time
from collections.abc import Iterator
from pathlib import Path


def state(pid: int) -> str | None:
    """The process state letter of ``pid`` (R, S, Z, ...), None when there is no such pid."""
    try:
        stat = Path(f"/proc/{pid}/stat").read_text()
    except OSError:
        return None
    return stat.rsplit(")", 1)[1].split()[0]


def running(pid: int) -> bool:
    """Whether ``pid`` exists and is not a zombie (a zombie no longer runs any code)."""
    return state(pid) not in (None, "Z", "X")


def children(pid: int) -> list[int]:
    """Pids whose parent is ``pid`` (running ones only)."""
    found = []
    for entry in Path("/proc").iterdir():
        if not entry.name.isdigit():
            continue
        try:
            stat = (entry / "stat").read_text()
        except OSError:
            continue
        fields = stat.rsplit(")", 1)[1].split()
        if int(fields[1]) == pid and fields[0] not in ("Z", "X"):
            found.append(int(entry.name))
    return found


def wait_gone(pids: list[int], timeout_s: float) -> list[int]:
    """Poll until none of ``pids`` runs; returns those still running after ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while True:
        left = [p for p in pids if running(p)]
        if not left or time.monotonic() > deadline:
            return left
        time.sleep(0.05)


def kill_all(pids: list[int]) -> None:
    """SIGKILL each pid that still exists (clean-up after a failed test)."""
    for p in pids:
        try:
            os.kill(p, signal.SIGKILL)
        except OSError:
            pass


def cmdline(pid: int) -> str:
    """The command line of ``pid`` (arguments joined by spaces; '' when it is gone)."""
    try:
        return Path(f"/proc/{pid}/cmdline").read_bytes().replace(b"\0", b" ").decode()
    except OSError:
        return ""


def default_sigint() -> None:
    """``preexec_fn`` of a child that must see Ctrl-C: SIGINT restored to its default action.

    A process started from a background job without job control (``cmd &`` in a script,
    ``nohup``, some CI runners) inherits SIGINT as ignored, and Python then installs no
    KeyboardInterrupt handler. vei rightly keeps such an inherited "ignore" (that is what
    ``nohup`` asks for), so a test of vei's Ctrl-C handling starts its child with the
    default disposition, whatever started pytest. (Python's ``restore_signals`` resets
    SIGPIPE, SIGXFZ and SIGXFSZ only.)"""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


@contextlib.contextmanager
def python_sigint() -> Iterator[None]:
    """Within the block, this process handles SIGINT as Python does by default (raising
    KeyboardInterrupt), so that the children it starts see SIGINT at its default action
    even where pytest inherited it as ignored (see :func:`default_sigint`)."""
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, before)


def spawned_workers(pid: int) -> list[int]:
    """Children of ``pid`` that are pool workers: started by multiprocessing's spawn method,
    or forked (the same command line as ``pid``; multiprocessing's resource tracker is
    spawned with its own)."""
    mine = cmdline(pid)
    return [c for c in children(pid) if "spawn_main" in (line := cmdline(c)) or line == mine]
