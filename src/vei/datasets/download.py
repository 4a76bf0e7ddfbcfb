"""Download the parts of public datasets that vei's importers need (standard library only).

``download_trafficmonitoring`` fetches, per scenario, exactly the three files the importer
reads from github.com/jul095/TrafficMonitoring at a fixed commit, into the repository's
own layout (``dest/data/measurements/...``), so ``dest`` is a dataset root for
``vei import trafficmonitoring --root dest``:

- ``matching/<scenario>_matching.csv`` (read first: it names the INS record),
- ``videos/trajectory_output/<scenario>_trajectories.csv``,
- ``car_data/<measurement_prefix>INSSOL.csv`` (file names contain apostrophes; URLs quote them).

Every file is written atomically (temporary file + rename) after its length was checked
against Content-Length, so a file that exists is complete: a rerun skips it (resume).
Network errors, timeouts, HTTP 5xx/429 and truncated bodies are retried with exponential
backoff; HTTP 404 is not (the scenario name is wrong: the message lists the known ones).
"""

from __future__ import annotations

import http.client
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable, Sequence
from pathlib import Path

from vei.errors import VeiError
from vei.io.atomic import atomic_path

#: Raw-file URL of the TrafficMonitoring repository at the commit the importer was written against.
TRAFFICMONITORING_BASE_URL = "https://raw.githubusercontent.com/jul095/TrafficMonitoring/641075e8d42337a46e8825fc3947f0b49b405b3b"
#: Scenarios of that commit that have a matching file (camera <-> INS), i.e. that can be imported.
TRAFFICMONITORING_SCENARIOS: tuple[str, ...] = (
    "audi_08_klinikum_rechtsabbiegen",
    "audi_08_klinikum_rechtsabbiegen_02",
    "audi_08_stadtmitte_geradeaus",
    "audi_09_marktkauf_linksabbiegen",
    "audi_10_marktkauf_linksabbiegen",
    "klinikum_01_marktkauf_geradeaus",
    "klinikum_01_stadtmitte_rechtsabbiegen",
    "marktkauf_04_audi_rechtsabbiegen",
    "marktkauf_05_klinikum_geradeaus",
    "marktkauf_07_stadtmitte_linksabbiegen",
    "stadtmitte_11_marktkauf_rechtsabbiegen_02",
    "stadtmitte_12_audi_geradeaus",
    "stadtmitte_12_audi_geradeaus_02",
    "stadtmitte_12_audi_geradeaus_03",
)
#: The scenarios vei's tests and examples use (downloaded when no scenario is named).
DEFAULT_SCENARIOS: tuple[str, ...] = (
    "audi_08_klinikum_rechtsabbiegen",
    "klinikum_01_marktkauf_geradeaus",
    "stadtmitte_12_audi_geradeaus_03",
)

_CHUNK = 1 << 16
_RETRY_STATUS = {408, 429, 500, 502, 503, 504}
_LFS_MAGIC = b"version https://git-lfs.github.com/spec/"


class DownloadError(VeiError):
    """A file could not be downloaded (network, HTTP status, truncated or unexpected content)."""


def _url(base_url: str, relpath: str) -> str:
    return base_url.rstrip("/") + "/" + urllib.parse.quote(relpath, safe="/")


def fetch_file(
    url: str,
    target: Path,
    *,
    timeout_s: float = 30.0,
    retries: int = 3,
    backoff_s: float = 1.0,
    user_agent: str = "vei-downloader",
) -> int:
    """Download ``url`` to ``target`` atomically; returns the number of bytes.

    Args:
        url: http(s) URL.
        target: destination file (replaced only when the whole body arrived).
        timeout_s: socket timeout per attempt [s].
        retries: further attempts after the first on transient failures (>= 0).
        backoff_s: wait before the first retry [s], doubled each time.
    Raises:
        DownloadError: HTTP 4xx (no retry), or still failing after the retries.
    """
    last = "no attempt"
    for attempt in range(retries + 1):
        if attempt:
            time.sleep(backoff_s * 2 ** (attempt - 1))
        try:
            req = urllib.request.Request(url, headers={"User-Agent": user_agent})
            with urllib.request.urlopen(req, timeout=timeout_s) as resp, atomic_path(target) as tmp:
                expected = resp.headers.get("Content-Length")
                n = 0
                first = b""
                with open(tmp, "wb") as fh:
                    while chunk := resp.read(_CHUNK):
                        if n == 0:
                            first = chunk[: len(_LFS_MAGIC)]
                        fh.write(chunk)
                        n += len(chunk)
                if expected is not None and n != int(expected):
                    raise http.client.IncompleteRead(b"", int(expected) - n)
                if first.startswith(_LFS_MAGIC):
                    raise DownloadError(
                        f"{url} is a Git LFS pointer, not the file itself; download it with git lfs"
                    )
            return n
        except urllib.error.HTTPError as exc:
            last = f"HTTP {exc.code} {exc.reason}"
            if exc.code not in _RETRY_STATUS:
                raise DownloadError(f"could not download {url}: {last}") from None
        except (
            urllib.error.URLError,
            TimeoutError,
            ConnectionError,
            http.client.HTTPException,
        ) as exc:
            reason = getattr(exc, "reason", None) or exc
            last = f"{type(exc).__name__}: {reason}"
    raise DownloadError(f"could not download {url} after {retries + 1} attempt(s): {last}")


def _matching_prefix(path: Path) -> str:
    from vei.errors import InputError

    lines = path.read_text(encoding="utf-8-sig").splitlines()
    header = [h.strip() for h in lines[0].split(",")] if lines else []
    if "measurement_prefix" not in header or len(lines) < 2:
        raise InputError(
            "expected a header with measurement_prefix and one data row",
            path=path,
            field="measurement_prefix",
        )
    # the prefix holds apostrophes but no commas
    return lines[1].split(",")[header.index("measurement_prefix")].strip()


def download_trafficmonitoring(
    dest: str | Path,
    *,
    base_url: str = TRAFFICMONITORING_BASE_URL,
    scenarios: Sequence[str] | None = None,
    timeout_s: float = 30.0,
    retries: int = 3,
    backoff_s: float = 1.0,
    progress: Callable[[str], None] | None = None,
) -> Path:
    """Fetch the files the trafficmonitoring importer needs into ``dest``; returns ``dest``.

    Args:
        dest: dataset root to create/complete (``dest/data/measurements/...``).
        base_url: where the repository's files are served (default: GitHub raw files of
            jul095/TrafficMonitoring at commit 641075e); ``<base_url>/data/measurements/...``.
        scenarios: names to fetch (default DEFAULT_SCENARIOS); names outside
            TRAFFICMONITORING_SCENARIOS are tried as well.
        timeout_s, retries, backoff_s: per-file network settings (see :func:`fetch_file`).
        progress: called with one line per file ("skip ..." / "got ... (N bytes)").
    Raises:
        DownloadError: a file could not be fetched (a 404 on a matching file names the
            known scenarios).
    """
    from vei.datasets.trafficmonitoring import (
        CAR_DATA_DIR,
        INS_SUFFIX,
        MATCHING_DIR,
        MATCHING_SUFFIX,
        TRAJECTORIES_DIR,
        TRAJECTORIES_SUFFIX,
    )

    dest = Path(dest)
    names = list(DEFAULT_SCENARIOS if scenarios is None else scenarios)
    if not names:
        raise DownloadError("no scenario to download")
    say = progress or (lambda _line: None)

    def get(rel: Path) -> Path:
        target = dest / rel
        if target.is_file() and target.stat().st_size > 0:
            say(f"skip {rel} (already complete)")
            return target
        n = fetch_file(
            _url(base_url, rel.as_posix()),
            target,
            timeout_s=timeout_s,
            retries=retries,
            backoff_s=backoff_s,
        )
        say(f"got  {rel} ({n} bytes)")
        return target

    for name in names:
        if not name or "/" in name or "\\" in name or name.startswith("."):
            raise DownloadError(f"invalid scenario name {name!r}")
        try:
            matching = get(MATCHING_DIR / f"{name}{MATCHING_SUFFIX}")
        except DownloadError as exc:
            if "HTTP 404" in str(exc):
                raise DownloadError(
                    f"scenario {name!r} not found ({exc}); known scenarios: {', '.join(TRAFFICMONITORING_SCENARIOS)}"
                ) from None
            raise
        get(TRAJECTORIES_DIR / f"{name}{TRAJECTORIES_SUFFIX}")
        get(CAR_DATA_DIR / f"{_matching_prefix(matching)}{INS_SUFFIX}")
    return dest
