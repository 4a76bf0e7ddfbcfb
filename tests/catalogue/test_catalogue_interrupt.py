"""`vei catalogue --workers 2` interrupted by Ctrl-C: says how to resume, exits 130, leaves no
worker; the rerun finishes the catalogue without running the done encounters again."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from tests.procs import children, default_sigint, kill_all, spawned_workers, wait_gone
from vei.catalogue.store import done_encounters

REPO = Path(__file__).resolve().parents[2]

pytestmark = [
    pytest.mark.skipif(
        not sys.platform.startswith("linux"), reason="reads worker processes from /proc"
    ),
    pytest.mark.slow,  # the slow tier (docs/testing.md): a whole catalogue with workers
]


def test_sigint_says_how_to_resume_and_leaves_no_worker(tmp_path, trafficmonitoring_root):
    out = tmp_path / "cat"
    cmd = [
        sys.executable, "-m", "vei.cli.main", "catalogue", str(trafficmonitoring_root),
        "--out", str(out), "--recording", "stadtmitte_12_audi_geradeaus_03",
        "--recording", "audi_08_klinikum_rechtsabbiegen_02", "--n-variants", "8",
        "--no-figures", "--no-report", "--workers", "2",
    ]  # fmt: skip
    proc = subprocess.Popen(  # SIGINT at its default action, whatever started pytest
        cmd,
        cwd=REPO,
        start_new_session=True,
        preexec_fn=default_sigint,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    everyone: list[int] = []
    deadline = time.monotonic() + 240
    try:
        while not done_encounters(out):
            if proc.poll() is not None:
                raise AssertionError(proc.stderr.read().decode())
            assert time.monotonic() < deadline, "no encounter finished in 240 s"
            everyone = sorted(set(everyone) | set(children(proc.pid)))
            time.sleep(0.05)
        workers = spawned_workers(proc.pid)
        everyone = sorted(set(everyone) | set(children(proc.pid)))
        assert len(workers) == 2
        os.killpg(proc.pid, signal.SIGINT)  # like Ctrl-C in a terminal: the whole group
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
        kill_all(everyone)
    err = " ".join(err.decode().split())
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    n_done = len(done_encounters(out))
    assert 1 <= n_done < 3
    line = f"interrupted: {n_done} encounter(s) done in {out}; run the same command again to resume"
    assert line in err, err
    assert not wait_gone(everyone, timeout_s=5.0)
    assert not (out / "catalogue.parquet").exists()

    rerun = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=600)
    assert rerun.returncode == 0, rerun.stderr
    assert f"{n_done} encounter(s) done by an earlier run; status complete" in " ".join(
        rerun.stdout.split()
    )
    assert len(done_encounters(out)) == 3
