"""One executor seam for batch work: serial, local processes, or a Dask cluster.

Every batch verb (detect, report, and later evaluate and sensitivity) runs its per-input
work through the standard :class:`concurrent.futures.Executor` interface, chosen by

=====================================  =============================================
``--jobs N`` (N > 1)                   a local :class:`~concurrent.futures.ProcessPoolExecutor`
                                       of N processes (no Dask needed)
``--scheduler local`` [``--jobs N``]   a Dask ``LocalCluster`` (N worker processes,
                                       default: the CPU count), one thread each
``--scheduler tcp://host:8786``        a running Dask scheduler
``--scheduler scheduler.json``         a running scheduler, by its scheduler file
neither                                ``DASK_SCHEDULER_ADDRESS`` when set, else serial
=====================================  =============================================

Dask is the optional extra ``impactcli[dask]``, imported only here and only when asked
for; without it a Dask choice raises :class:`DaskMissingError` with one line saying how
to install it.

Workers receive plain, picklable arguments (paths and URLs, never file contents) and the
task functions are top-level functions of the package, so any worker with the same
environment can run them. A dead worker is survived (:func:`run_tasks`; how, per executor:
docs/fleet.md, "Surviving a dead worker"); results come back in completion order, each
with the index of its input.
"""

from __future__ import annotations

import os
import traceback
from collections.abc import Callable, Generator, Iterator, Mapping, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, TypeVar

__all__ = [
    "DASK_RETRIES", "DaskMissingError", "ExecutorChoice", "SerialExecutor", "TaskFailure",
    "choose_executor", "make_executor", "run_tasks",
]

T = TypeVar("T")
R = TypeVar("R")

#: Times Dask re-runs a task that raised (``client.submit(..., retries=)``).
DASK_RETRIES = 2
#: Rounds of a local process pool: the first, plus one fresh pool for lost tasks.
POOL_ROUNDS = 2
#: The environment variable naming a default Dask scheduler (Dask's own convention).
SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"
INSTALL_HINT = "pip install 'impactcli[dask]'"

Kind = Literal["serial", "processes", "dask"]


class DaskMissingError(RuntimeError):
    """A Dask scheduler was asked for but the ``dask`` extra is not installed."""


@dataclass(frozen=True)
class ExecutorChoice:
    """Where batch work runs.

    Attributes:
        kind: ``serial``, ``processes`` (local pool) or ``dask``.
        workers: worker processes (serial: 1; a remote Dask cluster: 0 = the cluster's).
        address: Dask only: ``local`` (a LocalCluster), a scheduler address
            (``tcp://host:8786``) or a scheduler file path.
        origin: what chose it: ``--jobs``, ``--scheduler``, the environment, or the default.
    """

    kind: Kind
    workers: int = 1
    address: str | None = None
    origin: str = "default"

    def describe(self) -> str:
        """One line for logs and the batch summary."""
        if self.kind == "serial":
            return "serial"
        if self.kind == "processes":
            return f"{self.workers} local processes"
        if self.address == "local":
            return f"Dask LocalCluster ({self.workers} workers)"
        return f"Dask scheduler {self.address} (from {self.origin})"

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready form (batch summary)."""
        return {"kind": self.kind, "workers": self.workers, "address": self.address,
                "origin": self.origin}


def choose_executor(jobs: int | None = None, scheduler: str | None = None,
                    environ: Mapping[str, str] | None = None) -> ExecutorChoice:
    """Decide where batch work runs (the table of the module docstring).

    Args:
        jobs: ``--jobs`` (None when not given); with ``scheduler="local"`` the number of
            LocalCluster workers.
        scheduler: ``--scheduler``: ``local``, an address or a scheduler file.
        environ: the environment (default ``os.environ``) for ``DASK_SCHEDULER_ADDRESS``.

    Raises:
        ValueError: ``--jobs`` combined with a remote scheduler, or ``jobs`` < 1.
    """
    env = os.environ if environ is None else environ
    if jobs is not None and jobs < 1:
        raise ValueError(f"--jobs must be at least 1, not {jobs}")
    if scheduler is not None:
        scheduler = scheduler.strip()
        if scheduler == "local":
            return ExecutorChoice("dask", jobs or (os.cpu_count() or 1), "local", "--scheduler")
        if jobs is not None:
            raise ValueError("--jobs applies to local processes or --scheduler local; a "
                             "running cluster has the workers it has")
        return ExecutorChoice("dask", 0, scheduler, "--scheduler")
    if jobs is None and env.get(SCHEDULER_ENV):
        return ExecutorChoice("dask", 0, env[SCHEDULER_ENV].strip(), SCHEDULER_ENV)
    if jobs is None or jobs == 1:
        return ExecutorChoice("serial", 1, None, "--jobs" if jobs else "default")
    return ExecutorChoice("processes", jobs, None, "--jobs")


class SerialExecutor(Executor):
    """Runs each task at submission, in this process (the ``--jobs 1`` executor)."""

    def submit(self, fn: Callable[..., R], /, *args: Any, **kwargs: Any) -> Future[R]:
        fut: Future[R] = Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as err:  # delivered through the future, as executors do
            if not isinstance(err, Exception):
                raise
            fut.set_exception(err)
        return fut


#: Modules the local pool's fork server imports once, so that workers start warm.
POOL_START_METHOD = "forkserver"
POOL_PRELOAD = (
    "impactcli.run.forkserver_guard", "impactcli.run.batch", "impactcli.run.one_log",
    "impactcli.logs", "impactcli.outputs.timeline",
)


#: The longest path an AF_UNIX socket binds to (Linux: 108 bytes with the final NUL).
SOCKET_PATH_MAX = 107
#: What multiprocessing appends to TMPDIR for the fork server's socket:
#: ``/pymp-XXXXXXXX/listener-XXXXXXXX``.
SOCKET_SUFFIX_LEN = 32
#: Where the fork server's socket goes when TMPDIR's path is too long for one.
SHORT_TEMP_DIRS = ("/tmp", "/var/tmp")


def socket_folder() -> str:
    """Multiprocessing's temporary folder (made once per process), where the fork server
    listens on a socket: in TMPDIR, unless TMPDIR's path is too long for a socket — then
    every ``--jobs N`` run would fail ("AF_UNIX path too long") — when it is made in the
    first of :data:`SHORT_TEMP_DIRS` that is writable (as Python 3.14 does). It holds the
    socket only, and multiprocessing removes it when the process ends."""
    import multiprocessing.util
    import tempfile

    here = tempfile.gettempdir()
    short = next((d for d in SHORT_TEMP_DIRS
                  if os.path.isdir(d) and os.access(d, os.W_OK | os.X_OK)), None)
    if len(here) + SOCKET_SUFFIX_LEN <= SOCKET_PATH_MAX or short is None:
        return multiprocessing.util.get_temp_dir()
    saved = tempfile.tempdir
    tempfile.tempdir = short  # get_temp_dir makes its folder in gettempdir(), once
    try:
        return multiprocessing.util.get_temp_dir()
    finally:
        tempfile.tempdir = saved


def process_pool(workers: int) -> ProcessPoolExecutor:
    """A local pool whose workers are forked from a fork server (not from this process,
    which may run threads, e.g. a Dask client's) with the pipeline already imported; the
    fork server and every worker die with this process (:mod:`impactcli.run.stopping`)."""
    import multiprocessing as mp

    from .stopping import worker_init

    ctx = mp.get_context(POOL_START_METHOD)
    if POOL_START_METHOD == "forkserver":
        ctx.set_forkserver_preload(list(POOL_PRELOAD))
        socket_folder()
    return ProcessPoolExecutor(max_workers=workers, mp_context=ctx, initializer=worker_init,
                               initargs=(os.getpid(), workers))


@contextmanager
def pool(workers: int) -> Iterator[ProcessPoolExecutor]:
    """:func:`process_pool` for a block: shut down waiting for its tasks when the block
    ends normally; stopped at once (:func:`impactcli.run.stopping.stop_workers`: nothing
    more dispatched, running tasks unwound, workers gone within a bounded time) when it
    ends by an exception, a signal's stop or a consumer that left (``GeneratorExit``)."""
    from .stopping import stop_workers

    ex = process_pool(workers)
    try:
        yield ex
    except BaseException:
        stop_workers(ex)
        raise
    ex.shutdown(wait=True)


def require_dask() -> Any:
    """The ``distributed`` module; DaskMissingError (exit 2, naming the extra) without it."""
    try:
        import distributed
    except ImportError:
        raise DaskMissingError(f"a Dask scheduler needs the dask extra: {INSTALL_HINT}") from None
    return distributed


def _is_scheduler_file(address: str) -> bool:
    return "://" not in address and (address.lower().endswith(".json") or Path(address).is_file())


@contextmanager
def dask_client(choice: ExecutorChoice) -> Iterator[Any]:
    """A ``distributed.Client`` for a Dask choice (a LocalCluster is started and closed)."""
    distributed = require_dask()
    address = choice.address or "local"
    if address == "local":
        with distributed.LocalCluster(
            n_workers=max(choice.workers, 1), threads_per_worker=1, processes=True,
            dashboard_address=":0", silence_logs=40,
        ) as cluster, distributed.Client(cluster) as client:
            yield client
        return
    if _is_scheduler_file(address):
        if not Path(address).is_file():
            raise FileNotFoundError(f"Dask scheduler file {address} not found")
        client_cm = distributed.Client(scheduler_file=address)
    else:
        client_cm = distributed.Client(address, timeout="30s")
    with client_cm as client:
        yield client


@contextmanager
def make_executor(jobs: int | None = None, scheduler: str | None = None, *,
                  environ: Mapping[str, str] | None = None,
                  client: Any = None) -> Iterator[Executor]:
    """The executor for ``--jobs``/``--scheduler`` (see :func:`choose_executor`).

    Args:
        jobs, scheduler, environ: as :func:`choose_executor`.
        client: an existing ``distributed.Client`` to use instead (tests, notebooks);
            it is not closed.

    Yields:
        A :class:`concurrent.futures.Executor`: :class:`SerialExecutor`, a
        ``ProcessPoolExecutor`` or Dask's ``ClientExecutor`` (``retries`` =
        :data:`DASK_RETRIES`, ``pure=False``). Closed (and a LocalCluster stopped) on exit.

    Raises:
        DaskMissingError: Dask was asked for and the extra is not installed.
    """
    if client is not None:
        yield client.get_executor(retries=DASK_RETRIES, pure=False)
        return
    choice = choose_executor(jobs, scheduler, environ)
    if choice.kind == "serial":
        yield SerialExecutor()
    elif choice.kind == "processes":
        with pool(choice.workers) as ex:
            yield ex
    else:
        with dask_client(choice) as cl:
            yield cl.get_executor(retries=DASK_RETRIES, pure=False)


@dataclass(frozen=True)
class TaskFailure:
    """A task that produced no result.

    Attributes:
        kind: ``worker-lost`` (its worker process died, also on the retry) or ``error``
            (the task raised; for impactcli's own tasks this means a bug).
        reason: one line.
        traceback: the formatted traceback when there is one.
    """

    kind: Literal["worker-lost", "error"]
    reason: str
    traceback: str = ""


def _failure(err: BaseException) -> TaskFailure:
    name = type(err).__name__
    if name == "KilledWorker":  # distributed.scheduler.KilledWorker
        return TaskFailure("worker-lost", f"its Dask worker died repeatedly ({err})")
    tb = "".join(traceback.format_exception(type(err), err, err.__traceback__))
    return TaskFailure("error", f"{name}: {err}", tb)


def run_tasks(fn: Callable[[T], R], items: Sequence[T], *, jobs: int | None = None,
              scheduler: str | None = None, environ: Mapping[str, str] | None = None,
              client: Any = None) -> Generator[tuple[int, R | TaskFailure], None, None]:
    """Run ``fn(item)`` for every item; yield ``(index, result or TaskFailure)`` as they finish.

    ``fn`` must be a picklable top-level function and the items picklable (paths, URLs,
    small dataclasses). A local pool that breaks is replaced once (module docstring).
    Exceptions raised by ``fn`` become :class:`TaskFailure` records; the batch goes on.
    """
    if not items:
        return
    choice = (ExecutorChoice("dask", 0, "client", "client") if client is not None
              else choose_executor(jobs, scheduler, environ))
    if choice.kind == "processes" and len(items) > 1:
        yield from _run_pool(fn, items, choice.workers)
        return
    if choice.kind == "processes":  # one item: no pool to start
        choice = ExecutorChoice("serial")
    if choice.kind == "serial":
        for i, item in enumerate(items):
            try:
                yield i, fn(item)
            except Exception as err:
                yield i, _failure(err)
        return
    with make_executor(jobs, scheduler, environ=environ, client=client) as ex:
        futures = {ex.submit(fn, item): i for i, item in enumerate(items)}
        try:
            for fut in as_completed(futures):
                try:
                    res = fut.result()
                except Exception as err:
                    yield futures[fut], _failure(err)
                else:
                    yield futures[fut], res
        except BaseException:  # stopped (a signal, a consumer gone): dispatch nothing more
            for fut in futures:
                fut.cancel()
            raise


def _run_pool(fn: Callable[[T], R], items: Sequence[T],
              workers: int) -> Iterator[tuple[int, R | TaskFailure]]:
    from .stopping import run_in_worker

    pending = list(range(len(items)))
    for _ in range(POOL_ROUNDS):
        if not pending:
            return
        lost: list[int] = []
        with pool(min(workers, len(pending))) as ex:
            futures = {ex.submit(run_in_worker, fn, items[i]): i for i in pending}
            for fut in as_completed(futures):
                i = futures[fut]
                try:
                    res = fut.result()
                except BrokenProcessPool:
                    lost.append(i)
                except Exception as err:
                    yield i, _failure(err)
                else:
                    yield i, res
        pending = sorted(lost)
    # A break takes every unfinished task down with it, started or not: run each survivor
    # alone, twice at most, so that only a task that kills its own worker twice is lost.
    for i in pending:
        yield i, _run_alone(fn, items[i])


def _run_alone(fn: Callable[[T], R], item: T) -> R | TaskFailure:
    from .stopping import run_in_worker

    for _ in range(POOL_ROUNDS):
        with pool(1) as ex:
            try:
                return ex.submit(run_in_worker, fn, item).result()
            except BrokenProcessPool:
                continue
            except Exception as err:
                return _failure(err)
    return TaskFailure("worker-lost", f"its worker process died {POOL_ROUNDS} times when run "
                                      "alone (after a pool broke)")
