"""Where a sweep's runs execute: local worker processes, or Ray.

Both hand rows back one at a time as they finish (``on_row(index, row)``, on the calling
thread) and both turn a run that never returned a row (its process crashed) into a row with
the reason. A Ctrl-C raises :class:`SweepInterrupted` holding the rows done.
"""

from __future__ import annotations

import logging
import multiprocessing
import multiprocessing.connection
import signal
from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

from dua_mujoco.sweep.runner import Task, failed_row

__all__ = ["Runner", "SweepInterrupted", "run_local", "run_ray"]

Runner = Callable[[Task], dict[str, Any]]
"""What runs a task: a module-level function (workers import it by name)."""
OnRow = Callable[[int, dict[str, Any]], None]


class SweepInterrupted(KeyboardInterrupt):
    """Ctrl-C during a sweep: ``rows`` holds those finished (by task index)."""

    def __init__(self, rows: dict[int, dict[str, Any]]) -> None:
        super().__init__("sweep interrupted")
        self.rows = rows


def died(exitcode: int | None) -> str:
    """The error of a run whose process ended without a row: ``worker died (exit code -11,
    SIGSEGV)``."""
    if exitcode is not None and exitcode < 0:
        try:
            return f"worker died (exit code {exitcode}, {signal.Signals(-exitcode).name})"
        except ValueError:
            pass
    return f"worker died (exit code {exitcode})"


def _serve(conn: multiprocessing.connection.Connection, runner: Runner) -> None:
    """A worker: run the tasks sent until None (or the parent is gone)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the parent's to handle
    while True:
        try:
            task = conn.recv()
        except EOFError:
            return
        if task is None:
            return
        try:
            row = runner(task)
        except Exception as exc:  # a runner that raises: still one row
            row = failed_row(task, f"{type(exc).__name__}: {exc}")
        conn.send(row)


class _Worker:
    def __init__(self, context: Any, runner: Runner) -> None:
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_serve, args=(child, runner), daemon=True)
        self.process.start()
        child.close()
        self.task: int | None = None

    def stop(self) -> None:
        if self.process.is_alive():
            self.process.kill()
        self.process.join()
        self.conn.close()


def run_local(
    tasks: Sequence[Task], runner: Runner, *, workers: int, on_row: OnRow
) -> dict[int, dict[str, Any]]:
    """Run ``tasks`` on ``workers`` processes (spawned, each running one task at a time; a
    process that dies is replaced and its task is a row with the reason).

    Returns:
        Rows by task index.
    """
    context = multiprocessing.get_context("spawn")  # no forked copies of a GL state
    queue = deque(range(len(tasks)))
    rows: dict[int, dict[str, Any]] = {}
    pool: list[_Worker] = []
    try:
        while queue or any(w.task is not None for w in pool):
            while queue and len(pool) < workers:
                pool.append(_Worker(context, runner))
            for worker in pool:
                if worker.task is None and queue:
                    worker.task = queue.popleft()
                    worker.conn.send(tasks[worker.task])
            busy = [w for w in pool if w.task is not None]
            ready = multiprocessing.connection.wait(
                [w.conn for w in busy] + [w.process.sentinel for w in busy]
            )
            for worker in busy:
                index = worker.task
                assert index is not None
                row = None
                if worker.conn in ready or worker.process.sentinel in ready:
                    try:
                        if worker.conn.poll():
                            row = worker.conn.recv()
                    except (EOFError, OSError):
                        row = None
                    if row is None and worker.process.sentinel not in ready:
                        continue
                    if row is None:  # the process ended without a row
                        worker.process.join()
                        row = failed_row(tasks[index], died(worker.process.exitcode))
                        worker.stop()
                        pool.remove(worker)
                    worker.task = None
                    rows[index] = row
                    on_row(index, row)
        for worker in pool:
            worker.conn.send(None)
    except KeyboardInterrupt:
        raise SweepInterrupted(rows) from None
    finally:
        for worker in pool:
            worker.stop()
    return rows


def run_ray(
    tasks: Sequence[Task], runner: Runner, *, address: str | None, num_cpus: int, on_row: OnRow
) -> dict[int, dict[str, Any]]:
    """Run ``tasks`` as Ray tasks of one CPU each, on a local Ray instance of ``num_cpus`` CPUs
    (``address`` None) or on the cluster at ``address`` (``dua_mujoco`` installed on its nodes).

    A task whose worker crashed (``WorkerCrashedError``) or that raised is a row with the reason;
    tasks are not retried (a crash would repeat).
    """
    try:
        import ray
    except ImportError:
        from dua_mujoco.exceptions import InvalidInputError

        raise InvalidInputError(
            "--ray needs Ray: pip install 'dua_mujoco[ray]' (or pip install ray)."
        ) from None
    started = not ray.is_initialized()
    if started:
        kwargs: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False}
        kwargs["logging_level"] = logging.WARNING  # no banner in the table's output
        if address is None:
            kwargs["num_cpus"] = num_cpus
        ray.init(address=address, **kwargs)
    remote = ray.remote(num_cpus=1, max_retries=0)(_call)
    pending = {remote.remote(runner, task): index for index, task in enumerate(tasks)}
    rows: dict[int, dict[str, Any]] = {}
    try:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            for ref in done:
                index = pending.pop(ref)
                try:
                    row = ray.get(ref)
                except ray.exceptions.RayError as exc:
                    row = failed_row(tasks[index], _ray_error(exc))
                rows[index] = row
                on_row(index, row)
    except KeyboardInterrupt:
        for ref in pending:
            ray.cancel(ref, force=True)
        raise SweepInterrupted(rows) from None
    finally:
        if started:
            ray.shutdown()
    return rows


def _call(runner: Runner, task: Task) -> dict[str, Any]:
    return runner(task)


def _ray_error(exc: BaseException) -> str:
    """The first line of a Ray error, prefixed by its class (``WorkerCrashedError: ...``)."""
    first = next((line for line in str(exc).splitlines() if line.strip()), "")
    return f"{type(exc).__name__}: {first}"
