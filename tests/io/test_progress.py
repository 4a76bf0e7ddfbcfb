"""What long work tells its user off a terminal: a line at least every interval, literal
text, counts that advance; and the kernel's compile announcement."""

from __future__ import annotations

import io
import re
import subprocess
import sys
import time

import pytest

from vei.io.progress import activity, current_activity, heartbeat, note, progress


def _lines(buf: io.StringIO) -> list[str]:
    return [line for line in buf.getvalue().splitlines() if line]


def test_activity_off_a_terminal_says_start_progress_and_end():
    buf = io.StringIO()
    with activity("building [the] map", stream=buf, interval_s=0.1):
        assert current_activity() == "building [the] map"
        time.sleep(0.35)
    lines = _lines(buf)
    assert lines[0] == "building [the] map ..."
    assert 2 <= sum("still running" in line for line in lines) <= 4
    assert re.fullmatch(r"building \[the\] map: done in \d\.\d s", lines[-1])
    assert current_activity() is None


def test_progress_off_a_terminal_prints_counts_at_least_every_interval():
    buf = io.StringIO()
    with progress("sweep", 10, unit="variants", done=2, stream=buf, interval_s=0.1) as p:
        for _ in range(4):
            time.sleep(0.12)
            p.advance(2)
    lines = _lines(buf)
    assert lines[0].startswith("sweep: 2/10 variants")
    assert lines[-1].startswith("sweep: 10/10 variants")
    assert len(lines) >= 4
    silent = io.StringIO()
    with progress("sweep", 10, stream=silent, enabled=False) as p:
        p.advance(10)
    assert silent.getvalue() == ""


def test_heartbeat_names_the_current_activity_when_nothing_was_written():
    buf = io.StringIO()
    with heartbeat("vei test", interval_s=0.1, stream=buf):
        with activity("compiling", stream=io.StringIO(), interval_s=60):
            time.sleep(0.3)
        print("something", file=sys.stderr)  # a write resets the silence
    beats = [line for line in _lines(buf) if line.startswith("vei test: still working")]
    assert beats and all("compiling" in b for b in beats)


def test_note_is_literal():
    buf = io.StringIO()
    note("[red]x[/red] Straße", stream=buf)
    assert buf.getvalue() == "[red]x[/red] Straße\n"


def test_the_kernel_says_when_it_compiles(tmp_path):
    """A missing compile stamp means a cold kernel: the first run announces the compilation
    (off a terminal: a line when it starts and one when it ends), then writes the stamp;
    the next run is warm and says nothing about it."""
    pytest.importorskip("numba")
    from vei.sim import kernel

    kernel._build()
    stamp = kernel._compiled_stamp(kernel._KERNEL)
    assert stamp is not None
    stamp.unlink(missing_ok=True)
    code = (
        "from vei.sim import kernel\n"
        "print('cold', kernel.is_cold(), flush=True)\n"
        "from vei.sim.warmup import ensure_compiled\n"
        "print('compiled', ensure_compiled(), flush=True)\n"
        "print('cold', kernel.is_cold(), flush=True)\n"
    )
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    assert first.stdout.split() == ["cold", "True", "compiled", "True", "cold", "False"]
    assert f"{kernel.COMPILE_MESSAGE} ..." in first.stderr
    assert f"{kernel.COMPILE_MESSAGE}: done in" in first.stderr
    assert stamp.is_file()
    second = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert second.stdout.split() == ["cold", "False", "compiled", "False", "cold", "False"]
    assert "compiling" not in second.stderr


def test_a_stamp_without_machine_code_is_cold(tmp_path, monkeypatch):
    """A stamp left behind in a cleared cache (numba's index files gone) is no warm kernel:
    the first run must still announce its compilation."""
    from vei.sim import kernel

    monkeypatch.setattr(kernel, "_WARM", False)
    monkeypatch.setattr(kernel, "available", lambda: True)
    monkeypatch.setattr(kernel, "_build", lambda: None)
    stamp = tmp_path / "loop.compiled"
    monkeypatch.setattr(kernel, "_compiled_stamp", lambda _k: stamp)
    stamp.write_text(kernel._compile_key() + "\n")
    assert kernel.is_cold()  # no index file of the kernel's machine code
    (tmp_path / "loop.kernel-87.py311.nbi").write_bytes(b"index")
    assert not kernel.is_cold()
    stamp.write_text("another machine\n")
    assert kernel.is_cold()
