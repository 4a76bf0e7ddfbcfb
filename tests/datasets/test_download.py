"""Downloader against a local HTTP server on loopback that serves the shared dataset files."""

from __future__ import annotations

import filecmp
import functools
import threading
import time
from collections.abc import Iterator
from http.server import SimpleHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import pytest

from vei.datasets.download import (
    DEFAULT_SCENARIOS,
    TRAFFICMONITORING_BASE_URL,
    DownloadError,
    download_trafficmonitoring,
    fetch_file,
)
from vei.datasets.trafficmonitoring import list_scenarios


class _Handler(SimpleHTTPRequestHandler):
    """Serves a folder; records request paths; can misbehave on chosen paths."""

    def __init__(self, *args, state: dict, **kwargs):
        self.state = state
        super().__init__(*args, **kwargs)

    def log_message(self, format, *args):  # noqa: A002 - keep the test output clean
        pass

    def do_GET(self):  # noqa: N802 - http.server API
        self.state["requests"].append(self.path)
        rule = self.state["faults"].get(self.path.rsplit("/", 1)[-1])
        if rule and rule["times"] > 0:
            rule["times"] -= 1
            kind = rule["kind"]
            if kind == "503":
                self.send_error(503, "try later")
                return
            if kind == "truncate":
                self.send_response(200)
                self.send_header("Content-Length", "1000")
                self.end_headers()
                self.wfile.write(b"frame_id,class_id\n")
                return
            if kind == "slow":
                time.sleep(rule.get("sleep", 1.0))
            if kind == "lfs":
                body = b"version https://git-lfs.github.com/spec/v1\noid sha256:00\nsize 12\n"
                self.send_response(200)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body)
                return
        super().do_GET()


@pytest.fixture
def server(trafficmonitoring_root) -> Iterator[dict]:
    state: dict = {"requests": [], "faults": {}}
    handler = functools.partial(_Handler, directory=str(trafficmonitoring_root), state=state)
    httpd = ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(
        target=httpd.serve_forever, kwargs={"poll_interval": 0.05}, daemon=True
    )
    thread.start()
    state["url"] = f"http://127.0.0.1:{httpd.server_address[1]}"
    try:
        yield state
    finally:
        httpd.shutdown()
        httpd.server_close()
        thread.join(timeout=5)


def _files(root: Path) -> list[str]:
    return sorted(p.relative_to(root).as_posix() for p in root.rglob("*") if p.is_file())


def test_default_url_is_the_pinned_commit():
    assert TRAFFICMONITORING_BASE_URL == (
        "https://raw.githubusercontent.com/jul095/TrafficMonitoring/641075e8d42337a46e8825fc3947f0b49b405b3b"
    )


def test_downloads_exactly_the_needed_files_equal_to_originals(
    server, trafficmonitoring_root, tmp_path
):
    # Every scenario the shared copy holds (nine of the dataset's fourteen), fetched by name.
    names = list_scenarios(trafficmonitoring_root)
    assert set(DEFAULT_SCENARIOS) <= set(names) and len(names) >= 9
    lines: list[str] = []
    dest = download_trafficmonitoring(
        tmp_path / "tm", base_url=server["url"], scenarios=names, progress=lines.append
    )
    got = _files(dest)
    assert got == [f for f in _files(trafficmonitoring_root) if f.startswith("data/")]
    assert len(got) == 3 * len(names)  # matching, camera trajectories, INS per scenario
    for rel in got:
        assert filecmp.cmp(dest / rel, trafficmonitoring_root / rel, shallow=False), rel
    assert list_scenarios(dest) == names
    # apostrophes are URL-quoted on the wire
    ins = [r for r in server["requests"] if "INSSOL" in r]
    assert len(ins) == len(names) and all("%27" in r and "'" not in r for r in ins)
    assert len(lines) == 3 * len(names) and all(line.startswith("got ") for line in lines)


def test_default_download_is_the_three_default_scenarios(server, tmp_path):
    dest = download_trafficmonitoring(tmp_path / "tm", base_url=server["url"])
    assert list_scenarios(dest) == list(DEFAULT_SCENARIOS)
    assert len(_files(dest)) == 3 * len(DEFAULT_SCENARIOS)


def test_resume_skips_complete_files(server, tmp_path):
    dest = tmp_path / "tm"
    download_trafficmonitoring(
        dest, base_url=server["url"], scenarios=["klinikum_01_marktkauf_geradeaus"]
    )
    assert len(server["requests"]) == 3
    traj = (
        dest
        / "data/measurements/videos/trajectory_output/klinikum_01_marktkauf_geradeaus_trajectories.csv"
    )
    traj.unlink()
    server["requests"].clear()
    lines: list[str] = []
    download_trafficmonitoring(
        dest,
        base_url=server["url"],
        scenarios=["klinikum_01_marktkauf_geradeaus"],
        progress=lines.append,
    )
    assert server["requests"] == [
        "/data/measurements/videos/trajectory_output/klinikum_01_marktkauf_geradeaus_trajectories.csv"
    ]
    assert sum(line.startswith("skip") for line in lines) == 2


def test_transient_errors_are_retried(server, trafficmonitoring_root, tmp_path):
    name = "klinikum_01_marktkauf_geradeaus"
    server["faults"][f"{name}_matching.csv"] = {"kind": "503", "times": 1}
    server["faults"][f"{name}_trajectories.csv"] = {"kind": "truncate", "times": 2}
    dest = download_trafficmonitoring(
        tmp_path / "tm", base_url=server["url"], scenarios=[name], backoff_s=0.01
    )
    rel = f"data/measurements/videos/trajectory_output/{name}_trajectories.csv"
    assert filecmp.cmp(dest / rel, trafficmonitoring_root / rel, shallow=False)
    assert len(server["requests"]) == 3 + 1 + 2
    assert not [p for p in dest.rglob(".*.tmp")]


def test_gives_up_after_retries_and_leaves_nothing(server, tmp_path):
    name = "klinikum_01_marktkauf_geradeaus"
    server["faults"][f"{name}_trajectories.csv"] = {"kind": "truncate", "times": 10}
    with pytest.raises(DownloadError, match="after 3 attempt"):
        download_trafficmonitoring(
            tmp_path / "tm", base_url=server["url"], scenarios=[name], retries=2, backoff_s=0.01
        )
    folder = tmp_path / "tm/data/measurements/videos/trajectory_output"
    assert list(folder.iterdir()) == []  # neither the file nor a temporary one


def test_timeout(server, tmp_path):
    server["faults"]["klinikum_01_marktkauf_geradeaus_matching.csv"] = {
        "kind": "slow",
        "times": 5,
        "sleep": 1.0,
    }
    url = server["url"] + "/data/measurements/matching/klinikum_01_marktkauf_geradeaus_matching.csv"
    t0 = time.perf_counter()
    with pytest.raises(DownloadError, match="timed out|Timeout"):
        fetch_file(url, tmp_path / "m.csv", timeout_s=0.2, retries=1, backoff_s=0.01)
    assert time.perf_counter() - t0 < 1.5
    assert not (tmp_path / "m.csv").exists()


def test_unknown_scenario_404_lists_known(server, tmp_path):
    with pytest.raises(DownloadError) as info:
        download_trafficmonitoring(
            tmp_path / "tm", base_url=server["url"], scenarios=["nope_01"], backoff_s=0.01
        )
    msg = str(info.value)
    assert "scenario 'nope_01' not found" in msg and "HTTP 404" in msg
    assert "marktkauf_04_audi_rechtsabbiegen" in msg
    assert server["requests"] == [
        "/data/measurements/matching/nope_01_matching.csv"
    ]  # 404: no retry


def test_lfs_pointer_is_refused(server, tmp_path):
    name = "klinikum_01_marktkauf_geradeaus"
    server["faults"][f"{name}_matching.csv"] = {"kind": "lfs", "times": 1}
    with pytest.raises(DownloadError, match="Git LFS pointer"):
        download_trafficmonitoring(tmp_path / "tm", base_url=server["url"], scenarios=[name])
    assert not (tmp_path / f"tm/data/measurements/matching/{name}_matching.csv").exists()


def test_connection_refused_is_a_clean_error(tmp_path):
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    with pytest.raises(DownloadError, match="after 2 attempt"):
        download_trafficmonitoring(
            tmp_path / "tm",
            base_url=f"http://127.0.0.1:{port}",
            retries=1,
            backoff_s=0.01,
            timeout_s=2,
        )
