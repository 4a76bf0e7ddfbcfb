"""A protocol probe for CARLA's RPC port, so that the C++ client never aborts the process.

CARLA's server speaks msgpack-rpc (rpclib): a request ``[0, msgid, method, params]``, a
response ``[1, msgid, error, result]``, each one msgpack object on the TCP stream. The
C++ client in the ``carla`` package throws from a background thread (and the process
aborts: exit 134, ``clmdep_msgpack type_error``) when something else answers. Before
vei hands a port to that client, :func:`probe_carla` sends the request CARLA's own
``client.get_server_version()`` sends (method ``version``) from Python and accepts the
port only if a well-formed msgpack-rpc response with a version string comes back within
the timeout; anything else is a :class:`~vei.errors.BackendError` naming host:port.
"""

from __future__ import annotations

import socket
import struct
import time
from typing import Any

from vei.errors import BackendError

#: The probe's request: msgpack of [0, 0, "version", []].
VERSION_REQUEST = b"\x94\x00\x00\xa7version\x90"
_MAX_REPLY_BYTES = 1 << 16
#: Deepest nesting of arrays / maps accepted in a reply (a version reply nests 2 deep).
_MAX_DEPTH = 32


class _Incomplete(Exception):
    """More bytes are needed to finish the msgpack object."""


def _need(buf: bytes, pos: int, n: int) -> None:
    if pos + n > len(buf):
        raise _Incomplete


def unpack_one(buf: bytes, pos: int = 0, depth: int = 0) -> tuple[Any, int]:
    """Decode one msgpack object from ``buf`` at ``pos``; (object, next position).

    Supports nil, booleans, integers, floats, str, bin, arrays and maps (the types of
    msgpack-rpc messages), nested at most ``_MAX_DEPTH`` deep. Raises ValueError on bytes
    that are not such msgpack (or nest deeper), and the private _Incomplete when ``buf``
    ends inside the object.
    """
    if depth > _MAX_DEPTH:
        raise ValueError(f"msgpack nested deeper than {_MAX_DEPTH} levels")
    _need(buf, pos, 1)
    b = buf[pos]
    pos += 1
    if b <= 0x7F:
        return b, pos
    if b >= 0xE0:
        return b - 0x100, pos
    if 0xA0 <= b <= 0xBF:
        return _str(buf, pos, b & 0x1F)
    if 0x90 <= b <= 0x9F:
        return _array(buf, pos, b & 0x0F, depth)
    if 0x80 <= b <= 0x8F:
        return _map(buf, pos, b & 0x0F, depth)
    if b == 0xC0:
        return None, pos
    if b in (0xC2, 0xC3):
        return b == 0xC3, pos
    fixed = {
        0xCC: ">B", 0xCD: ">H", 0xCE: ">I", 0xCF: ">Q",
        0xD0: ">b", 0xD1: ">h", 0xD2: ">i", 0xD3: ">q",
        0xCA: ">f", 0xCB: ">d",
    }  # fmt: skip
    if b in fixed:
        size = struct.calcsize(fixed[b])
        _need(buf, pos, size)
        return struct.unpack_from(fixed[b], buf, pos)[0], pos + size
    lengths = {0xD9: ">B", 0xDA: ">H", 0xDB: ">I", 0xC4: ">B", 0xC5: ">H", 0xC6: ">I"}
    lengths.update({0xDC: ">H", 0xDD: ">I", 0xDE: ">H", 0xDF: ">I"})
    if b in lengths:
        size = struct.calcsize(lengths[b])
        _need(buf, pos, size)
        n = struct.unpack_from(lengths[b], buf, pos)[0]
        pos += size
        if b in (0xD9, 0xDA, 0xDB):
            return _str(buf, pos, n)
        if b in (0xC4, 0xC5, 0xC6):
            _need(buf, pos, n)
            return bytes(buf[pos : pos + n]), pos + n
        if b in (0xDC, 0xDD):
            return _array(buf, pos, n, depth)
        return _map(buf, pos, n, depth)
    raise ValueError(f"byte 0x{b:02x} starts no msgpack-rpc value")


def _str(buf: bytes, pos: int, n: int) -> tuple[str, int]:
    _need(buf, pos, n)
    try:
        return bytes(buf[pos : pos + n]).decode("utf-8"), pos + n
    except UnicodeDecodeError as exc:
        raise ValueError("invalid UTF-8 in a msgpack string") from exc


def _array(buf: bytes, pos: int, n: int, depth: int) -> tuple[list, int]:
    if n > _MAX_REPLY_BYTES:
        raise ValueError("implausibly long msgpack array")
    out = []
    for _ in range(n):
        item, pos = unpack_one(buf, pos, depth + 1)
        out.append(item)
    return out, pos


def _map(buf: bytes, pos: int, n: int, depth: int) -> tuple[dict, int]:
    if n > _MAX_REPLY_BYTES:
        raise ValueError("implausibly long msgpack map")
    out = {}
    for _ in range(n):
        key, pos = unpack_one(buf, pos, depth + 1)
        val, pos = unpack_one(buf, pos, depth + 1)
        out[repr(key)] = val
    return out, pos


def probe_carla(host: str, port: int, timeout_s: float) -> str:
    """Ask host:port for CARLA's version over msgpack-rpc; the version string.

    Args:
        host, port: the server's RPC endpoint. timeout_s: for connecting and answering [s].

    Raises:
        BackendError: nothing listens (at once), no answer within the timeout, the peer
            closes the connection, or the answer is not a msgpack-rpc response with a
            version string (e.g. an HTTP server, garbage). The message names host:port.
    """
    where = f"{host}:{port}"
    start = time.monotonic()
    hint = (
        "Start CARLA (CarlaUE4.sh / CarlaUnreal.sh) or point vei at one with --host/--port "
        "or VEI_CARLA_HOST/VEI_CARLA_PORT."
    )
    try:
        sock = socket.create_connection((host, port), timeout=timeout_s)
    except OSError as exc:
        raise BackendError(
            f"no CARLA server at {where}: {exc.strerror or exc} "
            f"(after {time.monotonic() - start:.2f} s). {hint}"
        ) from exc
    buf = b""
    with sock:
        try:
            sock.sendall(VERSION_REQUEST)
            while True:
                left = timeout_s - (time.monotonic() - start)
                if left <= 0:
                    raise TimeoutError
                sock.settimeout(left)
                chunk = sock.recv(4096)
                if not chunk:
                    raise BackendError(
                        f"the server at {where} closed the connection without answering CARLA's "
                        f"version request{_shown(buf)}: not a CARLA server. {hint}"
                    )
                buf += chunk
                try:
                    reply, _ = unpack_one(buf)
                except _Incomplete:
                    if len(buf) > _MAX_REPLY_BYTES:
                        raise ValueError("reply too long") from None
                    continue
                break
        except TimeoutError as exc:
            raise BackendError(
                f"the CARLA server at {where} did not answer within {timeout_s:g} s{_shown(buf)}"
            ) from exc
        except ConnectionError as exc:  # reset / aborted / broken pipe: it hung up on us
            raise BackendError(
                f"the server at {where} closed the connection without answering CARLA's "
                f"version request ({exc.strerror or exc}){_shown(buf)}: not a CARLA server. {hint}"
            ) from exc
        except ValueError as exc:
            raise BackendError(
                f"the server at {where} does not speak CARLA's msgpack-rpc ({exc}){_shown(buf)}. {hint}"
            ) from exc
        except OSError as exc:
            raise BackendError(
                f"the connection to {where} failed while asking for CARLA's version: {exc}. {hint}"
            ) from exc
    ok = (
        isinstance(reply, list)
        and len(reply) == 4
        and reply[0] == 1
        and reply[1] == 0
        and reply[2] is None
        and isinstance(reply[3], str)
    )
    if not ok:
        raise BackendError(
            f"the server at {where} answered CARLA's version request with {reply!r:.120}, "
            f"not a msgpack-rpc response carrying a version: not a CARLA server. {hint}"
        )
    return reply[3]


def _shown(buf: bytes) -> str:
    return f" (it sent {buf[:40]!r})" if buf else ""
