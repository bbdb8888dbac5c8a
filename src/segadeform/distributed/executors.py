"""Executors: run independent tasks on this machine's processes or on a Ray cluster.

:func:`make_executor` takes what ``--executor`` says:

==================  =====================================================================
``local``           a process pool on this machine (the default; nothing extra to install)
``ray``             a Ray instance started on this machine for this run, ``workers`` CPUs
``ray://HOST:PORT`` a Ray cluster through Ray Client (the head's client port, 10001 by default)
``ray:ADDRESS``     a Ray cluster this machine belongs to: ``ray:auto`` or ``ray:HOST:6379``
==================  =====================================================================

``Executor.map_unordered(fn, tasks)`` yields ``fn(task)`` for every task, in the order they finish.
``fn`` is a picklable callable -- a module-level function is pickled by reference, so every worker
imports segadeform -- and each task a picklable value.  The tasks keep one contract, which is what makes
retries and resumed runs safe: a task is a function of its spec alone, commits its result atomically
(temporary name, then rename; see :mod:`segadeform.io.location`) and returns early when the result is already
committed.

On Ray a task whose worker process or node dies is run again (``max_retries`` times); an exception
the task raises is not retried (it would fail again) and ends the run, as on the local pool.  Ray is
imported only when a Ray executor is made (``pip install segadeform[ray]``).
"""

from __future__ import annotations

import abc
import concurrent.futures as cf
import logging
import os
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any

from ..errors import InputError, SegadeformError

__all__ = ["Executor", "LocalExecutor", "RayExecutor", "ExecutorError", "make_executor", "EXECUTOR_HELP"]

EXECUTOR_HELP = "local (process pool, default) | ray (a Ray instance here) | ray://HOST:PORT | ray:auto | ray:HOST:PORT"


class ExecutorError(SegadeformError):
    """A worker died (more often than the retries allow) or the cluster could not be reached."""


class Executor(abc.ABC):
    """Runs tasks; see the module docstring.  ``remote``: tasks may run on other machines than this one."""

    name = "executor"
    remote = False
    workers: int | None = None

    @abc.abstractmethod
    def map_unordered(self, fn: Callable[[Any], Any], tasks: Iterable) -> Iterator:
        raise NotImplementedError

    def describe(self) -> str:
        return f"{self.name} ({self.workers or 'all'} workers)"

    def close(self) -> None:  # noqa: B027 (a default, not abstract: an executor with nothing to release keeps it)
        pass

    def __enter__(self):
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class LocalExecutor(Executor):
    """``workers`` processes on this machine (one: the tasks run in this process, one after another)."""

    name = "local"

    def __init__(self, workers: int | None = None) -> None:
        if workers is not None and workers < 1:
            raise InputError("the number of workers must be at least 1", got=workers)
        self.workers = workers or 1

    def map_unordered(self, fn, tasks):
        tasks = list(tasks)
        if self.workers <= 1:
            for t in tasks:
                yield fn(t)
            return
        with cf.ProcessPoolExecutor(
            max_workers=min(self.workers, max(len(tasks), 1)), initializer=_stop_on_signal
        ) as ex:
            futs = [ex.submit(_unless_stopped, fn, t) for t in tasks]
            try:
                for f in cf.as_completed(futs):
                    try:
                        yield f.result()
                    except cf.process.BrokenProcessPool:
                        raise ExecutorError(
                            "a worker process died (killed?) while running a task (expected it "
                            "to finish; run again to resume: finished tasks are kept)"
                        ) from None
            except BaseException:
                # stopped (Ctrl-C, or SIGTERM, which reaches this process only): the workers stop their tasks
                # too, each unwinding as on Ctrl-C (a task's temporary files and subprocesses go), rather than
                # being waited out; a task they finished before is kept, as the contract says
                for f in futs:
                    f.cancel()
                for proc in list(getattr(ex, "_processes", {}).values()):
                    if proc.is_alive():
                        proc.terminate()
                raise
            finally:
                for f in futs:
                    f.cancel()


# A local worker process's own state: set once it was told to stop (the tasks the pool had already queued for it
# must not start: the pool cannot take them back).
_STOPPING = False


def _interrupted(signum, frame):
    import signal

    global _STOPPING
    _STOPPING = True
    for s in (signal.SIGINT, signal.SIGTERM):  # once: a second signal must not break the unwinding of the first
        signal.signal(s, _ignored)  # (not SIG_IGN: a signal already on its way then raised "Signal 15 ignored due to
    raise KeyboardInterrupt  # race condition" in the unwinding, a traceback per worker on Ctrl-C: a TD's trial)


def _ignored(signum, frame) -> None:
    """A local worker's handler after its first stop signal: nothing (the worker is unwinding already)."""


def _stop_on_signal() -> None:
    """A local worker's start: SIGTERM (sent by :meth:`LocalExecutor.map_unordered` when the run is stopped) and
    SIGINT (Ctrl-C in a terminal reaches every process of the group) raise KeyboardInterrupt once, so the task
    unwinds as on Ctrl-C, and no task starts in this worker after that (:func:`_unless_stopped`)."""
    import signal

    for s in (signal.SIGINT, signal.SIGTERM):
        signal.signal(s, _interrupted)


def _unless_stopped(fn, task):
    """``fn(task)`` in a local worker, unless the worker was told to stop."""
    if _STOPPING:
        raise KeyboardInterrupt
    return fn(task)


def _import_ray():
    try:
        import ray
    except ImportError as e:
        raise ExecutorError(
            f"the ray executor needs Ray (expected ray installed: pip install segadeform[ray], got {e})"
        ) from None
    return ray


class RayExecutor(Executor):
    """Tasks on a Ray cluster (see the module docstring).

    Args:
        address: None: start a Ray instance on this machine with ``workers`` CPUs; else what
            ``ray.init(address=...)`` takes (``ray://HOST:PORT``, ``auto``, ``HOST:PORT``).
        workers: at most this many tasks at a time (None: as many as the cluster runs; twice that
            many are kept submitted).
        max_retries: runs of a task after its worker or node died.
        cpus_per_task: the Ray CPUs each task holds.
        runtime_env: Ray's runtime environment for the workers (pip packages, environment variables).

    If this process is already connected to Ray (``ray.init`` was called), that connection is used
    and left open.
    """

    name = "ray"
    remote = True

    def __init__(
        self,
        address: str | None = None,
        workers: int | None = None,
        *,
        max_retries: int = 3,
        cpus_per_task: float = 1.0,
        runtime_env: dict | None = None,
    ) -> None:
        if workers is not None and workers < 1:
            raise InputError("the number of workers must be at least 1", got=workers)
        if max_retries < 0:
            raise InputError("max_retries must be at least 0", got=max_retries)
        self.address, self.workers, self.max_retries = address, workers, int(max_retries)
        self.cpus_per_task, self.runtime_env = float(cpus_per_task), runtime_env
        self._ray = None
        self._own = False

    def describe(self) -> str:
        where = self.address or "a local instance"
        return f"ray at {where} ({self.workers or 'all'} workers, {self.max_retries} retries)"

    def connect(self):
        """Connect (or start Ray); done by the first :meth:`map_unordered`."""
        if self._ray is not None:
            return self._ray
        ray = _import_ray()
        if not ray.is_initialized():
            kw = dict(include_dashboard=False, log_to_driver=False, logging_level=logging.WARNING)
            if self.runtime_env:
                kw["runtime_env"] = self.runtime_env
            try:
                if self.address is None:
                    ray.init(address="local", num_cpus=self.workers or os.cpu_count(), **kw)
                else:
                    ray.init(address=self.address, **kw)
            except (ConnectionError, RuntimeError, ValueError) as e:
                raise ExecutorError(
                    f"cannot reach the Ray cluster (expected one at "
                    f"{self.address or 'a new local instance'}, got {type(e).__name__}: "
                    f"{str(e).splitlines()[0] if str(e) else ''})"
                ) from None
            self._own = True
        self._ray = ray
        return ray

    def map_unordered(self, fn, tasks):
        todo = list(tasks)
        if not todo:  # nothing to do (a finished run resumed): no cluster needed
            return
        ray = self.connect()
        from ray import exceptions as rex

        remote = ray.remote(_apply).options(
            num_cpus=self.cpus_per_task,
            max_retries=self.max_retries,
            retry_exceptions=False,
            name=getattr(fn, "__name__", "task"),
        )
        window = _Window(ray, self.workers, self.cpus_per_task)
        pending: dict = {}
        nxt = 0
        try:
            while nxt < len(todo) or pending:
                limit = window.size()
                while nxt < len(todo) and len(pending) < limit:
                    pending[remote.remote(fn, todo[nxt])] = nxt
                    nxt += 1
                ready, _ = ray.wait(list(pending), num_returns=1)
                ref = ready[0]
                i = pending.pop(ref)
                try:
                    result = ray.get(ref)
                except rex.RayTaskError as e:  # the task raised: its own exception, as the local pool gives it
                    cause = getattr(e, "cause", None)
                    if isinstance(cause, BaseException):
                        raise cause from None
                    raise ExecutorError(f"task {i} failed on a Ray worker: {str(e).splitlines()[0]}") from None
                except rex.RayError as e:  # the worker or its node died more often than the retries allow
                    raise ExecutorError(
                        f"task {i} did not finish on Ray (expected it to within "
                        f"{self.max_retries} retries of a dead worker, got "
                        f"{type(e).__name__}: {str(e).splitlines()[0] if str(e) else ''}); run "
                        f"again to resume: finished tasks are kept"
                    ) from None
                yield result
        finally:
            for ref in pending:
                try:
                    ray.cancel(ref)
                except Exception:  # already finished or gone: nothing to stop
                    pass

    def close(self) -> None:
        if self._ray is not None and self._own:
            self._ray.shutdown()
        self._ray, self._own = None, False


class _Window:
    """How many tasks to keep submitted: ``workers``, or without a limit twice the tasks the cluster
    runs at once -- enough to keep every slot busy, few enough that waiting on them stays cheap
    (looked up again every 30 s: an autoscaling cluster grows)."""

    def __init__(self, ray, workers: int | None, cpus_per_task: float) -> None:
        self.ray, self.workers, self.cpus = ray, workers, cpus_per_task
        self.at, self.n = -1e9, 1

    def size(self) -> int:
        if self.workers:
            return self.workers
        now = time.monotonic()
        if now - self.at > 30.0:
            cpus = float(self.ray.cluster_resources().get("CPU", 1.0))
            self.n, self.at = max(int(2 * cpus / max(self.cpus, 1e-3)), 1), now
        return self.n


def _apply(fn, task):
    """What a Ray worker runs: ``fn(task)`` (any picklable callable, not only a Python function)."""
    return fn(task)


def make_executor(spec: str = "local", workers: int | None = None, **ray_options) -> Executor:
    """The executor ``spec`` names (see the module docstring); ``workers``: how many tasks at a time."""
    if not isinstance(spec, str):
        raise InputError("unknown executor", expected=EXECUTOR_HELP, got=repr(spec))
    s = spec.strip()
    if s == "local":
        if ray_options:
            raise InputError("Ray options given to the local executor", expected="none", got=sorted(ray_options))
        return LocalExecutor(workers)
    if s == "ray":
        return RayExecutor(None, workers, **ray_options)
    if s.startswith("ray://") and len(s) > len("ray://"):
        return RayExecutor(s, workers, **ray_options)
    if s.startswith("ray:") and len(s) > len("ray:") and not s.startswith("ray:/"):
        return RayExecutor(s[len("ray:") :], workers, **ray_options)
    raise InputError("unknown executor", expected=EXECUTOR_HELP, got=spec)
