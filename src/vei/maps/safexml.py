"""Parsing of untrusted XML (OSM, SUMO .net.xml, OpenDRIVE .xodr) without entity expansion.

Every XML file that vei reads or hands to an external converter goes through here first.
``defusedxml`` refuses entity declarations (billion laughs, quadratic blow-up) and external
entities / DTD retrieval (XXE); such a file becomes an :class:`~vei.errors.InputError` that
names the file, instead of a memory bomb or a leaked local file. Gzip-compressed files
(``.gz``) are read transparently.
"""

from __future__ import annotations

import gzip
import io
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path
from typing import IO

from vei.errors import InputError


def _defused():
    try:
        import defusedxml.ElementTree as dET
        from defusedxml import DefusedXmlException
    except ImportError as exc:  # pragma: no cover - defusedxml is a core dependency
        from vei.errors import DependencyError

        raise DependencyError(
            "defusedxml is required to parse XML safely (pip install defusedxml)"
        ) from exc
    return dET, DefusedXmlException


def _open(path: Path) -> IO[bytes]:
    if path.suffix == ".gz":
        return gzip.open(path, "rb")
    return open(path, "rb")


def _reject(exc: Exception, path: Path | str | None) -> InputError:
    _, defused_exc = _defused()
    if isinstance(exc, defused_exc):
        return InputError(
            f"refusing unsafe XML ({type(exc).__name__}: {exc}); entity declarations and "
            "external references are not allowed (XXE / entity-expansion protection)",
            path=path,
        )
    if isinstance(exc, ET.ParseError):
        return InputError(f"malformed XML: {exc}", path=path)
    if isinstance(exc, (OSError, EOFError, gzip.BadGzipFile)):
        return InputError(f"cannot read XML file: {exc}", path=path)
    raise exc


def iter_elements(path: str | Path, tags: set[str] | None = None) -> Iterator[ET.Element]:
    """Stream the elements of an XML file (``end`` events), safely.

    Args:
        path: an XML file, optionally gzip-compressed (``.gz``).
        tags: only yield elements with these tag names (all when None). Yielded elements are
            complete (children parsed); they are cleared after the caller moves on, so keep
            what you need from them.
    Raises:
        InputError: unsafe constructs (entities, external references), malformed XML, or an
            unreadable file, naming the file.
    """
    dET, _ = _defused()
    p = Path(path)
    try:
        with _open(p) as fh:
            for _event, elem in dET.iterparse(fh, events=("end",)):
                if tags is None or elem.tag in tags:
                    yield elem
                    if tags is not None:
                        elem.clear()
    except Exception as exc:  # noqa: BLE001 - translated or re-raised by _reject
        raise _reject(exc, p) from exc


def check_file(path: str | Path) -> str:
    """Scan a whole XML file for unsafe constructs without keeping it in memory.

    Returns:
        The root element's tag (e.g. ``'osm'``, ``'net'``, ``'OpenDRIVE'``).
    Raises:
        InputError: as :func:`iter_elements`, or when the file holds no element.
    """
    dET, _ = _defused()
    p = Path(path)
    root_tag: str | None = None
    try:
        with _open(p) as fh:
            for event, elem in dET.iterparse(fh, events=("start", "end")):
                if root_tag is None and event == "start":
                    root_tag = elem.tag
                elif event == "end" and len(elem) == 0:
                    elem.clear()
    except Exception as exc:  # noqa: BLE001
        raise _reject(exc, p) from exc
    if root_tag is None:
        raise InputError("XML file has no root element", path=p)
    return root_tag


def parse_file(path: str | Path) -> ET.Element:
    """Parse a whole XML file safely and return its root element.

    Raises:
        InputError: unsafe constructs, malformed XML, unreadable file (naming the file).
    """
    dET, _ = _defused()
    p = Path(path)
    try:
        with _open(p) as fh:
            return dET.parse(fh).getroot()
    except Exception as exc:  # noqa: BLE001
        raise _reject(exc, p) from exc


def parse_bytes(data: bytes | str, *, source: str = "<bytes>") -> ET.Element:
    """Parse XML held in memory (e.g. an HTTP answer) safely; ``source`` names it in errors."""
    dET, _ = _defused()
    raw = data.encode("utf-8") if isinstance(data, str) else data
    try:
        return dET.parse(io.BytesIO(raw)).getroot()
    except Exception as exc:  # noqa: BLE001
        err = _reject(exc, None)
        raise InputError(f"{source}: {err.detail}") from exc
