"""What a long command tells its user while it works: progress on a terminal, and a line at
least every 10 s when its output goes to a log or CI.

- :func:`activity`: one long step without a count (compiling the engine kernel, building a
  map). On a terminal a spinner with the elapsed time; otherwise a line when it starts, a
  line every ``interval_s`` while it runs and one when it ends.
- :func:`progress`: counted work (variants, encounters, tracks). On a terminal a rich bar;
  otherwise a line when it starts, one at most every ``interval_s`` as the count advances
  (and at least every ``interval_s`` while it does not) and one when it ends.
- :func:`heartbeat`: installed by the CLI when stderr is not a terminal: a line naming the
  current activity whenever nothing was written for ``interval_s``, so that no command is
  silent for longer whatever step it is in.

One heartbeat: off a terminal, only the outermost running activity or progress keeps a
ticker, and it writes only when nothing was written for ``interval_s``; an activity that
runs inside another (the kernel's compilation inside a step) says when it starts and ends
and is named in the outer one's line (``step 3/3: still running (90 s; compiling ...: 80
s)``), never a second stream of lines.

Every message is printed literally (no rich markup: user-provided names keep their
brackets). Lines go to stderr, so that a command's results on stdout stay clean.
"""

from __future__ import annotations

import contextlib
import sys
import threading
import time
from collections.abc import Iterator
from typing import IO, Any

#: Longest silence [s] of a command whose output is not a terminal (issue 28: "a line at
#: least every 10 s otherwise").
INTERVAL_S = 10.0

_lock = threading.Lock()
_current: list[tuple[str, float]] = []  # running activities (label, start), innermost last
_last_write = [time.monotonic()]


def _is_tty(stream: IO[str]) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


def _line(stream: IO[str], text: str) -> None:
    with _lock:
        stream.write(text + "\n")
        stream.flush()
        _last_write[0] = time.monotonic()


def _fmt_s(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds >= 10 else f"{seconds:.1f} s"


def note(message: str, *, stream: IO[str] | None = None) -> None:
    """Write one literal line to stderr (or ``stream``): a step's news, e.g. a level of
    the boundary search finished."""
    _line(stream if stream is not None else sys.stderr, message)


def current_activity() -> str | None:
    """The innermost running :func:`activity` / :func:`progress` label, if any."""
    with _lock:
        return _current[-1][0] if _current else None


def _push(label: str) -> bool:
    """Enter an activity; True when it is the outermost (it keeps the ticker)."""
    with _lock:
        _current.append((label, time.monotonic()))
        return len(_current) == 1


def _pop(label: str) -> None:
    with _lock:
        for i in range(len(_current) - 1, -1, -1):
            if _current[i][0] == label:
                del _current[i]
                break


def _inner_note() -> str:
    """'; <innermost nested activity>: N s' when one runs inside the outermost, else ''."""
    with _lock:
        if len(_current) < 2:
            return ""
        label, t0 = _current[-1]
    return f"; {label}: {_fmt_s(time.monotonic() - t0)}"


def _beat(stream: IO[str], text: Any, interval_s: float) -> None:
    """Write ``text()`` when nothing was written for ``interval_s`` (checked and written
    under the lock: two tickers never both write for one silence)."""
    if time.monotonic() - _last_write[0] < interval_s:
        return
    line = text()  # (takes the lock itself)
    with _lock:
        if time.monotonic() - _last_write[0] < interval_s:
            return
        stream.write(line + "\n")
        stream.flush()
        _last_write[0] = time.monotonic()


class _Ticker:
    """A daemon thread calling ``fn`` every ``interval_s`` until stopped."""

    def __init__(self, fn: Any, interval_s: float) -> None:
        self._stop = threading.Event()
        self._fn = fn
        self._interval = interval_s
        self._thread = threading.Thread(target=self._run, daemon=True, name="vei-progress")
        self._thread.start()

    def _run(self) -> None:
        while not self._stop.wait(self._interval):
            self._fn()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=1.0)


@contextlib.contextmanager
def activity(
    message: str,
    *,
    stream: IO[str] | None = None,
    interval_s: float = INTERVAL_S,
    enabled: bool = True,
) -> Iterator[None]:
    """Announce one long step: ``message`` (e.g. 'compiling the engine kernel') while the
    block runs, then its duration.

    Args:
        message: what is happening, printed literally.
        stream: where to write (default sys.stderr).
        interval_s: longest silence [s] off a terminal (> 0).
        enabled: False: print nothing (the block still runs).
    """
    if not enabled:
        yield
        return
    out = stream if stream is not None else sys.stderr
    t0 = time.monotonic()
    outermost = _push(message)
    try:
        if _is_tty(out):
            from rich.console import Console

            console = Console(file=out, markup=False, highlight=False)
            with console.status(message):
                yield
        else:
            _line(out, f"{message} ...")
            tick = None
            if outermost:  # a nested activity is named in the outer one's line instead

                def text() -> str:
                    el = _fmt_s(time.monotonic() - t0)
                    return f"{message}: still running ({el}{_inner_note()})"

                tick = _Ticker(lambda: _beat(out, text, interval_s), interval_s / 4)
            try:
                yield
            finally:
                if tick is not None:
                    tick.stop()
        _line(out, f"{message}: done in {_fmt_s(time.monotonic() - t0)}")
    finally:
        _pop(message)


class Progress:
    """Counted progress of one task (see :func:`progress`)."""

    def __init__(
        self, label: str, total: int, unit: str, done: int, out: IO[str], interval_s: float
    ) -> None:
        self.label, self.total, self.unit, self.done = label, int(total), unit, int(done)
        self._out = out
        self._interval = interval_s
        self._silent = False
        self._t0 = time.monotonic()
        self._printed = 0.0
        self._bar: Any = None
        self._task: Any = None

    def _text(self) -> str:
        el = time.monotonic() - self._t0
        text = f"{self.label}: {self.done}/{self.total} {self.unit}".rstrip()
        return f"{text} ({_fmt_s(el)})"

    def advance(self, n: int = 1) -> None:
        """``n`` more units done."""
        self.update(self.done + int(n))

    def update(self, done: int, total: int | None = None) -> None:
        """Set the count (and the total when it changed)."""
        self.done = int(done)
        if total is not None:
            self.total = int(total)
        if self._bar is not None:
            self._bar.update(self._task, completed=self.done, total=self.total)
        elif time.monotonic() - self._printed >= self._interval:
            self.print()

    def print(self) -> None:
        """Write the current count as a line (off a terminal; nothing when silent)."""
        if self._silent:
            return
        self._printed = time.monotonic()
        _line(self._out, self._text())

    def line(self) -> str:
        """The current count as text (what :meth:`print` writes); marks it printed."""
        self._printed = time.monotonic()
        return self._text()


@contextlib.contextmanager
def progress(
    label: str,
    total: int,
    *,
    unit: str = "",
    done: int = 0,
    enabled: bool | None = None,
    stream: IO[str] | None = None,
    interval_s: float = INTERVAL_S,
) -> Iterator[Progress]:
    """Report counted progress: ``with progress('sweep', n, unit='variants') as p:
    p.advance(k)``.

    Args:
        label: the task, printed literally. total: units of work. unit: their name.
        done: units already done (a resumed job).
        enabled: None = always (a bar on a terminal, lines otherwise); False = silent.
        stream: default sys.stderr. interval_s: longest silence [s] off a terminal.
    Returns:
        a :class:`Progress` (advance / update).
    """
    out = stream if stream is not None else sys.stderr
    rep = Progress(label, total, unit, done, out, interval_s)
    if enabled is False:
        rep._silent = True
        yield rep
        return
    outermost = _push(label)
    try:
        if _is_tty(out):
            from rich.console import Console
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                TextColumn,
                TimeElapsedColumn,
                TimeRemainingColumn,
            )
            from rich.progress import Progress as Bar

            console = Console(file=out, markup=False, highlight=False)
            cols = [TextColumn("{task.description}", markup=False), BarColumn()]
            cols += [MofNCompleteColumn(), TextColumn(unit, markup=False)]
            cols += [TimeElapsedColumn(), TimeRemainingColumn()]
            with Bar(*cols, console=console, transient=False) as bar:
                rep._bar = bar
                rep._task = bar.add_task(label, total=total, completed=done)
                yield rep
        else:
            rep.print()
            tick = None
            if outermost:  # inside another activity: counted lines only, no second ticker
                tick = _Ticker(
                    lambda: _beat(out, lambda: rep.line() + _inner_note(), interval_s),
                    interval_s / 4,
                )
            try:
                yield rep
            finally:
                if tick is not None:
                    tick.stop()
            rep.print()
    finally:
        _pop(label)


class _Stamped:
    """A text stream that remembers when it was last written to (for :func:`heartbeat`)."""

    def __init__(self, stream: IO[str]) -> None:
        self._stream = stream

    def write(self, s: str) -> int:
        _last_write[0] = time.monotonic()
        return self._stream.write(s)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._stream, name)


@contextlib.contextmanager
def heartbeat(
    command: str, *, interval_s: float = INTERVAL_S, stream: IO[str] | None = None
) -> Iterator[None]:
    """While the block runs: whenever neither stdout nor stderr was written for
    ``interval_s``, write '<command>: still working (<activity>, N s)' to stderr. Meant for
    output that is not a terminal (a log, CI); on a terminal it does nothing."""
    err = stream if stream is not None else sys.stderr
    if _is_tty(err):
        yield
        return
    t0 = time.monotonic()
    old_out, old_err = sys.stdout, sys.stderr
    sys.stdout, sys.stderr = _Stamped(old_out), _Stamped(old_err)  # type: ignore[assignment]
    _last_write[0] = t0

    def text() -> str:
        what = current_activity()
        return f"{command}: still working ({what + ', ' if what else ''}{_fmt_s(time.monotonic() - t0)})"

    tick = _Ticker(lambda: _beat(err, text, interval_s), interval_s / 4)
    try:
        yield
    finally:
        tick.stop()
        sys.stdout, sys.stderr = old_out, old_err
