"""The catalogue on a Ray cluster of two nodes on this machine (issue 35.3): ``ray start
--head`` and a second ``ray start --address`` with their own ports, one CPU each; the
catalogue run through it (RAY_ADDRESS) equals the local run row for row.

Teardown stops only the processes these two ``ray start`` calls spawned (found by the
cluster's own temporary folder in their command lines), never ``ray stop`` (which would stop
every Ray on the machine)."""

from __future__ import annotations

import json
import os
import shutil
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd
import pytest

from tests.catalogue.helpers import SMALL_SWEEP

pytestmark = pytest.mark.slow


def _free_ports(n: int) -> list[int]:
    socks = [socket.socket() for _ in range(n)]
    for s in socks:
        s.bind(("127.0.0.1", 0))
    ports = [s.getsockname()[1] for s in socks]
    for s in socks:
        s.close()
    return ports


def _spawned_by(marker: str) -> list[int]:
    """PIDs of this user's processes whose command line names ``marker``."""
    out = []
    for d in Path("/proc").iterdir():
        if not d.name.isdigit() or int(d.name) == os.getpid():
            continue
        try:
            if d.stat().st_uid != os.getuid():
                continue
            cmd = (d / "cmdline").read_bytes().replace(b"\0", b" ").decode(errors="replace")
        except OSError:
            continue
        if marker in cmd:
            out.append(int(d.name))
    return out


def _with_descendants(pids: list[int]) -> list[int]:
    """``pids`` and every process below them (Ray's workers rename themselves 'ray::...',
    so only their parents name the marker)."""
    out, todo = [], list(pids)
    while todo:
        p = todo.pop()
        if p in out:
            continue
        out.append(p)
        for task in Path(f"/proc/{p}/task").glob("*"):
            try:
                todo += [int(k) for k in (task / "children").read_text().split()]
            except OSError:
                pass
    return out


def _ray(args: list[str], env: dict[str, str]) -> subprocess.CompletedProcess:
    exe = Path(sys.executable).with_name("ray")
    return subprocess.run([str(exe), *args], env=env, capture_output=True, text=True, timeout=180)


def _node_args(ports: list[int]) -> list[str]:
    node, obj, lo, agent, metrics, runtime = ports
    return [
        "--num-cpus=1", "--object-store-memory=100000000", "--disable-usage-stats",
        f"--node-manager-port={node}", f"--object-manager-port={obj}",
        f"--min-worker-port={lo}", f"--max-worker-port={lo + 40}",
        f"--dashboard-agent-listen-port={agent}", f"--metrics-export-port={metrics}",
        f"--runtime-env-agent-port={runtime}",
    ]  # fmt: skip


@pytest.fixture(scope="module")
def two_nodes():
    pytest.importorskip("ray")
    # a short temporary folder (Ray's socket paths must stay under 107 characters)
    tmp = Path(tempfile.mkdtemp(prefix="vray", dir="/tmp"))
    # Ray 2.60's ``ray start --head`` turns token authentication on (the token in
    # ~/.ray/auth_token, generated once): the second node and the driver must send it
    env = {**os.environ, "RAY_DISABLE_IMPORT_WARNING": "1", "RAY_AUTH_MODE": "token"}
    env.pop("RAY_ADDRESS", None)
    # worker port ranges: 41 ports from a base picked free, far apart for the two nodes
    base = _free_ports(1)[0] % 20000 + 30000
    gcs, *head_ports = _free_ports(7)
    head_ports[2] = base
    node_ports = _free_ports(6)
    node_ports[2] = base + 100
    address = f"127.0.0.1:{gcs}"
    try:
        head = _ray(["start", "--head", f"--port={gcs}", "--node-ip-address=127.0.0.1",
                     f"--temp-dir={tmp}", "--include-dashboard=false",
                     *_node_args(head_ports)], env)  # fmt: skip
        if head.returncode != 0:
            pytest.skip(f"ray start --head failed here: {head.stderr[-1500:]}")
        node = _ray(["start", f"--address={address}", "--node-ip-address=127.0.0.1",
                     *_node_args(node_ports)], env)  # fmt: skip
        if node.returncode != 0:
            pytest.skip(f"the second ray node failed to start here: {node.stderr[-1500:]}")
        yield address
    finally:
        pids = _with_descendants(_spawned_by(str(tmp)))
        for sig in (signal.SIGTERM, signal.SIGKILL):
            for pid in pids:
                try:
                    os.kill(pid, sig)
                except ProcessLookupError:
                    pass
            time.sleep(2.0)
            pids = [p for p in pids if Path(f"/proc/{p}").exists()]
            if not pids:
                break
        shutil.rmtree(tmp, ignore_errors=True)


_PROBE = """
import json, time, ray
ray.init(log_to_driver=False, configure_logging=False)  # RAY_ADDRESS: the two-node cluster
alive = [n for n in ray.nodes() if n["Alive"]]

@ray.remote(num_cpus=1)
def where():
    time.sleep(1.0)
    return ray.get_runtime_context().get_node_id()

print(json.dumps({"cpus": [n["Resources"].get("CPU") for n in alive],
                  "ran_on": sorted(set(ray.get([where.remote(), where.remote()])))}))
"""


def _driver_env(address: str) -> dict[str, str]:
    """The environment of a driver of the two-node cluster (Ray reads its authentication
    mode when imported: a separate process, as ``vei catalogue`` runs on a cluster)."""
    env = {**os.environ, "RAY_ADDRESS": address, "RAY_AUTH_MODE": "token"}
    env["RAY_DISABLE_IMPORT_WARNING"] = "1"
    return env


def test_two_nodes_run_tasks_each(two_nodes):
    run = subprocess.run([sys.executable, "-c", _PROBE], env=_driver_env(two_nodes),
                         capture_output=True, text=True, timeout=300)  # fmt: skip
    assert run.returncode == 0, run.stderr[-2000:]
    doc = json.loads(run.stdout.strip().splitlines()[-1])
    assert doc["cpus"] == [1.0, 1.0]
    # two one-CPU tasks at once on two one-CPU nodes: one on each
    assert len(doc["ran_on"]) == 2


def test_catalogue_on_two_ray_nodes_equals_the_local_run(
    two_nodes, tmp_path, trafficmonitoring_root
):
    """``vei catalogue --engine ray`` on the cluster (RAY_ADDRESS) and ``--workers 1`` in
    one process: the same catalogue.parquet, row for row."""
    settings = tmp_path / "settings.yaml"
    settings.write_text(json.dumps({"sweep": SMALL_SWEEP, "risk": None, "figures": False}))
    recs = ["klinikum_01_marktkauf_geradeaus", "audi_08_klinikum_rechtsabbiegen_02"]
    vei = str(Path(sys.executable).with_name("vei"))

    def catalogue(out: Path, *extra: str, env: dict[str, str] | None = None) -> None:
        cmd = [vei, "catalogue", str(trafficmonitoring_root), "--out", str(out), "--settings",
               str(settings), "--n-variants", "8", "--no-report",
               *[a for r in recs for a in ("--recording", r)], *extra]  # fmt: skip
        run = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1200)
        assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]

    catalogue(tmp_path / "local", "--workers", "1")
    catalogue(tmp_path / "ray", "--engine", "ray", "--workers", "2", env=_driver_env(two_nodes))
    local = pd.read_parquet(tmp_path / "local" / "catalogue.parquet")
    on_ray = pd.read_parquet(tmp_path / "ray" / "catalogue.parquet")
    assert local["encounter_id"].nunique() >= 2 and len(local) == len(on_ray)
    pd.testing.assert_frame_equal(local, on_ray)
