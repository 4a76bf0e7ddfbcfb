"""Worker processes that die with their parent: the process pool of sweeps and catalogues.

:class:`WorkerPool` is a :class:`concurrent.futures.ProcessPoolExecutor` (``spawn`` start
method, safe with numba and threads) whose workers never outlive the process that opened
it, however that process ends:

- **Linux**: each worker asks the kernel for ``SIGKILL`` when its parent dies
  (``prctl(PR_SET_PDEATHSIG, SIGKILL)``, through ctypes), so ``kill -9`` of the parent ends
  every worker at once, even one busy in compiled code that holds the GIL. The kernel
  sends the signal when the *thread* that started the worker ends: open the pool in the
  thread that uses it (all workers are started by :meth:`WorkerPool.start`, from the
  caller's thread; the pool never starts replacements from its manager thread because
  ``max_tasks_per_child`` is not used).
- **Everywhere** (the portable path, and a second guard on Linux): a daemon watchdog thread
  in each worker polls ``os.getppid()`` every ``poll_s`` seconds and ends the worker
  (``os._exit``) when the parent has changed (the worker was re-parented: its parent died).
  It needs the GIL, so a worker inside a long GIL-holding call notices at the call's end.
- **Ctrl-C**: workers ignore ``SIGINT`` (a terminal sends it to the whole process group),
  so only the parent handles it; leaving the ``with`` block with an exception
  (``KeyboardInterrupt`` included) kills the workers at once instead of waiting for the
  tasks in flight, which are lost (a resumable sweep reruns them).
- **Process start paid once**: :meth:`WorkerPool.start` (called on entering the ``with``
  block) starts every worker and runs the optional ``initializer`` (e.g. imports and JIT
  compilation) in each before the first task; the same workers then serve every task.
  With ``wait_ready=False`` entering the block only launches them (:meth:`launch`, still
  from the caller's thread) and the caller works on while they import (sweeps do).

Use::

    with WorkerPool(2, initializer=warm_up) as pool:   # workers started and warmed here
        futures = [pool.submit(fn, arg) for arg in args]
        print(pool.pids)                                # the worker process ids

``worker_pool(n)`` is the same as a context-manager function. :func:`ray_session` is the
other place workers come from: a Ray session for a block (sweeps and catalogues with
``engine='ray'``). Only the standard library is imported at module level (Ray lazily), so
this module sits at the bottom of the ``experiments`` layer; of vei it imports only
``vei.errors``.
"""

from __future__ import annotations

import contextlib
import multiprocessing as mp
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor
from typing import Any

#: ``prctl`` option number of PR_SET_PDEATHSIG (linux/prctl.h).
PR_SET_PDEATHSIG = 1

#: Default period of the watchdog thread that checks the parent is alive [s].
DEFAULT_POLL_S = 0.5


def set_parent_death_signal(sig: int = signal.SIGKILL) -> bool:
    """Ask the Linux kernel to send ``sig`` to this process when its parent thread ends.

    Args:
        sig: signal number (default SIGKILL).
    Returns:
        True when the request was accepted; False on systems without ``prctl`` (not Linux,
        no libc) or when the call failed.
    """
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return libc.prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0) == 0
    except (OSError, AttributeError):  # pragma: no cover - libc without prctl
        return False


def _watch_parent(parent_pid: int, poll_s: float) -> None:
    """Body of the watchdog thread: end this process once its parent is not ``parent_pid``."""
    while True:
        time.sleep(poll_s)
        if os.getppid() != parent_pid:
            os._exit(1)


def _init_worker(
    parent_pid: int,
    poll_s: float,
    pdeathsig: bool,
    initializer: Callable[..., Any] | None,
    initargs: tuple,
    ready: Any,
) -> None:
    """Initializer of every worker: ignore SIGINT, die with the parent, run the user's
    initializer, then put this worker's pid on the ``ready`` queue."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if pdeathsig:
        set_parent_death_signal(signal.SIGKILL)
    # The parent may have died before prctl took effect: then nobody would signal us.
    if os.getppid() != parent_pid:
        os._exit(1)
    threading.Thread(
        target=_watch_parent, args=(parent_pid, poll_s), name="vei-parent-watchdog", daemon=True
    ).start()
    if initializer is not None:
        initializer(*initargs)
    ready.put(os.getpid())


class WorkerPool(ProcessPoolExecutor):
    """A spawn-based process pool whose workers end when this process ends (module docstring).

    Args:
        workers: number of worker processes (>= 1), all started by :meth:`start`.
        initializer, initargs: run once in each worker after the parent-death guards
            (picklable: a module-level function).
        poll_s: period of each worker's parent watchdog [s] (> 0).
        pdeathsig: use Linux's PR_SET_PDEATHSIG (default); False leaves only the portable
            watchdog (what other systems get; tests use it to check that path).
        wait_ready: entering the ``with`` block waits until every worker has run its
            initializer (:meth:`start`, default); False only launches them
            (:meth:`launch`): the caller works on while they import and initialise, and
            its first tasks wait in the queue (a failing initializer then breaks the pool
            at the first result).
        kill_on_exit: leaving the ``with`` block normally kills the workers at once, as an
            exception does, instead of waiting for the submitted tasks and for every
            worker to exit (the default): for a caller that has every result it needs
            (a worker still starting is then not waited for either).
        start_method: 'spawn' (default: a new interpreter that imports what it needs) or
            'fork' (a copy of this process: its imports and loaded code included, so a
            worker starts in milliseconds). Fork only where it is safe: Linux, one
            thread in this process, and no threaded runtime started in it (see
            :func:`fork_is_safe`).
    Attributes:
        pids: the worker process ids, in the order they became ready (empty before
            :meth:`start`).
    """

    def __init__(
        self,
        workers: int,
        *,
        initializer: Callable[..., Any] | None = None,
        initargs: tuple = (),
        poll_s: float = DEFAULT_POLL_S,
        pdeathsig: bool = True,
        wait_ready: bool = True,
        kill_on_exit: bool = False,
        start_method: str = "spawn",
    ) -> None:
        if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        if not poll_s > 0:
            raise ValueError(f"poll_s must be > 0, got {poll_s!r}")
        if start_method not in ("spawn", "fork"):
            raise ValueError(f"start_method must be 'spawn' or 'fork', got {start_method!r}")
        ctx = mp.get_context(start_method)
        self._ready = ctx.Queue()
        super().__init__(
            max_workers=workers,
            mp_context=ctx,
            initializer=_init_worker,
            initargs=(
                os.getpid(), float(poll_s), bool(pdeathsig), initializer, tuple(initargs),
                self._ready,
            ),
        )  # fmt: skip
        self.workers = workers
        self.wait_ready = bool(wait_ready)
        self.kill_on_exit = bool(kill_on_exit)
        self.pids: tuple[int, ...] = ()
        self._launch_futures: list = []

    def launch(self) -> WorkerPool:
        """Start every worker process now, from the calling thread, without waiting for
        their initializers; returns self.

        Trivial tasks submitted from the calling thread make the executor start all
        ``workers`` processes.
        """
        while (
            len(self._processes or {}) < self.workers
            and len(self._launch_futures) < 4 * self.workers
        ):
            self._launch_futures.append(self.submit(int))
        return self

    def start(self, timeout_s: float = 300.0) -> WorkerPool:
        """Start every worker now and wait until each has run its initializer; returns self.

        Trivial tasks submitted from the calling thread make the executor start all
        ``workers`` processes; each reports its pid once initialised.

        Raises:
            concurrent.futures.process.BrokenProcessPool: a worker died while starting
                (e.g. its initializer raised).
            TimeoutError: the workers were not all ready within ``timeout_s`` [s].
        """
        if self.pids:
            return self
        import queue

        futures = self.launch()._launch_futures
        pids: list[int] = []
        deadline = time.monotonic() + timeout_s
        while len(pids) < self.workers:
            try:
                pids.append(self._ready.get(timeout=0.1))
            except queue.Empty:
                for f in futures:
                    if f.done():
                        f.result()  # raises BrokenProcessPool when a worker died
                if time.monotonic() > deadline:
                    raise TimeoutError(
                        f"{self.workers} workers not ready in {timeout_s} s"
                    ) from None
        for f in futures:
            f.result()
        self.pids = tuple(pids)
        return self

    def kill_workers(self, timeout_s: float = 5.0) -> None:
        """Kill every worker now (SIGKILL), cancel pending tasks and shut the pool down.

        Tasks in flight are lost. Waits up to ``timeout_s`` [s] for the workers to be reaped.
        """
        procs = list((self._processes or {}).values())
        for p in procs:
            with contextlib.suppress(OSError, ValueError, AttributeError):
                p.kill()
        self.shutdown(wait=False, cancel_futures=True)
        deadline = time.monotonic() + timeout_s
        for p in procs:
            with contextlib.suppress(OSError, ValueError, AttributeError, AssertionError):
                p.join(max(0.0, deadline - time.monotonic()))

    def __enter__(self) -> WorkerPool:
        try:
            return self.start() if self.wait_ready else self.launch()
        except BaseException:  # Ctrl-C or a failed initializer while starting: no leftovers
            self.kill_workers()
            raise

    def __exit__(self, exc_type: Any, exc: Any, tb: Any) -> bool:
        if exc_type is None and not self.kill_on_exit:
            self.shutdown(wait=True)
        else:
            self.kill_workers()
        return False


def fork_is_safe() -> bool:
    """True when worker processes may be forked from this process: on Linux, with this
    thread the only one running and numba's threading layer not started yet (GNU OpenMP,
    numba's layer on Linux, hangs in a child forked after its threads ran; other threads'
    locks would be copied held)."""
    if not sys.platform.startswith("linux") or threading.active_count() != 1:
        return False
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    return parallel is None or not getattr(parallel, "_is_initialized", True)


@contextlib.contextmanager
def worker_pool(
    workers: int,
    *,
    initializer: Callable[..., Any] | None = None,
    initargs: tuple = (),
    poll_s: float = DEFAULT_POLL_S,
    pdeathsig: bool = True,
    start_method: str = "spawn",
) -> Iterator[WorkerPool]:
    """``with worker_pool(n) as pool``: a started :class:`WorkerPool` (same arguments).

    On a normal exit waits for the submitted tasks; on an exception (KeyboardInterrupt
    included) kills the workers at once and re-raises.
    """
    with WorkerPool(
        workers, initializer=initializer, initargs=initargs, poll_s=poll_s, pdeathsig=pdeathsig,
        start_method=start_method,
    ) as pool:  # fmt: skip
        yield pool


@contextlib.contextmanager
def ray_session(workers: int) -> Iterator[Any]:
    """``with ray_session(n) as ray``: the ``ray`` module, initialised for the block.

    Uses the session of this process when Ray is initialised already (and leaves it
    running); otherwise connects to the cluster at ``$RAY_ADDRESS`` when set, or starts a
    local Ray with ``num_cpus=workers``, and shuts it down at the end of the block.

    Raises:
        vei.errors.DependencyError: Ray is not installed (extra ``distributed``).
    """
    try:
        import ray
    except ImportError as exc:  # pragma: no cover - ray is in the 'distributed' extra
        from vei.errors import DependencyError

        raise DependencyError("engine 'ray' needs Ray: pip install 'vei[distributed]'") from exc
    started = False
    if not ray.is_initialized():
        os.environ.setdefault("RAY_DISABLE_IMPORT_WARNING", "1")
        address = os.environ.get("RAY_ADDRESS")
        if address:
            ray.init(address=address, log_to_driver=False, configure_logging=False)
        else:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False,
                     configure_logging=False)  # fmt: skip
        started = True
    try:
        yield ray
    finally:
        if started:
            ray.shutdown()
