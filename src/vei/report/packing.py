"""Packing an encounter's report data small (issue 35.3: 10^4 encounters under 50 MB).

An encounter's data (:func:`vei.catalogue.report_data.encounter_data`) is mostly numeric
arrays: recorded tracks, the replay of every case-study configuration, map outlines. Each
such array is quantized to a fixed step (:data:`STEPS`: positions to 1 cm, headings to
1 mrad, speeds to 1 cm/s, times and TTC to 1 ms; far below what a figure shows), written
as integers about their middle or as differences of first or second order, whichever is
smallest (smooth motion: second differences of a few units), in the narrowest of Int8 / Int16 / Int32, and the whole encounter (the JSON of
what is left with a placeholder per array, then the arrays' bytes) is deflated (zlib).
:func:`script` writes the deflated bytes as they are into the string literal of the
encounter's script, which the page loads as ``x-user-defined`` text (one character per
byte; base64 would add a third). The page inflates them with the browser's
``DecompressionStream`` and rebuilds the arrays (``report.js``: ``unpack``);
:func:`unpack` / :func:`read_script` here are the reference decoder (tests). A replay
configuration's ``ttc`` (the TTC at the replay's times) is left out where it is the full
series ``ttc_full`` at those times (``ttc_from_full``: rebuilt on unpacking); the sweep's
variant markers are stored in order of their x, their flags as 0 / 1.

Payload layout (after inflating): ``uint32`` little-endian length L of the JSON text, the
JSON text (UTF-8) ``{"data": ..., "arrays": [[n, width, scale, order, origin, nan_runs],
...], "v": 2}`` in which packed array k is ``{"$a": k}``, then the arrays' bytes one after
the other in the order of ``arrays``; array k's values are ``(origin + cumsum^order(d)) /
scale`` with d its n little-endian signed integers of ``width`` bytes, None over
``nan_runs`` ([[start, length], ...]).
"""

from __future__ import annotations

import json
import re
import struct
import zlib
from typing import Any

import numpy as np

#: Quantization per array name, as 1/step (positions x, y to 1 cm; yaw to 1 mrad; speed to
#: 1 cm/s; t, ttc, ttc_t, ttc_full to 1 ms; zone exact), under :data:`PACKED_KEYS`.
STEPS: dict[str, int] = {
    "x": 100, "y": 100, "yaw": 1000, "speed": 100, "t": 1000, "ttc": 1000, "ttc_t": 1000,
    "ttc_full": 1000, "zone": 1,
}  # fmt: skip
#: Top-level keys of an encounter whose arrays are packed (``riskmap``: its variants'
#: points only, :data:`POINT_SCALE`).
PACKED_KEYS = ("tracks", "replay", "roads", "road_layers")
#: The sweep's variant markers (time shift [s], speed [m/s]) to 1e-3 (a tenth of a pixel).
POINT_SCALE = 1000
#: Arrays shorter than this stay JSON [values].
MIN_PACKED = 8
#: Largest quantized magnitude packed (beyond: the array stays JSON).
_LIMIT = 2**31 - 1
_WIDTHS = ((1, "<i1"), (2, "<i2"), (4, "<i4"))


def _numeric(v: Any) -> np.ndarray | None:
    """``v`` as a float array when it is a numeric 1-D array or a list of numbers / None."""
    if isinstance(v, np.ndarray):
        if v.ndim == 1 and v.dtype.kind in "fiu":
            return v.astype(np.float64)
        return None
    if (
        isinstance(v, list)
        and v
        and all(
            x is None or (isinstance(x, int | float | np.number) and not isinstance(x, bool))
            for x in v
        )
    ):
        return np.array([np.nan if x is None else float(x) for x in v], dtype=np.float64)
    return None


class _Packer:
    """Collects the packed arrays of one encounter: their bytes and specs, in order."""

    def __init__(self) -> None:
        self.parts: list[bytes] = []
        self.specs: list[list[Any]] = []

    def array(self, a: np.ndarray, scale: int) -> dict[str, Any] | None:
        """The placeholder of array ``a`` [n] quantized to 1/scale; None if it cannot be
        packed (too short, too large)."""
        n = a.size
        if n < MIN_PACKED:
            return None
        bad = ~np.isfinite(a)
        if bad.all():
            return None
        with np.errstate(invalid="ignore"):
            q = np.round(a * scale)
        if np.nanmax(np.abs(q)) > _LIMIT // 4:
            return None
        runs: list[list[int]] = []
        if bad.any():  # NaN: the last value repeated (differences 0), listed as runs
            idx = np.where(~bad, np.arange(n), 0)
            np.maximum.accumulate(idx, out=idx)
            first = int(np.argmax(~bad))
            q = np.where(bad, q[idx], q)
            q[:first] = q[first]
            edges = np.diff(np.r_[0, bad.astype(np.int8), 0])
            runs = [
                [int(s), int(e - s)]
                for s, e in zip(
                    np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True
                )
            ]
        qi = q.astype(np.int64)
        # the smallest of: values about their middle (order 0: noise), first differences
        # (order 1: steps), second differences (order 2: smooth motion)
        mid = int((qi.min() + qi.max()) // 2)
        d1 = np.diff(qi, prepend=qi[0])
        d2 = np.diff(d1, prepend=0)
        order, d, origin = min(
            ((0, qi - mid, mid), (1, d1, int(qi[0])), (2, d2, int(qi[0]))),
            key=lambda c: int(np.abs(c[1]).sum()),
        )
        peak = int(np.abs(d).max())
        width, dtype = next((w, t) for w, t in _WIDTHS if peak < 2 ** (8 * w - 1) - 1 or w == 4)
        if peak >= _LIMIT:
            return None
        self.parts.append(d.astype(dtype).tobytes())
        self.specs.append([n, width, scale, order, origin, runs])
        return {"$a": len(self.specs) - 1}

    def walk(self, v: Any, scale: int | None, name: str = "") -> Any:
        """``v`` with every array named in STEPS packed (``scale`` 0: STEPS' step; None:
        nothing packed; else that scale), the rest as it is."""
        if isinstance(v, dict):
            return {k: self.walk(x, scale, str(k)) for k, x in v.items()}
        if isinstance(v, list | tuple) and not (scale is not None and name in STEPS):
            return [self.walk(x, scale, name) for x in v]
        if scale is not None and name in STEPS:
            a = _numeric(v)
            if a is not None:
                packed = self.array(a, STEPS[name] if scale == 0 else scale)
                if packed is not None:
                    return packed
        return v


def _ttc_on(t: np.ndarray, ttc_t: np.ndarray, ttc_full: np.ndarray) -> np.ndarray:
    """The TTC [s] at the replay's times ``t`` [K] taken from the full series (``ttc_t``,
    ``ttc_full`` [M]), times matched to 1 ms; NaN where ``ttc_t`` lacks a time."""
    key = np.round(np.asarray(ttc_t, float) * 1000).astype(np.int64)
    want = np.round(np.asarray(t, float) * 1000).astype(np.int64)
    pos = np.clip(np.searchsorted(key, want), 0, max(0, key.size - 1))
    hit = (key.size > 0) & (key[pos] == want) if key.size else np.zeros(want.size, bool)
    vals = np.asarray(ttc_full, float)[pos] if key.size else np.full(want.size, np.nan)
    return np.where(hit, vals, np.nan)


def _drop_ttc(cfg: dict[str, Any], t: Any) -> dict[str, Any]:
    """A replay configuration without its ``ttc`` [K] where that is the full series at the
    replay's times to 1 ms (``ttc_from_full``: the page takes it from there)."""
    need = ("ttc", "ttc_t", "ttc_full")
    if not all(k in cfg for k in need):
        return cfg
    ttc = np.asarray([np.nan if v is None else v for v in cfg["ttc"]], float)
    tt = np.asarray(cfg["ttc_t"], float)
    if tt.size and np.any(np.diff(tt) <= 0):
        return cfg
    got = _ttc_on(np.asarray(t, float), tt, np.asarray(cfg["ttc_full"], float))
    with np.errstate(invalid="ignore"):
        a, b = np.round(ttc * 1000), np.round(got * 1000)
    same = np.where(np.isfinite(a) | np.isfinite(b), a == b, True)
    if ttc.shape != got.shape or not same.all():
        return cfg
    return {**{k: v for k, v in cfg.items() if k != "ttc"}, "ttc_from_full": True}


def _points_array(p: _Packer, name: str, v: Any) -> Any:
    """A sweep marker array packed: x, y to 1/POINT_SCALE; the flags (collision, flagged)
    as 0 / 1 (unpacked as 0.0 / 1.0); else as it is."""
    if name in ("x", "y"):
        return p.walk(v, POINT_SCALE, name)
    a = np.asarray(v)
    if a.ndim == 1 and a.dtype == bool:
        return p.array(a.astype(np.float64), 1) or v
    return v


def _sorted_points(pts: dict[str, Any]) -> dict[str, Any]:
    """The sweep's variant markers in order of x (their order is not shown; sorted, x
    differs little from one to the next): every array of x's length reordered alike."""
    x = np.asarray(pts.get("x", []), float)
    if x.ndim != 1 or x.size < 2:
        return pts
    order = np.argsort(x, kind="stable")
    return {k: (np.asarray(v)[order] if len(v) == x.size else v) for k, v in pts.items()}


def pack(enc: dict[str, Any]) -> str:
    """Encounter data (JSON-ready but for numpy arrays) packed to base64 text (module
    docstring); every array under :data:`PACKED_KEYS` named in :data:`STEPS`, and
    ``riskmap.points`` x / y, is quantized, the rest stays as
    :func:`vei.report.html_report._script_json` writes it (floats to 4 decimals)."""
    from vei.report.html_report import _clean

    p = _Packer()
    data: dict[str, Any] = {}
    for key, v in enc.items():
        if key == "replay" and isinstance(v, dict) and "t" in v:
            v = {**v, "configs": [_drop_ttc(c, v["t"]) for c in v.get("configs", [])]}
        if key in PACKED_KEYS:
            data[key] = p.walk(v, 0, key)
        elif key == "riskmap" and isinstance(v, dict) and isinstance(v.get("points"), dict):
            pts = _sorted_points(v["points"])
            pts = {k: _points_array(p, k, x) for k, x in pts.items()}
            data[key] = {**v, "points": pts}
        else:
            data[key] = v
    doc = {"data": data, "arrays": p.specs, "v": 2}
    text = json.dumps(_clean(doc), separators=(",", ":"), allow_nan=False)
    head = text.encode("utf-8")
    payload = struct.pack("<I", len(head)) + head + b"".join(p.parts)
    return zlib.compress(payload, 9)


#: Bytes escaped in a script's string literal (the rest are written as they are).
_ESCAPES = {b"\0": b"\\x00", b"\n": b"\\n", b"\r": b"\\r", b'"': b'\\"', b"\\": b"\\\\"}
_ESCAPE_RE = re.compile(rb'[\x00\n\r"\\]')
_UNESCAPE = {v: k for k, v in _ESCAPES.items()}
_UNESCAPE_RE = re.compile(rb'\\(?:x00|n|r|"|\\)')
#: The call an encounter's script makes; the page loads it with ``charset =
#: "x-user-defined"`` (each byte one character, 0x80-0xFF as U+F780-U+F7FF).
_CALL = re.compile(rb'^window\.veiReport\.receive(?:Map)?\((\d+|"[0-9a-f]+"),"(.*)"\);\n?$', re.S)


def script(i: int, payload: bytes) -> bytes:
    """Encounter ``i``'s script: ``window.veiReport.receive(i,"...");`` with the packed
    payload's bytes as they are inside the string literal (NUL, line breaks, quote and
    backslash escaped): about 1.02 bytes per byte (base64: 1.33)."""
    body = _ESCAPE_RE.sub(lambda m: _ESCAPES[m.group()], payload)
    return b'window.veiReport.receive(%d,"%s");\n' % (int(i), body)


def map_script(key: str, payload: bytes) -> bytes:
    """A map-layers script: ``window.veiReport.receiveMap("key","...");``, the packed
    payload as in :func:`script`; ``key`` lowercase hex."""
    if not re.fullmatch(r"[0-9a-f]+", key):
        raise ValueError(f"map key must be lowercase hex, got {key!r}")
    body = _ESCAPE_RE.sub(lambda m: _ESCAPES[m.group()], payload)
    return b'window.veiReport.receiveMap("%s","%s");\n' % (key.encode("ascii"), body)


def read_script(data: bytes) -> tuple[int | str, dict[str, Any]]:
    """The reference reader of :func:`script`'s and :func:`map_script`'s bytes: (i or the
    map's key, the data, :func:`unpack`)."""
    m = _CALL.match(data)
    if m is None:
        raise ValueError(
            'not an encounter or map script (window.veiReport.receive(i,"..."); expected)'
        )
    payload = _UNESCAPE_RE.sub(lambda k: _UNESCAPE[k.group()], m.group(2))
    head = m.group(1).decode("ascii")
    return (head.strip('"') if head.startswith('"') else int(head)), unpack(payload)


def _decode_array(spec: list[Any], buf: bytes, base: int, offset: int) -> list[float | None]:
    n, width, scale, order, origin, runs = spec
    dtype = dict(_WIDTHS)[width]
    d = np.frombuffer(buf, dtype=dtype, count=n, offset=base + offset).astype(np.int64)
    for _ in range(order):
        d = np.cumsum(d)
    out: list[float | None] = ((d + origin) / scale).tolist()
    for s, ln in runs:
        out[s : s + ln] = [None] * ln
    return out


def unpack(payload: bytes) -> dict[str, Any]:
    """The reference decoder of :func:`pack`'s payload: the encounter with every packed
    array a list of floats (None where the original was NaN / None)."""
    buf = zlib.decompress(payload)
    (n,) = struct.unpack_from("<I", buf, 0)
    doc = json.loads(buf[4 : 4 + n].decode("utf-8"))
    base = 4 + n
    offsets = np.cumsum([0] + [s[0] * s[1] for s in doc["arrays"]]).tolist()

    def revive(v: Any) -> Any:
        if isinstance(v, dict):
            if set(v) == {"$a"}:
                k = v["$a"]
                return _decode_array(doc["arrays"][k], buf, base, offsets[k])
            return {k: revive(x) for k, x in v.items()}
        if isinstance(v, list):
            return [revive(x) for x in v]
        return v

    data = revive(doc["data"])
    replay = data.get("replay")
    for c in (replay or {}).get("configs", []):
        if c.pop("ttc_from_full", False):
            full = np.array([np.nan if v is None else v for v in c["ttc_full"]], float)
            ttc = _ttc_on(np.asarray(replay["t"], float), np.asarray(c["ttc_t"], float), full)
            c["ttc"] = [None if not np.isfinite(v) else float(v) for v in ttc]
    return data
