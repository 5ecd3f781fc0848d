"""Where a study's runs execute: on Dask distributed (a ``LocalCluster`` of single-
threaded worker processes, or an existing cluster by its scheduler's address), or one
after the other in this process (``--serial``); and the study's progress bar.

Each executor's ``results(tasks, progress)`` yields ``(task, row)`` as runs finish. A
worker that dies (killed, out of memory) is replaced by its nanny and Dask runs its task
again elsewhere; the run then resumes from its checkpoint. A task that killed workers
too often comes back as a failed row (``KilledWorker``); re-running the study resumes it.
"""

from __future__ import annotations

import logging
import math
import os
import signal
import sys
import threading
import time
from contextlib import contextmanager

from ..errors import IpcsimError, excerpt, one_line
from .runs import WORKER_ENV, RunTask, describe, execute

__all__ = ["SerialExecutor", "DaskExecutor", "StudyProgress", "INSTALL_HINT", "default_workers",
           "interrupted_by_signals"]

INSTALL_HINT = ('ipcsim sweep runs on Dask, which is not installed: pip install '
                '"ipcsim[cluster]" (or run the study in this process with --serial)')
POLL_S = 0.25
_TRIM = "distributed.nanny.pre-spawn-environ.MALLOC_TRIM_THRESHOLD_"


def default_workers() -> int:
    """One worker per core this process may use."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return max(1, os.cpu_count() or 1)


@contextmanager
def interrupted_by_signals():
    """While the study runs, Ctrl-C (SIGINT) and SIGTERM (a batch scheduler's,
    ``timeout``'s) stop it alike: a KeyboardInterrupt in this thread, so that the executor
    shuts its cluster down (no worker or semaphore is left behind) and the study ends with
    status 130, resumable; also where the process was started with SIGINT ignored (in
    the background of a script), as ``ipcsim run`` stops there. A run in this process
    (``--serial``) turns them into "stop after this step" itself, as ``ipcsim run``
    does."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = {s: signal.signal(s, interrupt) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)


def _failed(task: RunTask, error: str) -> dict:
    return {"run": task.name, **task.parameters, "status": "failed",
            "error": one_line(error, 300), "folder": task.folder}


class SerialExecutor:
    """The runs one after the other in this process (each on one numba thread)."""

    name = "this process"

    def __enter__(self):
        self._before = os.environ.get("IPCSIM_THREADS")
        os.environ.setdefault("IPCSIM_THREADS", WORKER_ENV["IPCSIM_THREADS"])
        return self

    def __exit__(self, *exc):
        if self._before is None:  # as it was: later simulations choose their threads
            os.environ.pop("IPCSIM_THREADS", None)
        return False

    def results(self, tasks, progress):
        for task in tasks:
            progress.update(running=1)
            yield task, execute(task)


def check_scheduler_address(address: str) -> str:
    """``--scheduler``'s address, checked without connecting: a scheme Dask knows, a host
    and a port (1 to 65535). A malformed one is an IpcsimError (exit status 2)."""
    from distributed.comm import registry
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        scheme, location = parse_address(address)
        if scheme == "inproc":
            raise ValueError("an in-process address, which no other process can reach")
        registry.get_backend(scheme)
        _, port = parse_host_port(location)
        if not 0 < port < 65536:
            raise ValueError(f"port {port} is not from 1 to 65535")
    except (ValueError, TypeError, ImportError) as exc:
        raise IpcsimError(f"--scheduler {excerpt(address, 80)}: not a Dask scheduler "
                          f"address ({excerpt(one_line(str(exc)), 160)}); give "
                          "tcp://host:port") from None
    return address


def _connect_timeout() -> float:
    """Seconds to reach a scheduler: Dask's distributed.comm.timeouts.connect."""
    import dask
    from dask.utils import parse_timedelta

    return float(parse_timedelta(dask.config.get("distributed.comm.timeouts.connect"),
                                 default="seconds"))


def _probe(address: str, timeout: float) -> None:
    """Connect to ``address`` and exchange Dask's handshake, all within ``timeout``
    seconds: a listener that is no Dask scheduler (an HTTP server) never answers the
    handshake, which Dask's own connect would wait for without end. Raises
    TimeoutError or OSError."""
    import asyncio

    from distributed.comm import connect

    async def handshake():
        comm = await asyncio.wait_for(connect(address, timeout=timeout), timeout)
        await comm.close()

    asyncio.run(handshake())


class DaskExecutor:
    """The runs as Dask tasks: ``workers`` single-threaded processes of a new
    ``LocalCluster`` (default one per core), or the cluster at ``scheduler``. Dask is
    imported, and the address checked, when the executor is made."""

    def __init__(self, workers: int | None = None, scheduler: str | None = None):
        try:
            import dask.distributed  # noqa: F401
        except ImportError:
            raise IpcsimError(INSTALL_HINT) from None
        if scheduler is not None:
            check_scheduler_address(scheduler)
        self.workers, self.scheduler = workers, scheduler
        self.client = self.cluster = None

    @property
    def name(self) -> str:
        if self.scheduler:
            return f"the Dask cluster at {self.scheduler}"
        return f"a local Dask cluster of {self.workers or default_workers()} worker processes"

    def __enter__(self):
        import dask
        from dask.distributed import Client, LocalCluster

        try:
            if self.scheduler:
                timeout = _connect_timeout()
                _probe(self.scheduler, timeout)
                self.client = Client(self.scheduler, timeout=timeout)
            else:
                # Two of Dask's defaults slow a simulation down (docs/benchmarks.md): the
                # workers' statistical profiler, which samples the running task's stack
                # every 10 ms on the worker's event loop, taking the GIL from it, and
                # MALLOC_TRIM_THRESHOLD_, which turns off glibc's dynamic mmap threshold,
                # so that every array over 128 KiB is mmap'ed and faulted in afresh (0.3 s
                # of system time per 300 steps of a 384-tet cube, none without it). A
                # worker takes its config from here. Logs below CRITICAL stay quiet: a
                # worker's heartbeat that races the scheduler's shutdown logs a traceback
                # at ERROR, and a run's own failure is its study.csv row.
                with dask.config.set({_TRIM: None, "distributed.worker.profile.enabled":
                                      False}):
                    self.cluster = LocalCluster(
                        n_workers=self.workers or default_workers(), threads_per_worker=1,
                        processes=True, env=dict(WORKER_ENV), dashboard_address=None,
                        silence_logs=logging.CRITICAL)
                self.client = Client(self.cluster)
        except Exception as exc:  # noqa: BLE001  (OSError, a timeout, TLS without a context...)
            self.__exit__()
            where = self.scheduler or "a local cluster"
            why = one_line(str(exc)) or type(exc).__name__
            if isinstance(exc, TimeoutError) and self.scheduler:
                why = (f"no Dask scheduler answered within {_connect_timeout():g} s (Dask's "
                       "distributed.comm.timeouts.connect); is it one?")
            raise IpcsimError(f"cannot start or reach {where}: {excerpt(why, 200)}") from None
        except BaseException:  # Ctrl-C or SIGTERM while the cluster starts: shut it down
            self.__exit__()
            raise
        return self

    def __exit__(self, *exc):
        for thing in (self.client, self.cluster):
            if thing is not None:
                try:
                    thing.close()
                except Exception:  # noqa: BLE001  (a cluster going down is no news)
                    pass
        self.client = self.cluster = None
        return False

    def _running(self, pending) -> int:
        try:
            keys = {k for ks in self.client.processing().values() for k in ks}
            slots = sum(self.client.nthreads().values())
        except Exception:  # noqa: BLE001  (the scheduler busy or restarting a worker)
            return 0
        return min(slots, sum(1 for f in pending if f.key in keys))

    def results(self, tasks, progress):
        from dask.distributed import wait

        futures = {self.client.submit(execute, t, key=f"ipcsim-run-{t.name}-{t.digest[:16]}",
                                      pure=False): t for t in tasks}
        pending = dict(futures)
        try:
            while pending:
                try:
                    done, _ = wait(list(pending), timeout=POLL_S, return_when="FIRST_COMPLETED")
                except TimeoutError:
                    done = ()
                for f in done:
                    task = pending.pop(f)
                    try:
                        row = f.result()
                    except Exception as exc:  # noqa: BLE001  (KilledWorker, a lost worker)
                        row = _failed(task, f"{type(exc).__name__}: {exc}")
                    yield task, row
                progress.update(running=self._running(pending))
        finally:
            if pending:
                self.client.cancel(list(pending))


class StudyProgress:
    """One bar for the study: runs done of all, running, failed and the time left (on a
    terminal); otherwise a line per finished run; nothing with ``mode="off"``."""

    def __init__(self, total: int, done: int, mode: str, stream=None):
        self.total, self.done, self.failed, self.running = total, done, 0, 0
        self.skipped = done
        self.mode, self.stream = mode, stream or sys.stdout
        self.started = time.perf_counter()
        self._bar = None
        if mode == "bar":
            from rich.console import Console
            from rich.progress import BarColumn, Progress, TextColumn

            self._bar = Progress(
                TextColumn("runs {task.completed}/{task.total}"), BarColumn(),
                TextColumn("running {task.fields[running]}  failed {task.fields[failed]}  "
                           "ETA {task.fields[eta]}"),
                console=Console(file=self.stream), transient=False)
            self._task = self._bar.add_task("study", total=total, completed=done, running=0,
                                            failed=0, eta="-")
            self._bar.start()

    def eta(self) -> str:
        ran = self.done - self.skipped
        if ran <= 0:
            return "-"
        left = (time.perf_counter() - self.started) / ran * (self.total - self.done)
        m, s = divmod(int(math.ceil(left)), 60)
        return f"{m // 60}:{m % 60:02d}:{s:02d}" if m >= 60 else f"{m}:{s:02d}"

    def update(self, running: int | None = None) -> None:
        if running is not None:
            self.running = running
        if self._bar is not None:
            self._bar.update(self._task, completed=self.done, running=self.running,
                             failed=self.failed, eta=self.eta())

    def finished(self, task: RunTask, row: dict) -> None:
        self.done += 1
        self.failed += row.get("status") != "ok"
        self.update()
        if self.mode == "lines":
            what = row.get("status") if row.get("status") == "ok" else \
                f"failed: {row.get('error', '')}"
            print(f"{describe(task)}: {what} — {self.done}/{self.total} done, "
                  f"{self.failed} failed, ETA {self.eta()}", file=self.stream, flush=True)

    def close(self) -> None:
        if self._bar is not None:
            self._bar.stop()
            self._bar = None
