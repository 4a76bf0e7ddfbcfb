"""CARLA's port probe: a port that answers but is not CARLA is a clear error, never an abort.

Loopback servers only (127.0.0.1): garbage, HTTP, closing at once, silent, and a
well-formed msgpack-rpc answer. The CLI cases run ``vei`` in a child process, so that an
abort of the C++ client (exit 134) would show as such.
"""

from __future__ import annotations

import contextlib
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator

import pytest

from vei.errors import BackendError
from vei.sim.backends.carla import connect
from vei.sim.backends.carla_rpc import VERSION_REQUEST, probe_carla, unpack_one

HTTP_REPLY = b"HTTP/1.1 400 Bad Request\r\nContent-Length: 0\r\nConnection: close\r\n\r\n"


@contextlib.contextmanager
def loopback_server(handler: Callable[[socket.socket], None]) -> Iterator[int]:
    """A TCP server on 127.0.0.1 that runs ``handler(conn)`` for each connection; its port."""
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(8)
    srv.settimeout(0.2)
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                conn, _ = srv.accept()
            except (TimeoutError, OSError):
                continue
            with conn:
                with contextlib.suppress(OSError):
                    handler(conn)

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    try:
        yield srv.getsockname()[1]
    finally:
        stop.set()
        thread.join(2.0)
        srv.close()


def _garbage(conn: socket.socket) -> None:
    conn.recv(100)
    conn.sendall(b"\xc1\xc1 this is no msgpack-rpc \x00\xff")
    time.sleep(0.3)


def _http(conn: socket.socket) -> None:
    conn.recv(100)
    conn.sendall(HTTP_REPLY)


def _close_at_once(conn: socket.socket) -> None:
    pass


def _msgpack_error(conn: socket.socket) -> None:
    # a msgpack-rpc server that does not know 'version': [1, 0, "no such method", nil]
    conn.recv(100)
    conn.sendall(b"\x94\x01\x00\xaeno such method\xc0")


def _fake_carla(conn: socket.socket) -> None:
    data = conn.recv(100)
    assert data == VERSION_REQUEST
    conn.sendall(b"\x94\x01\x00\xc0\xa60.9.16")


def _deeply_nested(conn: socket.socket) -> None:
    """Arrays of one array nested 5,000 deep: decoding must stop, not recurse to the end."""
    conn.recv(100)
    conn.sendall(b"\x91" * 5000 + b"\xc0")


def test_nesting_is_bounded():
    assert unpack_one(b"\x91" * 32 + b"\xc0")[0] is not None
    with pytest.raises(ValueError, match="nested deeper"):
        unpack_one(b"\x91" * 5000 + b"\xc0")


def test_the_request_is_msgpack_rpc_for_version():
    assert unpack_one(VERSION_REQUEST) == ([0, 0, "version", []], len(VERSION_REQUEST))
    assert unpack_one(b"\x94\x01\x00\xc0\xa60.9.16")[0] == [1, 0, None, "0.9.16"]


def test_a_msgpack_rpc_answer_with_a_version_is_accepted():
    with loopback_server(_fake_carla) as port:
        assert probe_carla("127.0.0.1", port, 2.0) == "0.9.16"


@pytest.mark.parametrize(
    ("handler", "message"),
    [
        (_garbage, "does not speak CARLA's msgpack-rpc"),
        (_http, "not a CARLA server"),
        (_close_at_once, "closed the connection without answering"),
        (_msgpack_error, "not a CARLA server"),
        (_deeply_nested, "does not speak CARLA's msgpack-rpc"),
    ],
)
def test_a_port_that_is_not_carla_is_a_clear_error(handler, message):
    timeout = 2.0
    with loopback_server(handler) as port:
        start = time.monotonic()
        with pytest.raises(BackendError, match=message) as exc:
            connect("127.0.0.1", port, timeout)
        elapsed = time.monotonic() - start
    assert f"127.0.0.1:{port}" in str(exc.value)
    assert elapsed < timeout + 1.0


def _silent(conn: socket.socket) -> None:
    conn.recv(100)
    time.sleep(3.0)


@pytest.mark.parametrize(
    ("handler", "what"), [(_http, "not a CARLA server"), (_silent, "did not answer")]
)
def test_cli_exits_2_naming_host_port_within_the_timeout(handler, what, tmp_path):
    """`vei casestudy --backend carla --carla-timeout 1` against a port that is not CARLA:
    exit 2 (not 134), the message names host:port, the connection attempt ends in time."""
    from tests.sim.backends.conftest import crossing_scenario, write_straight_xodr
    from vei.io.scenario import write_scenario

    root = tmp_path / "scn"
    root.mkdir()
    write_straight_xodr(root / "map.xodr")
    write_scenario(crossing_scenario(root), root)
    code = (  # time the connection attempt itself (the run before it reads the scenario)
        "import sys, time\n"
        "import vei.sim.backends.carla as c\n"
        "orig = c.connect\n"
        "def timed(*a, **k):\n"
        "    t = time.monotonic()\n"
        "    try:\n"
        "        return orig(*a, **k)\n"
        "    finally:\n"
        "        print(f'elapsed={time.monotonic() - t:.3f}', flush=True)\n"
        "c.connect = timed\n"
        "from vei.cli.main import main\n"
        "sys.exit(main(sys.argv[1:]))\n"
    )
    with loopback_server(handler) as port:
        args = ["casestudy", str(root), "--out", str(tmp_path / "out"), "--time-shift", "0",
                "--backend", "carla", "--host", "127.0.0.1", "--port", str(port),
                "--carla-timeout", "1", "--no-figures"]  # fmt: skip
        proc = subprocess.run(
            [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=60
        )
    assert proc.returncode == 2, proc.stdout + proc.stderr
    assert f"127.0.0.1:{port}" in proc.stderr and what in proc.stderr
    assert "Traceback" not in proc.stderr
    elapsed = float(proc.stdout.strip().rsplit("elapsed=", 1)[1])
    assert elapsed < 1.0 + 1.0  # within the timeout + 1 s
