"""The compiled kernel's machine code on disk: what it depends on, whether a feature set is
compiled yet, and one compiling process at a time (importable without numba).

numba caches each compiled specialisation of :func:`vei.sim.kernel.loop.kernel` /
``variant`` beside the package (or in ``$NUMBA_CACHE_DIR`` / the user cache when the
package's folder is not writable), keyed by argument types: one entry per feature set
(:class:`vei.sim.kernel.pack.Features`). Beside them this module keeps

- ``loop.sources.sha256``: a digest of every module compiled into the kernel (numba checks
  only the kernel's own file); on a change the cache is flushed (:func:`drop_stale`);
- ``loop.compiled.<features>``: who compiled that feature set (sources, numba, CPU), so
  that a run can say beforehand that it is going to compile (:func:`is_cold`);
- ``loop.<features>.lock``: held while a process compiles that feature set, so that the
  workers of a sweep wait for one compilation and then load it (:func:`compiling`).
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import platform
from collections.abc import Iterator
from pathlib import Path
from typing import Any

#: Modules compiled into the kernel, relative to this package: its own modules, and
#: vei.boxes (the box-overlap test), vei.config.settings (the order of P's rows: layout's
#: P_* constants), the fused metrics and the model cores it compiles on scalars.
KERNEL_SOURCES = (
    "loop.py", "scalar.py", "ego.py", "corridor.py", "sfm.py", "riders.py", "layout.py",
    "decision.py",
    "traffic.py", "contacts.py", "../../models/traffic_core.py",
    "../../boxes.py", "../../config/settings.py", "../../metrics/fused.py",
    "../../metrics/fused_layout.py", "../../metrics/fused_ops.py",
    "../../models/ego_core.py", "../../models/sfm_core.py", "../../models/decision_core.py",
    "../../metrics/severity.py", "policy.py", "policy_pack.py", "../../policy/aeb.py",
    "../../policy/idm.py", "../../policy/compiled.py",
)  # fmt: skip
#: Names of the compiled functions whose caches hold the kernel's machine code.
_FUNCTIONS = ("kernel", "variant")

_KEY: str | None = None  # compile_key(), computed once per process


def sources_digest() -> str:
    """SHA-256 of every module of :data:`KERNEL_SOURCES`."""
    here = Path(__file__).resolve().parent
    return hashlib.sha256(b"".join((here / n).read_bytes() for n in KERNEL_SOURCES)).hexdigest()


def compile_key() -> str:
    """What the cached machine code depends on (sources, numba, CPU), kept in the stamps."""
    global _KEY
    if _KEY is None:
        import llvmlite.binding as llvm
        import numba

        cpu = llvm.get_host_cpu_name()
        _KEY = f"{sources_digest()} numba {numba.__version__} {platform.machine()} {cpu}"
    return _KEY


def cache_dir(dispatcher: Any) -> Path | None:
    """The folder numba caches ``dispatcher``'s machine code in (None: no cache)."""
    path = getattr(getattr(dispatcher, "_cache", None), "cache_path", None)
    return Path(path) if path else None


def _write(path: Path, text: str) -> None:
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def drop_stale(*dispatchers: Any) -> None:
    """Flush the dispatchers' on-disk caches when any module compiled into them changed.

    numba keys a cached function by its own source file only, so an edit of a helper module
    (inlined into the kernel) would otherwise keep serving the old machine code. The digest
    of :data:`KERNEL_SOURCES` is kept next to the cache; on a mismatch every dispatcher's
    cache is flushed (recompiled on the first call) and the new digest written atomically.
    """
    folder = next((d for d in map(cache_dir, dispatchers) if d is not None), None)
    if folder is None:
        return
    digest = sources_digest()
    stamp = folder / "loop.sources.sha256"
    try:
        if stamp.is_file() and stamp.read_text().strip() == digest:
            return
        for disp in dispatchers:
            cache = getattr(disp, "_cache", None)
            if cache is not None:
                cache.flush()
        folder.mkdir(parents=True, exist_ok=True)
        _write(stamp, digest + "\n")
    except OSError:  # read-only install: nothing cached by us can be stale
        return


def stamp_path(folder: Path | None, features: str) -> Path | None:
    """The compile stamp of feature set ``features`` (a Features.name) in ``folder``."""
    return None if folder is None else folder / f"loop.compiled.{features}"


def is_cold(folder: Path | None, features: str) -> bool:
    """True when feature set ``features`` has no machine code cached in ``folder`` for this
    machine and installation (its first call compiles)."""
    stamp = stamp_path(folder, features)
    if stamp is None:
        return True
    # the stamp says who compiled; numba's index files that the machine code is still there
    # (a cleared __pycache__ can leave the one without the other)
    # runs with a user's compiled policy use the serial shell (vei.sim.kernel.loop.kernel_seq)
    fns = ("kernel_seq", "variant") if "user" in features.split("+") else _FUNCTIONS
    if not all(any(stamp.parent.glob(f"loop.{f}-*.nbi")) for f in fns):
        return True
    try:
        return stamp.read_text().strip() != compile_key()
    except OSError:
        return True


def mark_compiled(folder: Path | None, features: str) -> None:
    """Say on disk that ``features`` is compiled for this machine and installation."""
    stamp = stamp_path(folder, features)
    if stamp is None:
        return
    try:
        _write(stamp, compile_key() + "\n")
    except OSError:  # a cache we cannot write: numba compiles again next time anyway
        return


@contextlib.contextmanager
def compiling(folder: Path | None, features: str) -> Iterator[None]:
    """Hold the lock of feature set ``features`` while the block compiles it: another
    process compiling the same set waits here, then loads the machine code the first one
    wrote (no two workers compile the same thing at once). Without a writable cache folder
    or ``fcntl`` (Windows) the block runs unlocked."""
    try:
        import fcntl
    except ImportError:  # pragma: no cover - not POSIX
        yield
        return
    if folder is None:
        yield
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd = os.open(folder / f"loop.{features}.lock", os.O_RDWR | os.O_CREAT, 0o644)
    except OSError:
        yield
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield
    finally:
        with contextlib.suppress(OSError):
            fcntl.flock(fd, fcntl.LOCK_UN)
        os.close(fd)
