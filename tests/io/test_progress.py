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
    """A missing compile stamp means a cold feature set: the first run announces the
    compilation (off a terminal: a line when it starts and one when it ends), then writes
    the stamp; the next run is warm and says nothing about it."""
    pytest.importorskip("numba")
    from vei.sim import kernel
    from vei.sim.kernel import cache

    base = kernel.Features()
    stamp = cache.stamp_path(kernel._cache_dir(), base.name)
    assert stamp is not None
    stamp.unlink(missing_ok=True)
    code = (
        "from vei.sim import kernel\n"
        "f = kernel.Features()\n"
        "print('cold', kernel.is_cold(f), flush=True)\n"
        "from vei.sim.warmup import ensure_compiled\n"
        "print('compiled', ensure_compiled(f), flush=True)\n"
        "print('cold', kernel.is_cold(f), flush=True)\n"
    )
    first = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert first.returncode == 0, first.stderr
    assert first.stdout.split() == ["cold", "True", "compiled", "True", "cold", "False"]
    assert f"{kernel.compile_message(base)} ..." in first.stderr
    assert f"{kernel.compile_message(base)}: done in" in first.stderr
    assert "(base;" in kernel.compile_message(base)
    assert stamp.is_file()
    second = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert second.stdout.split() == ["cold", "False", "compiled", "False", "cold", "False"]
    assert "compiling" not in second.stderr


def test_a_stamp_without_machine_code_is_cold(tmp_path, monkeypatch):
    """A stamp left behind in a cleared cache (numba's index files gone) is no warm kernel:
    the first run must still announce its compilation."""
    from vei.sim import kernel
    from vei.sim.kernel import cache

    monkeypatch.setattr(kernel, "_WARM", set())
    monkeypatch.setattr(kernel, "available", lambda: True)
    monkeypatch.setattr(kernel, "_cache_dir", lambda: tmp_path)
    base = kernel.Features()
    cache.mark_compiled(tmp_path, base.name)
    assert kernel.is_cold(base)  # no index file of the kernel's machine code
    for f in ("kernel", "variant"):
        (tmp_path / f"loop.{f}-87.py311.nbi").write_bytes(b"index")
    assert not kernel.is_cold(base)
    (tmp_path / "loop.compiled.base").write_text("another machine\n")
    assert kernel.is_cold(base)


def test_a_nested_activity_is_part_of_the_outer_line():
    """One heartbeat (issue 33): the compilation inside a step says when it starts and
    ends, and the step's own line names it while it runs; no second stream of lines."""
    buf = io.StringIO()
    with activity("step 3/3", stream=buf, interval_s=0.1):
        time.sleep(0.05)
        with activity("compiling", stream=buf, interval_s=0.1):
            time.sleep(0.45)
    lines = _lines(buf)
    ticks = [line for line in lines if "still running" in line]
    assert lines[0] == "step 3/3 ..." and lines[1] == "compiling ..."
    assert 2 <= len(ticks) <= 5
    assert all(t.startswith("step 3/3: still running (") for t in ticks)
    assert re.search(r"; compiling: 0\.\d s\)$", ticks[-1])
    assert lines[-2].startswith("compiling: done in")
    assert lines[-1].startswith("step 3/3: done in")
    # a count inside: its line names the compilation, which has no ticker of its own
    buf2 = io.StringIO()
    with progress("sweep", 4, stream=buf2, interval_s=0.1) as p:
        with activity("compiling", stream=buf2, interval_s=0.1):
            time.sleep(0.35)
        p.advance(4)
    lines2 = _lines(buf2)
    assert not any(line.startswith("compiling: still") for line in lines2)
    assert any(line.startswith("sweep: 0/4") and "; compiling:" in line for line in lines2)
