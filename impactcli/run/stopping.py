"""Stopping a run: SIGINT and SIGTERM in the main process, and the processes of a local pool
(``--jobs N``), which must never outlive it.

Main process (:func:`stop_on_signals`): SIGINT (Ctrl-C) and SIGTERM raise
:class:`~impactcli.errors.Interrupted` where the main thread stands, so every ``with`` and
``finally`` on the way out runs: temporary files are removed, outputs already moved into
place stay. The CLI exits 128 + the signal's number (130, 143). A second signal while the
run stops is ignored: the stop is bounded (:data:`STOP_GRACE_S`). A signal that lands
while a temporary file or folder is made is raised once its removal is registered
(:func:`impactcli.files.whole`); one that lands in a removal is raised once it is done
(:func:`impactcli.files.discard`). A signal that lands in a
C library's callback (numba compiling: :data:`CALLBACK_MODULES`), where a raised exception
would be printed with its traceback and dropped, is sent again once it has returned.

A pool's workers (:func:`worker_init`, run in each worker; :func:`run_in_worker` around
each task) ignore SIGINT — a Ctrl-C reaches the whole process group, and the main process
decides — and on SIGTERM unwind the task they run (removing its temporary files) and exit.
:func:`stop_workers` sends them that SIGTERM when the main process stops, waits at most
:data:`STOP_GRACE_S`, then kills what is left.

No orphans when the main process itself is killed (``kill -9``, where nothing of it runs):

- each worker watches the main process (:func:`watch_process`: a pidfd where Linux has
  one, else a poll) and stops itself, as on SIGTERM, when it is gone; on Linux it also asks
  for SIGTERM when its parent, the pool's fork server, dies (``PR_SET_PDEATHSIG``);
- the fork server asks for SIGKILL when the main process dies
  (:mod:`impactcli.run.forkserver_guard`, imported by the fork server only);
- multiprocessing's resource tracker ends by itself once every process holding its pipe
  (the main process, the fork server, the workers) is gone.

Elsewhere than Linux the parent-death signal is not available and the watch polls: the
workers still stop, within :data:`WATCH_INTERVAL_S`.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from typing import Any, TypeVar

from ..errors import Interrupted
from ..files import hold_stop, process_running

T = TypeVar("T")
R = TypeVar("R")

#: How long the workers of a stopped batch get to unwind (remove their temporary files)
#: after SIGTERM before they are killed [s].
STOP_GRACE_S = 5.0
#: How often a worker looks whether the main process is still there, where it cannot wait
#: on a pidfd [s].
WATCH_INTERVAL_S = 0.25
#: Linux ``prctl`` option: the signal a process gets when its parent dies.
PR_SET_PDEATHSIG = 1

_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


#: Python run by a C library's callback, where an exception is printed ("Exception ignored
#: in ...", with its traceback) and dropped instead of propagated: llvmlite's object cache
#: while numba compiles a kernel. A stop signal that lands there is sent again this much
#: later [s], once the callback has returned.
CALLBACK_MODULES = ("llvmlite",)
DEFER_S = 0.05
#: Deferred this many times in a row, the stop raises wherever it lands (bounded stop).
MAX_DEFERRALS = 20
_deferrals = [0]


def in_native_callback(frame: Any) -> bool:
    """Whether ``frame`` (a signal handler's) runs inside a package of
    :data:`CALLBACK_MODULES` (a path component of its file, not any name containing it)."""
    parts = tuple(f"{os.sep}{m}{os.sep}" for m in CALLBACK_MODULES)
    while frame is not None:
        if any(p in frame.f_code.co_filename for p in parts):
            return True
        frame = frame.f_back
    return False


def deferred(signum: int, frame: Any) -> bool:
    """When ``frame`` is inside a C library's callback, send ``signum`` to this process
    again :data:`DEFER_S` later — if the same handler still stands then — and return True:
    the handler must not raise there. At most :data:`MAX_DEFERRALS` times in a row."""
    if not in_native_callback(frame) or _deferrals[0] >= MAX_DEFERRALS:
        _deferrals[0] = 0
        return False
    _deferrals[0] += 1
    handler = signal.getsignal(signum)

    def again() -> None:
        if signal.getsignal(signum) is handler:
            os.kill(os.getpid(), signum)

    t = threading.Timer(DEFER_S, again)
    t.daemon = True
    t.start()
    return True


def _raise_interrupted(signum: int, frame: Any) -> None:
    if deferred(signum, frame):
        return
    for sig in _STOP_SIGNALS:  # the stop is under way: a second signal does not cut it short
        signal.signal(sig, signal.SIG_IGN)
    if hold_stop(signum):  # raised as the file operation under way ends
        return
    raise Interrupted(signum, signal.Signals(signum).name)


@contextlib.contextmanager
def stop_on_signals() -> Iterator[None]:
    """Within the block (in the main thread), SIGINT and SIGTERM raise
    :class:`~impactcli.errors.Interrupted`; the previous handlers come back after it."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = {sig: signal.getsignal(sig) for sig in _STOP_SIGNALS}
    try:
        for sig in _STOP_SIGNALS:
            signal.signal(sig, _raise_interrupted)
        yield
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def after_finish() -> None:
    """From here on the run has finished (its outputs written, its exit code decided) and
    the process only tears down (the interpreter's exit: threads joined, libraries'
    ``atexit``): a SIGINT or SIGTERM then is said and ignored, once, where it would have
    raised into the teardown (a traceback, or exit 130 over a finished run's 0 or 1 — a
    trial's Ctrl-C 4.3 s into a 4.0 s run). A second one acts as the signal does."""
    if threading.current_thread() is not threading.main_thread():
        return
    for sig in _STOP_SIGNALS:
        signal.signal(sig, _finished)


def _finished(signum: int, frame: Any) -> None:
    signal.signal(signum, signal.SIG_DFL)
    name = signal.Signals(signum).name
    with contextlib.suppress(OSError, ValueError):
        sys.stderr.write(f"impactcli: {name} after the run had finished: ignored — its "
                         "outputs and exit code stand\n")
        sys.stderr.flush()


def die_with_parent(sig: int = signal.SIGKILL) -> bool:
    """Ask the kernel to send ``sig`` to this process when its parent dies (Linux
    ``prctl(PR_SET_PDEATHSIG)``); False where that is not available (nothing done)."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(PR_SET_PDEATHSIG, int(sig), 0, 0, 0)) == 0
    except (OSError, AttributeError):
        return False


#: Whether this worker runs a task now (``running[0]``: :func:`run_in_worker`).
_running = [False]


def _worker_sigterm(signum: int, frame: Any) -> None:
    if deferred(signum, frame):
        return
    if _running[0]:  # unwind the task (its temporary files go), then exit: run_in_worker
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        if hold_stop(signum):
            return
        raise Interrupted(signum, signal.Signals(signum).name)
    os._exit(128 + signum)  # idle: nothing to clean


def worker_init(main_pid: int, workers: int = 1) -> None:
    """A pool worker's start (``ProcessPoolExecutor(initializer=...)``): SIGINT ignored,
    SIGTERM stops it (module docstring), it stops when ``main_pid`` is gone, and its own
    threads take its share of the cores, one of ``workers`` (:mod:`impactcli.cores`)."""
    from ..cores import set_workers

    set_workers(workers)
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _worker_sigterm)
    die_with_parent(signal.SIGTERM)
    watch_process(main_pid)


def run_in_worker(fn: Callable[[T], R], item: T) -> R:
    """``fn(item)`` in a pool worker; stopped by SIGTERM, the task unwinds and the worker
    exits (the pool sees it gone; the main process is stopping anyway). Before the exit,
    which runs no exit hook, what the task's frames held is collected, so that the
    temporary folders left to their finalizers (a store made as the stop came, before a
    ``try`` would close it) are removed."""
    import gc

    _running[0] = True
    try:
        return fn(item)
    except Interrupted as stop:
        code = stop.exit_code
    finally:
        _running[0] = False
    gc.collect()  # the exception and its frames are gone: their objects are finalized
    os._exit(code)


def watch_process(pid: int) -> threading.Thread:
    """A daemon thread that stops this process (SIGTERM to itself, then
    :func:`os._exit` after :data:`STOP_GRACE_S`) once process ``pid`` has ended."""
    def wait_gone() -> None:
        fd = None
        with contextlib.suppress(AttributeError, OSError):
            fd = os.pidfd_open(pid)
        if fd is not None:
            import select

            select.select([fd], [], [])  # readable once the process has ended
        else:
            while process_running(pid):
                time.sleep(WATCH_INTERVAL_S)
        os.kill(os.getpid(), signal.SIGTERM)
        time.sleep(STOP_GRACE_S)
        os._exit(128 + signal.SIGTERM)

    t = threading.Thread(target=wait_gone, name="impactcli-watch-main", daemon=True)
    t.start()
    return t


def stop_workers(executor: Any, grace_s: float = STOP_GRACE_S) -> None:
    """Stop a local pool now: nothing more dispatched (pending tasks cancelled), every
    worker sent SIGTERM (it unwinds its task, removing its temporary files), waited for
    at most ``grace_s``, then killed."""
    import multiprocessing as mp

    procs = list(mp.active_children())
    # CPython's thread that manages the pool: it closes the pool's wake-up pipe once the
    # workers are gone, and at exit the interpreter writes to that pipe without a lock
    # (3.11's concurrent.futures.process._python_exit): the thread is waited for here, so
    # the two never meet ("OSError: Bad file descriptor" printed as the process ends)
    manager = getattr(executor, "_executor_manager_thread", None)
    executor.shutdown(wait=False, cancel_futures=True)
    for p in procs:
        with contextlib.suppress(OSError, ValueError):
            p.terminate()
    deadline = time.monotonic() + grace_s
    for p in procs:
        p.join(max(deadline - time.monotonic(), 0.0))
    for p in procs:
        if p.is_alive():
            with contextlib.suppress(OSError, ValueError):
                p.kill()
            p.join(1.0)
    if isinstance(manager, threading.Thread) and manager.is_alive():
        manager.join(max(deadline - time.monotonic(), 1.0))
