"""The compiled kernel's on-disk cache is dropped when a module compiled into it changes."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

from vei.sim import kernel


class _Cache:
    def __init__(self, path) -> None:
        self.cache_path = str(path)
        self.flushes = 0

    def flush(self) -> None:
        self.flushes += 1


def test_stale_cache_flushed_once_per_source_change(tmp_path) -> None:
    cache = _Cache(tmp_path / "cache")
    fake = SimpleNamespace(_cache=cache)
    kernel._drop_stale_cache(fake)  # no stamp yet: flush, write the digest
    stamp = tmp_path / "cache" / "loop.sources.sha256"
    assert cache.flushes == 1 and stamp.is_file()
    digest = stamp.read_text().strip()
    assert len(digest) == 64
    kernel._drop_stale_cache(fake)  # sources unchanged: the cache is kept
    assert cache.flushes == 1
    stamp.write_text("0" * 64 + "\n")  # as if a helper module had been edited
    kernel._drop_stale_cache(fake)
    assert cache.flushes == 2 and stamp.read_text().strip() == digest
    assert not list(stamp.parent.glob("*.tmp"))


def test_every_kernel_module_is_in_the_digest() -> None:
    here = Path(kernel.__file__).parent
    compiled = {p.name for p in here.glob("*.py")} - {"__init__.py"}
    # vei.boxes (the bottom floor) gives the kernel its box-overlap test, vei.config.settings
    # the order of the parameter rows (layout's P_* constants), vei.metrics.fused the
    # per-variant metrics of simulate_metrics, vei.models.ego_core / sfm_core the ego's and
    # the riders' laws (compiled on scalars by the package's ego / sfm modules)
    extra = {"../../boxes.py", "../../config/settings.py", "../../metrics/fused.py"}
    extra |= {"../../metrics/fused_layout.py", "../../metrics/fused_ops.py"}
    extra |= {"../../models/ego_core.py", "../../models/sfm_core.py"}
    extra |= {"../../models/decision_core.py"}  # the rider's decision (issue 24)
    extra |= {"../../models/traffic_core.py"}  # reacting cars (issue 24)
    assert compiled | extra == set(kernel._KERNEL_SOURCES)
    assert all((here / n).is_file() for n in kernel._KERNEL_SOURCES)
