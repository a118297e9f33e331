"""Where simulator runs execute: a local process pool, a Dask cluster, or in-process.

Every simulator call of a study goes through a :class:`concurrent.futures.Executor`
made by :func:`make_executor`:

- ``workers=N`` (N ≥ 1, default: every core this process may use): a local
  process pool with the ``spawn`` start method (PyBullet and torch do not
  survive ``fork``), restarted when a worker process dies;
- ``workers=0``: in-process, no isolation (debugging, profiling);
- ``scheduler="tcp://host:8786"``: the executor of a ``distributed.Client``
  connected to a running Dask scheduler (install ``susp-bo[cluster]``; the
  workers need susp_bo installed). The study code does not change.

:func:`run_tasks` submits a batch of tasks at once (so an EGO batch fills the
workers), reports each result as it completes (so the evaluation store records
it at once) and returns the outcomes in task order. Nothing a task does kills
the study: an exception in the task becomes a failed outcome of kind
``"error"``; a worker that dies (``os._exit``, segfault, OOM killer, lost
cluster node) becomes a failed outcome of kind ``"crash"`` — see
:mod:`susp_bo.store` for what a resumed study does with each kind.

A dead worker breaks a whole process pool and every task then in flight fails
with it, innocent or not. :func:`run_tasks` restarts the pool and re-runs the
affected tasks by bisection: halves of the affected set run in parallel, a
half that breaks the pool again is split again, and a task is declared crashed
only when it breaks the pool running alone. One crashing task in a batch of n
therefore costs about log2(n) extra parallel rounds, and a transient crash
(OOM kill) of a task that ran beside others gets a second run.
"""

from __future__ import annotations

import multiprocessing
import os
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any, Literal

from susp_bo.progress import progress_bar

_THREAD_VARIABLES = ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


@dataclass(frozen=True, eq=False)  # holds arrays: compare fields, not objects
class TaskOutcome:
    """The result of one task of :func:`run_tasks`.

    Attributes:
        index: position of the task in the submitted sequence.
        ok: True when the task returned.
        value: what the task returned (None when it failed).
        reason: why it failed, ``"ExceptionType: message"`` (None when ok).
        failure_kind: ``"error"`` (the task raised) or ``"crash"`` (its worker
            died or was lost); None when ok.
        seconds: wall time of the task in its worker (s); for a crash, the time
            from submission until the crash was detected.
    """

    index: int
    ok: bool
    value: Any = None
    reason: str | None = None
    failure_kind: Literal["error", "crash"] | None = None
    seconds: float = 0.0


def default_workers() -> int:
    """Number of cores this process may run on (its CPU affinity), at least 1."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


class InProcessExecutor(Executor):
    """Runs each task at submission, in this process (``workers=0``).

    No isolation: a task that kills its process kills the study.
    """

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        future: Future = Future()
        future.set_running_or_notify_cancel()
        try:
            future.set_result(fn(*args, **kwargs))
        except Exception as error:
            future.set_exception(error)
        return future


_PARENT_POLL_S = 0.5


def _exit_when_orphaned(parent_pid: int, poll_s: float = _PARENT_POLL_S) -> None:
    """Watchdog loop of a worker: ``os._exit`` as soon as its parent process is gone.

    A parent killed with SIGKILL runs no cleanup, and a spawn-pool worker blocked on
    its call queue would wait forever (holding the multiprocessing resource tracker's
    pipe open, so the tracker stays too). When the parent dies the worker is
    re-parented (to init or a subreaper), so ``os.getppid()`` changes: checked every
    ``poll_s`` seconds. Portable (no ``prctl``): ``PR_SET_PDEATHSIG`` fires when the
    parent *thread* that spawned the worker ends, which would kill healthy workers of
    a pool submitted to from a short-lived thread.
    """
    while os.getppid() == parent_pid:
        time.sleep(poll_s)
    os._exit(1)


def _die_with_parent(parent_pid: int) -> None:
    """Start the orphan watchdog (:func:`_exit_when_orphaned`) in a daemon thread."""
    import threading

    threading.Thread(
        target=_exit_when_orphaned,
        args=(parent_pid,),
        name="susp-bo-orphan-watchdog",
        daemon=True,
    ).start()


def _single_threaded_worker(parent_pid: int | None = None) -> None:
    """Process-pool initializer: one BLAS/OpenMP thread per worker, so N workers use N cores;
    and the worker exits when the study process dies, even by SIGKILL."""
    for name in _THREAD_VARIABLES:
        os.environ.setdefault(name, "1")
    if "numpy" in sys.modules:  # loaded before this ran (a program importing NumPy first:
        # spawned workers import it again): its BLAS read the variables already
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=1, user_api="blas")
    if "torch" in sys.modules:
        sys.modules["torch"].set_num_threads(1)
    _die_with_parent(os.getppid() if parent_pid is None else parent_pid)


_RESTART_TIMEOUT_S = 60.0
_RESTART_GRACE_S = 2.0  # the manager thread's own terminate usually ends within it


def _kill_workers(processes: dict[int, Any] | None) -> None:
    """SIGKILL every live worker process in ``processes`` (CPython's ``pid -> Process``
    dict of a pool, shared by the pool and its manager thread)."""
    try:
        alive = list((processes or {}).values())
    except RuntimeError:  # the manager thread changed the dict while it was copied
        return
    for process in alive:
        if process.is_alive():
            process.kill()


class RestartableProcessPool(Executor):
    """A ``spawn`` process pool that can be replaced by a fresh one after a worker died.

    Args:
        max_workers: number of worker processes (≥ 1).
    """

    def __init__(self, max_workers: int) -> None:
        if max_workers < 1:
            raise ValueError(f"max_workers: {max_workers} is not allowed; expected >= 1")
        self.max_workers = max_workers
        self.restarts = 0
        self._pool = self._new_pool()

    def _new_pool(self) -> ProcessPoolExecutor:
        return ProcessPoolExecutor(
            max_workers=self.max_workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_single_threaded_worker,
            initargs=(os.getpid(),),
        )

    def submit(self, fn: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        return self._pool.submit(fn, *args, **kwargs)

    def restart(self) -> None:
        """Shut the (broken) pool down, killing its workers, and start a fresh one.

        ``shutdown(wait=True)`` alone can hang forever on CPython 3.11: a worker the pool
        spawned for a task submitted just as it broke escapes the pool's own terminate
        and then waits on the call queue while the pool's manager thread joins it (seen
        under load in the crash tests). So every worker still alive is killed, repeatedly,
        until the manager thread has finished.
        """
        old = self._pool
        # the worker dict, taken before shutdown: shutdown sets the pool's _processes to
        # None while the manager thread keeps joining the workers in this same dict (a
        # kill loop reading pool._processes afterwards found nothing and left a worker
        # blocked on the call queue, and the interpreter's exit hung joining it)
        manager = getattr(old, "_executor_manager_thread", None)
        processes = getattr(manager, "processes", None) or getattr(old, "_processes", None)
        old.shutdown(wait=False, cancel_futures=True)
        started = time.monotonic()
        while manager is not None and manager.is_alive():
            waited = time.monotonic() - started
            if waited > _RESTART_TIMEOUT_S:
                break
            if waited > _RESTART_GRACE_S:  # not finished on its own: a worker escaped
                _kill_workers(processes)
            manager.join(0.2)
        _kill_workers(processes)
        self._pool = self._new_pool()
        self.restarts += 1

    def shutdown(self, wait: bool = True, *, cancel_futures: bool = False) -> None:
        self._pool.shutdown(wait=wait, cancel_futures=cancel_futures)


_PORT_SCHEMES = ("tcp", "tls", "ws", "wss", "ucx")
"""Dask comm protocols whose addresses are ``host:port`` (``inproc://`` has no port)."""


def scheduler_address_problem(address: str) -> str | None:
    """What is wrong with a Dask scheduler address, or None when it is well formed.

    Dask's grammar: ``[protocol://]host:port``, the protocol ``tcp`` when omitted (so
    ``10.0.0.5:8786`` is allowed), or ``inproc://…``. Checked before anything is written or
    connected: Dask itself raises a bare ``ValueError`` from inside ``Client`` for a
    malformed one (and its half-built client then times out again when collected).

    Args:
        address: the address as given (``--scheduler`` or ``[executor] scheduler``).

    Returns:
        A plain reason naming what is missing, or None.
    """
    scheme, separator, location = address.partition("://")
    if not separator:
        scheme, location = "tcp", address
    if scheme == "inproc":
        return None if location else "no location after 'inproc://'"
    if scheme not in _PORT_SCHEMES:
        return f"unknown protocol {scheme!r} (expected one of {', '.join(_PORT_SCHEMES)}, inproc)"
    ipv6 = "an IPv6 host goes in brackets, [addr]:port (e.g. tcp://[::1]:8786)"
    if location.startswith("["):  # Dask's IPv6 notation (outside probe, session 29: an
        # unclosed bracket passed this check and Dask then timed out after 20 s)
        host, bracket, tail = location[1:].partition("]")
        if not bracket or "[" in host:
            return f"the '[' before the host is not closed by ']': {ipv6}"
        colon, port = tail[:1], tail[1:]
        if tail and colon != ":":
            return f"after ']' comes ':port': {ipv6}"
    else:
        host, colon, port = location.rpartition(":")
        if ":" in host or "[" in host or "]" in host:
            return ipv6
    if not colon or not port.isdigit() or not 0 < int(port) < 65536:
        return "no port number in 1–65535 after the host (expected host:port)"
    if host == "":
        return "no host before the port"
    return None


@contextmanager
def make_executor(
    workers: int | None = None, scheduler: str | None = None, connect_timeout_s: float = 10.0
) -> Iterator[Executor]:
    """The executor a study runs its simulations on.

    Args:
        workers: local worker processes; None = :func:`default_workers`,
            0 = in-process. Exclusive with ``scheduler``.
        scheduler: address of a running Dask scheduler (``tcp://host:8786``).
        connect_timeout_s: how long to try reaching the scheduler (s).

    Yields:
        The executor; shut down (and the Dask client closed) on exit.

    Raises:
        ValueError: both ``workers`` and ``scheduler`` given, workers < 0, or a malformed
            scheduler address (:func:`scheduler_address_problem`).
        ImportError: a scheduler is given but dask.distributed is not installed.
        ConnectionError: the scheduler cannot be reached.
    """
    if workers is not None and scheduler is not None:
        raise ValueError(
            f"workers={workers} and scheduler={scheduler!r}: give one of them, not both"
        )
    if scheduler is not None:
        problem = scheduler_address_problem(scheduler)
        if problem is not None:
            raise ValueError(f"scheduler {scheduler!r}: {problem}, e.g. 'tcp://10.0.0.5:8786'")
        with _dask_executor(scheduler, connect_timeout_s) as executor:
            yield executor
        return
    count = default_workers() if workers is None else workers
    if isinstance(count, bool) or not isinstance(count, int) or count < 0:
        raise ValueError(f"workers: {workers!r} is not allowed; expected an integer >= 0 or None")
    if count == 0:
        yield InProcessExecutor()
        return
    pool = RestartableProcessPool(count)
    try:
        yield pool
    finally:
        pool.shutdown(wait=True, cancel_futures=True)


@contextmanager
def _dask_executor(scheduler: str, connect_timeout_s: float) -> Iterator[Executor]:
    try:
        from distributed import Client
    except ImportError as error:
        raise ImportError(
            f"scheduler {scheduler!r}: running on a Dask cluster needs dask.distributed; "
            "install it with: pip install 'susp-bo[cluster]'"
        ) from error
    try:
        client = Client(scheduler, timeout=connect_timeout_s, set_as_default=False)
    except (OSError, TimeoutError) as error:
        raise ConnectionError(
            f"scheduler {scheduler!r}: cannot connect within {connect_timeout_s:g} s ({error}); "
            "is `dask scheduler` running there and reachable from this machine?"
        ) from error
    try:
        # pure=False: every submission runs, even of equal arguments (no key deduplication).
        yield client.get_executor(pure=False)
    finally:
        client.close()


def _call(fn: Callable[..., Any], args: tuple[Any, ...]) -> tuple[bool, Any, str | None, float]:
    """Worker side of a task: run it, turn an exception into a reason, time it."""
    start = time.perf_counter()
    try:
        value = fn(*args)
    except Exception as error:
        return False, None, describe_exception(error), time.perf_counter() - start
    return True, value, None, time.perf_counter() - start


def describe_exception(error: BaseException) -> str:
    """``"ExceptionType: message"``, with a ``reason`` attribute appended when it adds to it."""
    text = f"{type(error).__name__}: {error}"
    reason = getattr(error, "reason", None)
    if isinstance(reason, str) and reason and reason not in text:
        text += f" (reason: {reason})"
    return text


def run_tasks(
    executor: Executor,
    fn: Callable[..., Any],
    tasks: Sequence[Sequence[Any]],
    on_result: Callable[[TaskOutcome], None] | None = None,
    desc: str = "simulations",
    progress: bool = True,
) -> list[TaskOutcome]:
    """Run ``fn(*task)`` for every task on the executor, all submitted at once.

    Args:
        executor: from :func:`make_executor` (any Executor works; only a
            :class:`RestartableProcessPool` survives a dead worker with its
            innocent tasks re-run — on a plain pool they become crashes).
        fn: a picklable top-level function (workers import it by name).
        tasks: positional-argument tuples, one per task; each picklable.
        on_result: called in this process, in completion order, once per task,
            as soon as its outcome is known (record it in the store here). An
            exception it raises stops the batch.
        desc: label of the progress bar (on stderr, see susp_bo.progress).
        progress: show the bar.

    Returns:
        One :class:`TaskOutcome` per task, in task order.
    """
    arguments = [tuple(task) for task in tasks]
    outcomes: list[TaskOutcome | None] = [None] * len(arguments)
    with progress_bar(total=len(arguments), desc=desc, unit="run", disable=not progress) as bar:

        def finish(outcome: TaskOutcome) -> None:
            outcomes[outcome.index] = outcome
            if on_result is not None:
                on_result(outcome)
            bar.update(1)

        groups: deque[list[int]] = deque([list(range(len(arguments)))])
        while groups:
            group = groups.popleft()
            start = time.perf_counter()
            broken = _run_group(executor, fn, arguments, group, finish)
            if not broken:
                continue
            if not isinstance(executor, RestartableProcessPool):
                for index in broken:
                    finish(_crash(index, "worker process died; the pool is broken", start))
                continue
            executor.restart()
            if len(group) == 1:
                finish(_crash(group[0], "worker process died running this task alone", start))
                continue
            half = (len(broken) + 1) // 2
            groups.extendleft([broken[half:], broken[:half]] if len(broken) > 1 else [broken])
    return [outcome for outcome in outcomes if outcome is not None]


def _crash(index: int, reason: str, start: float) -> TaskOutcome:
    return TaskOutcome(
        index, ok=False, reason=reason, failure_kind="crash", seconds=time.perf_counter() - start
    )


def _run_group(
    executor: Executor,
    fn: Callable[..., Any],
    arguments: list[tuple[Any, ...]],
    group: list[int],
    finish: Callable[[TaskOutcome], None],
) -> list[int]:
    """Run one group in parallel; return the tasks lost to a broken process pool, sorted."""
    start = time.perf_counter()
    futures: dict[Future, int] = {}
    broken: list[int] = []

    def collect(future: Future, index: int) -> None:
        try:
            ok, value, reason, seconds = future.result()
        except BrokenProcessPool:
            broken.append(index)
        except Exception as error:  # lost on the way: Dask KilledWorker, cancelled, unpicklable
            finish(_crash(index, f"task lost: {describe_exception(error)}", start))
        else:
            kind = None if ok else "error"
            finish(TaskOutcome(index, ok, value, reason, kind, seconds))

    for index in group:
        try:
            future = executor.submit(_call, fn, arguments[index])
        except BrokenProcessPool:
            broken.append(index)
            continue
        if future.done():  # in-process: report at once, not after the whole batch
            collect(future, index)
        else:
            futures[future] = index
    for future in as_completed(futures):
        collect(future, futures[future])
    return sorted(broken)
