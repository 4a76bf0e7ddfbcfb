"""Worker processes die with their parent: WorkerPool alone, and the real `vei sweep` CLI.

Each test starts a real parent process, kills it (SIGKILL / SIGTERM) or interrupts it
(SIGINT), and looks the worker pids up in /proc: a pid that is gone, or a zombie waiting
for its new parent to reap it, is a worker that no longer runs.
"""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pandas as pd
import pytest

from tests.procs import (
    children,
    default_sigint,
    kill_all,
    python_sigint,
    running,
    spawned_workers,
    wait_gone,
)
from vei.sweep.workers import WorkerPool, set_parent_death_signal, worker_pool

REPO = Path(__file__).resolve().parents[2]

pytestmark = pytest.mark.skipif(
    not sys.platform.startswith("linux"), reason="reads worker processes from /proc"
)


POOL_SCRIPT = textwrap.dedent(
    """
    import sys, time
    from vei.sweep.workers import worker_pool

    if __name__ == "__main__":
        with worker_pool(2, pdeathsig=sys.argv[1] == "1", poll_s=0.2,
                         start_method=sys.argv[2]) as pool:
            futures = [pool.submit(time.sleep, 120) for _ in range(2)]
            print(" ".join(map(str, pool.pids)), flush=True)
            time.sleep(120)
    """
)


@pytest.mark.parametrize(
    ("sig", "pdeathsig", "method"),
    [
        (signal.SIGKILL, True, "spawn"),
        (signal.SIGTERM, True, "spawn"),
        (signal.SIGKILL, False, "spawn"),  # the portable watchdog alone
        (signal.SIGTERM, False, "spawn"),
        (signal.SIGKILL, True, "fork"),  # forked workers (vei sweep's, where safe)
        (signal.SIGKILL, False, "fork"),
    ],
)
def test_workers_end_when_the_parent_is_killed(tmp_path, sig, pdeathsig, method):
    script = tmp_path / "pool.py"
    script.write_text(POOL_SCRIPT)
    parent = subprocess.Popen(
        [sys.executable, str(script), "1" if pdeathsig else "0", method],
        cwd=tmp_path,
        stdout=subprocess.PIPE,
        stderr=subprocess.DEVNULL,
        text=True,
    )
    pids: list[int] = []
    try:
        pids = [int(p) for p in parent.stdout.readline().split()]
        assert len(pids) == 2 and all(running(p) for p in pids)
        assert sorted(pids) == sorted(spawned_workers(parent.pid))
        parent.send_signal(sig)
        parent.wait(timeout=10)
        assert parent.returncode == -sig
        left = wait_gone(pids, timeout_s=3.0)
        assert not left, f"workers {left} outlived their parent (signal {sig})"
    finally:
        parent.kill()
        parent.wait()
        kill_all(pids)


def test_pool_starts_every_worker_once_and_they_ignore_sigint():
    # workers started while SIGINT is handled here, so that their ignoring it is their own
    with python_sigint(), worker_pool(2) as pool:
        assert len(pool.pids) == 2 and len(set(pool.pids)) == 2
        for p in pool.pids:
            os.kill(p, signal.SIGINT)
        time.sleep(0.3)
        assert all(running(p) for p in pool.pids)
        # the same two processes serve every task: no start per task
        served = {f.result() for f in [pool.submit(os.getpid) for _ in range(20)]}
        assert served <= set(pool.pids)
        assert {f.result() for f in [pool.submit(pow, 3, 4)]} == {81}
        pids = list(pool.pids)
    assert not wait_gone(pids, timeout_s=5.0)


def test_an_exception_in_the_block_kills_the_workers_at_once():
    t0 = time.monotonic()
    with pytest.raises(KeyboardInterrupt), WorkerPool(2) as pool:
        pids = list(pool.pids)
        pool.submit(time.sleep, 60)
        raise KeyboardInterrupt
    assert not wait_gone(pids, timeout_s=3.0)
    assert time.monotonic() - t0 < 20  # the 60 s task was not waited for


def test_a_launched_pool_starts_every_worker_without_waiting():
    with WorkerPool(2, wait_ready=False) as pool:
        assert pool.pids == ()  # not waited for
        procs = list(pool._processes.values())
        assert len(procs) == 2  # but both started, from this thread
        assert pool.submit(pow, 2, 5).result() == 32
        served = {pool.submit(os.getpid).result() for _ in range(8)}
        assert served <= {p.pid for p in procs}
    assert not wait_gone([p.pid for p in procs], timeout_s=5.0)


def test_bad_arguments_and_prctl_on_linux():
    with pytest.raises(ValueError, match="workers"):
        WorkerPool(0)
    with pytest.raises(ValueError, match="poll_s"):
        WorkerPool(1, poll_s=0)
    with pytest.raises(ValueError, match="start_method"):
        WorkerPool(1, start_method="forkserver")
    with worker_pool(1) as pool:  # asked in a worker, never in the test process itself
        assert pool.submit(set_parent_death_signal, signal.SIGKILL).result() is True


# --- the real CLI --------------------------------------------------------------------------


@pytest.fixture(scope="module")
def demo_scenario(tmp_path_factory) -> Path:
    """The synthetic demo interaction (vei demo's data), reconstructed into a scenario."""
    from vei.experiments.demo_data import demo_interaction
    from vei.io.scenario import write_scenario
    from vei.recon.pipeline import reconstruct

    folder = tmp_path_factory.mktemp("demo") / "scenario"
    write_scenario(reconstruct(demo_interaction()), folder)
    return folder


@pytest.fixture(scope="module")
def spec_path(tmp_path_factory) -> Path:
    """A 20 x 20 grid (400 variants) over time shift and cruise speed: 16 chunks of 25."""
    path = tmp_path_factory.mktemp("spec") / "sweep.yaml"
    path.write_text(
        "design: grid\nbase: normal\nparameters:\n"
        "  time_shift_s: {min: -3.0, max: 3.0, num: 20}\n"
        "  ego.cruise_speed_mps: {min: 3.0, max: 9.0, num: 20}\n"
    )
    return path


def _sweep_cmd(scenario: Path, spec: Path, out: Path) -> list[str]:
    return [
        sys.executable, "-m", "vei.cli.main", "sweep", str(scenario), "--spec", str(spec),
        "--out", str(out), "--workers", "3", "--chunk-size", "25", "--no-progress",
    ]  # fmt: skip


def _start_and_wait_for_parts(cmd: list[str], out: Path, n_parts: int) -> tuple:
    """Start the CLI in its own session, with SIGINT at its default action (whatever started
    pytest); once ``n_parts`` part files exist, return (process, its worker pids, all its
    child pids)."""
    proc = subprocess.Popen(
        cmd,
        cwd=REPO,
        start_new_session=True,
        preexec_fn=default_sigint,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    deadline = time.monotonic() + 120
    workers: list[int] = []
    while len(list((out / "parts").glob("part-*.parquet"))) < n_parts:
        if proc.poll() is not None:
            raise AssertionError(proc.stderr.read().decode())
        assert time.monotonic() < deadline, "the sweep wrote no parts in 120 s"
        workers = spawned_workers(proc.pid) or workers
        time.sleep(0.05)
    workers = spawned_workers(proc.pid) or workers
    return proc, workers, sorted(set(workers) | set(children(proc.pid)))


@pytest.mark.slow
def test_vei_sweep_killed_leaves_no_worker_and_resumes(demo_scenario, spec_path, tmp_path):
    from vei.sweep.run import done_ids, read_results, run_sweep
    from vei.sweep.spec import load_spec

    out = tmp_path / "killed"
    cmd = _sweep_cmd(demo_scenario, spec_path, out)
    proc, workers, everyone = _start_and_wait_for_parts(cmd, out, 2)
    try:
        assert len(workers) == 2  # --workers 3: the sweep's process computes too
        os.kill(proc.pid, signal.SIGKILL)  # the parent only, not its process group
        proc.wait(timeout=30)
        assert proc.returncode == -signal.SIGKILL
        left = wait_gone(everyone, timeout_s=5.0)
        assert not left, f"processes {left} of the killed sweep still run"
    finally:
        proc.kill()
        kill_all(everyone)
    assert not (out / "results.parquet").exists()
    n_done = len(done_ids(out))
    assert 50 <= n_done < 400

    rerun = subprocess.run(cmd, cwd=REPO, capture_output=True, text=True, timeout=300)
    assert rerun.returncode == 0, rerun.stderr
    assert re.search(rf"done before \(resumed\)\s*│\s*{n_done}\s", rerun.stdout), rerun.stdout
    whole = run_sweep(
        demo_scenario, load_spec(spec_path), tmp_path / "whole", chunk_size=100, progress=False
    )
    assert whole.n_run == 400
    a, b = read_results(out), read_results(tmp_path / "whole")
    assert len(a) == 400 and a["variant_id"].is_unique
    pd.testing.assert_frame_equal(a, b)


@pytest.mark.slow
def test_vei_sweep_sigint_says_how_to_resume(demo_scenario, spec_path, tmp_path):
    from vei.sweep.run import done_ids

    out = tmp_path / "interrupted"
    cmd = _sweep_cmd(demo_scenario, spec_path, out)
    proc, workers, everyone = _start_and_wait_for_parts(cmd, out, 1)
    try:
        assert len(workers) == 2
        os.killpg(proc.pid, signal.SIGINT)  # like Ctrl-C in a terminal: the whole group
        _, err = proc.communicate(timeout=60)
    finally:
        proc.kill()
        kill_all(everyone)
    err = err.decode()
    assert proc.returncode == 130, err
    assert "Traceback" not in err
    n_parts = len(list((out / "parts").glob("part-*.parquet")))
    n_done = len(done_ids(out))
    assert n_parts < 16 and not (out / "results.parquet").exists()
    line = (
        f"interrupted: {n_parts} chunk(s) done ({n_done} of 400 variants) in {out}; "
        "run the same command again to resume"
    )
    assert line in " ".join(err.split()), err
    assert not wait_gone(everyone, timeout_s=5.0)


def test_a_failing_initializer_is_an_error_and_leaves_no_worker():
    from concurrent.futures.process import BrokenProcessPool

    t0 = time.monotonic()
    with pytest.raises(BrokenProcessPool), WorkerPool(2, initializer=int, initargs=("x",)):
        pass  # int("x") raises ValueError in each worker
    assert time.monotonic() - t0 < 30
    assert not wait_gone(spawned_workers(os.getpid()), timeout_s=5.0)


def test_fork_is_safe_only_with_one_thread_and_no_threading_layer():
    import threading

    from vei.sweep.workers import fork_is_safe

    code = (
        "import sys\n"
        "from vei.sweep.workers import fork_is_safe\n"
        "a = fork_is_safe()\n"
        "import numpy as np\n"
        "from vei.sim.engine import simulate\n"
        "from vei.sim.testing import crossing_scenario\n"
        "from vei.sim.state import prepare_scenario, VariantParams\n"
        "from vei.config import case_preset\n"
        "arrays = prepare_scenario(crossing_scenario())\n"
        "simulate(arrays, VariantParams.from_case(case_preset('normal-cap'), arrays, 2),\n"
        "         record='none', kernel='numba')\n"  # numba's threads now run
        "print(a, fork_is_safe())\n"
    )
    run = subprocess.run([sys.executable, "-c", code], cwd=REPO, capture_output=True,
                         text=True, timeout=300, check=False)  # fmt: skip
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == ["True", "False"]
    stop = threading.Event()
    other = threading.Thread(target=stop.wait)
    other.start()
    try:
        assert not fork_is_safe()  # a second thread runs here
    finally:
        stop.set()
        other.join()
