"""The compiled kernel's on-disk cache: dropped when a module compiled into it changes,
stamped per feature set, and compiled by one process at a time."""

from __future__ import annotations

import multiprocessing
import time
from pathlib import Path
from types import SimpleNamespace

from vei.sim import kernel
from vei.sim.kernel import cache


class _Cache:
    def __init__(self, path) -> None:
        self.cache_path = str(path)
        self.flushes = 0

    def flush(self) -> None:
        self.flushes += 1


def test_stale_cache_flushed_once_per_source_change(tmp_path) -> None:
    caches = [_Cache(tmp_path / "cache"), _Cache(tmp_path / "cache")]
    fakes = [SimpleNamespace(_cache=c) for c in caches]
    cache.drop_stale(*fakes)  # no stamp yet: flush both, write the digest
    stamp = tmp_path / "cache" / "loop.sources.sha256"
    assert [c.flushes for c in caches] == [1, 1] and stamp.is_file()
    digest = stamp.read_text().strip()
    assert len(digest) == 64
    cache.drop_stale(*fakes)  # sources unchanged: the cache is kept
    assert [c.flushes for c in caches] == [1, 1]
    stamp.write_text("0" * 64 + "\n")  # as if a helper module had been edited
    cache.drop_stale(*fakes)
    assert [c.flushes for c in caches] == [2, 2] and stamp.read_text().strip() == digest
    assert not list(stamp.parent.glob("*.tmp"))


def test_every_kernel_module_is_in_the_digest() -> None:
    here = Path(kernel.__file__).parent
    # the packing, the cache's bookkeeping and the package are plain Python (not compiled)
    compiled = {p.name for p in here.glob("*.py")} - {"__init__.py", "pack.py", "cache.py"}
    # vei.boxes (the bottom floor) gives the kernel its box-overlap test, vei.config.settings
    # the order of the parameter rows (layout's P_* constants), vei.metrics.fused the
    # per-variant metrics of simulate_metrics, vei.models.ego_core / sfm_core the ego's and
    # the riders' laws (compiled on scalars by the package's ego / sfm modules)
    extra = {"../../boxes.py", "../../config/settings.py", "../../metrics/fused.py"}
    extra |= {"../../metrics/fused_layout.py", "../../metrics/fused_ops.py"}
    extra |= {"../../models/ego_core.py", "../../models/sfm_core.py"}
    extra |= {"../../models/decision_core.py"}  # the rider's decision (issue 24)
    extra |= {"../../models/traffic_core.py"}  # reacting cars (issue 24)
    extra |= {"../../metrics/severity.py"}  # the standing car of the fused 'striking' (32)
    # ego policies in the kernel (issue 34): aeb's / idm's constants, the observation rows
    extra |= {"../../policy/aeb.py", "../../policy/idm.py", "../../policy/compiled.py"}
    assert compiled | extra == set(cache.KERNEL_SOURCES)
    assert all((here / n).is_file() for n in cache.KERNEL_SOURCES)


def test_feature_sets_have_their_own_stamps(tmp_path) -> None:
    """A compiled feature set says nothing about another: each has its stamp, and both
    need numba's index files of the kernel and its per-variant function."""
    base, full = kernel.Features(), kernel.ALL_FEATURES
    assert base.name == "base"
    assert full.name == "others+riders+decisions+traffic+metrics+policy+user"
    assert kernel.Features(others=True, metrics=True).name == "others+metrics"
    cache.mark_compiled(tmp_path, base.name)
    assert cache.is_cold(tmp_path, base.name)  # no machine code (index files) yet
    for f in ("kernel", "variant"):
        (tmp_path / f"loop.{f}-120.py311.nbi").write_bytes(b"index")
    assert not cache.is_cold(tmp_path, base.name)
    assert cache.is_cold(tmp_path, full.name)  # never compiled
    (tmp_path / f"loop.compiled.{base.name}").write_text("another machine\n")
    assert cache.is_cold(tmp_path, base.name)
    # a set with a user's compiled policy runs the serial shell: it needs its index files
    pol = kernel.Features(policy=True, user=True).name
    cache.mark_compiled(tmp_path, pol)
    assert cache.is_cold(tmp_path, pol)
    (tmp_path / "loop.kernel_seq-130.py311.nbi").write_bytes(b"index")
    assert not cache.is_cold(tmp_path, pol)


def _hold(folder: str, started, held_s: float) -> None:
    with cache.compiling(Path(folder), "base"):
        started.set()
        time.sleep(held_s)


def test_one_process_compiles_a_feature_set_at_a_time(tmp_path) -> None:
    """While one process holds a feature set's lock, another waits for it (the workers of a
    sweep compile it once, then load it); another feature set is not held up."""
    ctx = multiprocessing.get_context("spawn")
    started = ctx.Event()
    proc = ctx.Process(target=_hold, args=(str(tmp_path), started, 1.5))
    proc.start()
    try:
        assert started.wait(60)
        t0 = time.monotonic()
        with cache.compiling(tmp_path, "others"):
            other = time.monotonic() - t0
        with cache.compiling(tmp_path, "base"):
            waited = time.monotonic() - t0
    finally:
        proc.join(60)
    assert other < 0.5
    assert waited > 0.5
