"""Where a study's independent tasks run: this machine's processes (the default) or Ray.

A study (benchmark episodes, calibration cases, candidate fits, training runs) is a list of
independent, deterministic tasks, so where each one runs must not change its result.
``make_executor("local", workers)`` runs them in ``workers`` processes of this machine
(``workers <= 1``: in this process, in order); ``make_executor("ray", address=...)`` on a
Ray cluster (no address and no ``RAY_ADDRESS``: a local Ray instance with ``workers`` CPUs).
Ray is imported here only, inside :class:`RayExecutor`, so the default install needs none.

Both survive a worker dying (killed, out of memory, a lost node): Ray resubmits the task
(``max_retries``); the local executor sees its pool break, starts a new one and resubmits
what had not finished, counting an attempt against each task that was running then.
:func:`run_study` adds what a long study needs on top: each result appended to a JSON-lines
file as it finishes, ``resume`` that runs only what the file lacks, and one progress bar.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Future, ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from contextlib import nullcontext
from pathlib import Path
from types import TracebackType
from typing import IO, Any

__all__ = [
    "EXECUTORS",
    "Executor",
    "LocalExecutor",
    "RayExecutor",
    "TaskFailed",
    "add_executor_args",
    "die_with_parent",
    "make_executor",
    "read_results",
    "run_study",
]

EXECUTORS = ("local", "ray")
MAX_RETRIES = 3
"""Resubmissions of a task whose worker died, before the study gives up on it."""


class TaskFailed(RuntimeError):
    """A task's worker died more often than ``max_retries`` allows."""


class Executor:
    """Runs ``fn(item)`` (or ``fn(shared, item)``) for every item; see the module docstring."""

    kind = "?"
    workers = 1
    """Tasks that run side by side."""

    def imap(
        self, fn: Callable[..., Any], items: Sequence[Any], shared: Any = None
    ) -> Iterator[tuple[int, Any]]:
        """``(index, result)`` as each task finishes (any order).

        ``shared`` (not None) is sent to each worker once, not once per task, and passed as
        ``fn``'s first argument: the large common input of many small tasks.
        """
        raise NotImplementedError

    def map(
        self,
        fn: Callable[..., Any],
        items: Sequence[Any],
        shared: Any = None,
        on_result: Callable[[int, Any], None] | None = None,
    ) -> list[Any]:
        """Every result, in item order; ``on_result(index, result)`` as each one finishes."""
        out: dict[int, Any] = {}
        for i, res in self.imap(fn, items, shared):
            out[i] = res
            if on_result is not None:
                on_result(i, res)
        return [out[i] for i in range(len(items))]

    def describe(self) -> str:
        return f"{self.kind} executor, {self.workers} worker(s)"

    def close(self) -> None:
        """Release the workers (a Ray instance this executor started is shut down)."""

    def __enter__(self) -> Executor:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()


# --------------------------------------------------------------------------- local processes

_WORKER: dict[str, Any] = {}
"""A local worker's state: the queue it reports started tasks on, and the shared input."""


def die_with_parent(parent: int | None = None) -> None:
    """Ask the kernel to end this process when its parent dies (Linux; elsewhere nothing).

    A pool initializer. Why: a study killed by ``kill`` or the out-of-memory killer runs no
    ``finally``, and its spawned workers went on computing for half an hour (issue 16, stop
    27: two orphaned ``bench_diagnose`` cases). ``parent``: the pid the worker was started
    from; if it is already gone (a race with the call), the worker exits at once.
    """
    import ctypes
    import signal
    import sys

    if not sys.platform.startswith("linux"):
        return
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        libc.prctl(1, signal.SIGTERM, 0, 0, 0)  # PR_SET_PDEATHSIG
    except (OSError, AttributeError):
        return
    if parent is not None and os.getppid() != parent:
        os._exit(1)


def _init_worker(started: Any, shared: Any, parent: int | None = None) -> None:
    die_with_parent(parent)
    _WORKER["started"] = started
    _WORKER["shared"] = shared


def _call_local(fn: Callable[..., Any], i: int, item: Any, with_shared: bool) -> Any:
    # Written synchronously (SimpleQueue) before the task runs, so a worker that dies in the
    # task has always said which one it was running.
    _WORKER["started"].put(i)
    return fn(_WORKER["shared"], item) if with_shared else fn(item)


class LocalExecutor(Executor):
    """``workers`` processes of this machine (``spawn`` by default: nothing shared by fork).

    ``start_method="fork"`` lets ``fn``/``shared`` be closures that do not pickle (they are
    inherited); the pool is created after ``imap`` is called, so it inherits the caller's state.
    """

    kind = "local"

    def __init__(
        self, workers: int = 1, start_method: str = "spawn", max_retries: int = MAX_RETRIES
    ) -> None:
        if start_method not in mp.get_all_start_methods():
            raise ValueError(f"start method {start_method!r} is not available on this platform")
        self.workers = max(1, int(workers))
        self.start_method = start_method
        self.max_retries = max_retries
        self.restarts = 0
        """Pools started again after a worker died (for reports and tests)."""

    def imap(
        self, fn: Callable[..., Any], items: Sequence[Any], shared: Any = None
    ) -> Iterator[tuple[int, Any]]:
        items = list(items)
        if self.workers <= 1:
            for i, item in enumerate(items):
                yield i, (fn(shared, item) if shared is not None else fn(item))
            return
        todo = set(range(len(items)))
        attempts = [0] * len(items)
        ctx = mp.get_context(self.start_method)
        while todo:
            started = ctx.SimpleQueue()
            running: set[int] = set()
            pool = ProcessPoolExecutor(
                min(self.workers, len(todo)),
                mp_context=ctx,
                initializer=_init_worker,
                initargs=(started, shared, os.getpid()),
            )
            broken = False
            try:
                futures: dict[Future[Any], int] = {
                    pool.submit(_call_local, fn, i, items[i], shared is not None): i
                    for i in sorted(todo)
                }
                for fut in as_completed(futures):
                    i = futures[fut]
                    try:
                        res = fut.result()
                    except BrokenProcessPool:
                        broken = True  # every unfinished future fails now; keep the finished
                        continue
                    _drain(started, running)
                    running.discard(i)
                    todo.discard(i)
                    yield i, res
            finally:
                pool.shutdown(wait=True, cancel_futures=True)
            if broken:
                _drain(started, running)
                self.restarts += 1
                lost = sorted(running & todo) or sorted(todo)
                for i in lost:
                    attempts[i] += 1
                    if attempts[i] > self.max_retries:
                        raise TaskFailed(
                            f"task {i} ({items[i]!r}) was running each time a worker died, "
                            f"{attempts[i]} times; giving up after {self.max_retries} retries"
                        )
            started.close()

    def describe(self) -> str:
        return f"local executor, {self.workers} process(es)"


def _drain(started: Any, running: set[int]) -> None:
    while not started.empty():
        running.add(started.get())


# --------------------------------------------------------------------------- Ray


def _call_ray(fn: Callable[..., Any], shared: Any, item: Any, with_shared: bool) -> Any:
    return fn(shared, item) if with_shared else fn(item)


class RayExecutor(Executor):
    """Tasks on a Ray cluster, one CPU each; a task whose worker dies is retried.

    ``address`` (or ``RAY_ADDRESS``) names a running cluster (``ray start --head`` prints it;
    ``auto`` finds one on this machine); without either a local instance with ``workers``
    CPUs is started and shut down again by :meth:`close`. When Ray is already initialised in
    this process (a test fixture, a notebook) that instance is used and left running.
    Every node needs this package installed at the same version as the driver.
    """

    kind = "ray"

    def __init__(
        self, address: str | None = None, workers: int = 1, max_retries: int = MAX_RETRIES
    ) -> None:
        try:
            import ray
        except ImportError as exc:
            raise RuntimeError(
                '--executor ray needs Ray: pip install -e ".[cluster]" (or: pip install ray)'
            ) from exc
        self._ray = ray
        self.max_retries = max_retries
        self._owned = False
        address = address or os.environ.get("RAY_ADDRESS") or None
        if not ray.is_initialized():
            if address:
                ray.init(address=address, log_to_driver=False)
            else:
                ray.init(
                    num_cpus=max(1, int(workers)), include_dashboard=False, log_to_driver=False
                )
            self._owned = True
        self.address = address or "local instance"
        self.workers = max(1, int(ray.cluster_resources().get("CPU", 1)))

    def imap(
        self, fn: Callable[..., Any], items: Sequence[Any], shared: Any = None
    ) -> Iterator[tuple[int, Any]]:
        ray = self._ray
        remote = ray.remote(num_cpus=1, max_retries=self.max_retries)(_call_ray)
        fn_ref = ray.put(fn)
        shared_ref = ray.put(shared) if shared is not None else None
        pending = {
            remote.remote(fn_ref, shared_ref, item, shared is not None): i
            for i, item in enumerate(items)
        }
        try:
            while pending:
                done, _ = ray.wait(list(pending), num_returns=1)
                for ref in done:
                    i = pending.pop(ref)
                    try:
                        res = ray.get(ref)
                    except ray.exceptions.WorkerCrashedError as exc:
                        raise TaskFailed(
                            f"task {i} ({items[i]!r}): its worker died {self.max_retries + 1} "
                            f"times; giving up ({exc})"
                        ) from exc
                    yield i, res
        finally:
            for ref in pending:
                ray.cancel(ref, force=True)

    def describe(self) -> str:
        return f"ray executor ({self.address}), {self.workers} CPU(s)"

    def close(self) -> None:
        if self._owned and self._ray.is_initialized():
            self._ray.shutdown()
        self._owned = False


# --------------------------------------------------------------------------- choosing one


def make_executor(
    kind: str = "local",
    workers: int = 1,
    address: str | None = None,
    start_method: str = "spawn",
    max_retries: int = MAX_RETRIES,
) -> Executor:
    """The executor named by ``--executor`` (``address``: ``--ray-address``, Ray only)."""
    if kind == "local":
        return LocalExecutor(workers, start_method=start_method, max_retries=max_retries)
    if kind == "ray":
        return RayExecutor(address, workers, max_retries=max_retries)
    raise ValueError(f"--executor {kind!r}: expected one of {', '.join(EXECUTORS)}")


def _executor_kind(text: str) -> str:
    """``--executor`` value; ``ray`` without Ray installed is an error at parse time."""
    import importlib.util

    if text == "ray" and importlib.util.find_spec("ray") is None:
        raise argparse.ArgumentTypeError(
            'ray is not installed: pip install -e ".[cluster]" (or: pip install ray)'
        )
    return text


def add_executor_args(parser: argparse.ArgumentParser) -> None:
    """``--executor`` and ``--ray-address`` (the command keeps its own ``--workers``)."""
    parser.add_argument(
        "--executor",
        type=_executor_kind,
        choices=EXECUTORS,
        default="local",
        help="where tasks run: local processes (default) or a Ray cluster",
    )
    parser.add_argument(
        "--ray-address",
        default=None,
        help="Ray cluster to use (default $RAY_ADDRESS; neither: start a local Ray instance "
        "with --workers CPUs)",
    )


# --------------------------------------------------------------------------- studies


def read_results(path: str | Path) -> dict[str, Any]:
    """Key -> result of a :func:`run_study` results file.

    A last line cut short (the study was killed while writing it) is dropped; any other
    line that is not a ``{"key": ..., "result": ...}`` object is an error naming the line.
    """
    p = Path(path)
    lines = p.read_text().splitlines()
    out: dict[str, Any] = {}
    for n, line in enumerate(lines, 1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
            key, result = rec["key"], rec["result"]
        except (json.JSONDecodeError, KeyError, TypeError) as exc:
            if n == len(lines):
                break  # cut short by a kill: that task simply runs again
            raise ValueError(f"{p}, line {n}: not a study result record ({exc})") from exc
        out[str(key)] = result
    return out


def run_study(
    executor: Executor,
    fn: Callable[..., Any],
    tasks: Sequence[Any],
    keys: Sequence[str],
    results: str | Path | None = None,
    resume: bool = False,
    shared: Any = None,
    desc: str = "study",
    unit: str = "task",
    progress: bool = True,
    postfix: Callable[[Any], str] | None = None,
    done_before: int = 0,
    on_result: Callable[[str, Any], None] | None = None,
) -> list[Any]:
    """Every task's result, in task order, through ``executor``; nothing lost on a stop.

    Each result is appended to ``results`` (one JSON line ``{"key", "result"}``, flushed) as
    it finishes, so results must be JSON-serialisable; ``keys`` name the tasks uniquely.
    ``resume=True`` takes the results already in the file and runs only the other tasks;
    without it an existing file is started afresh. One progress bar covers the whole study
    (``done_before``: tasks the caller already skipped, counted as done).
    """
    from tqdm import tqdm

    keys = [str(k) for k in keys]
    if len(set(keys)) != len(keys):
        raise ValueError("run_study: task keys must be unique")
    if len(keys) != len(tasks):
        raise ValueError(f"run_study: {len(tasks)} tasks but {len(keys)} keys")
    out: dict[str, Any] = {}
    path = Path(results) if results is not None else None
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        if resume and path.is_file():
            old = read_results(path)
            out = {k: old[k] for k in keys if k in old}
            # Rewrite without a cut-short last line, so appending keeps the file well formed.
            path.write_text("".join(_record(k, v) for k, v in old.items()))
        else:
            path.write_text("")
    todo = [i for i, k in enumerate(keys) if k not in out]
    total = len(keys) + done_before
    bar_ctx = tqdm(
        total=total, initial=total - len(todo), desc=desc, unit=unit, disable=not progress
    )
    fh_ctx: Any = path.open("a") if path is not None else nullcontext()
    with bar_ctx as bar, fh_ctx as fh:
        for j, res in executor.imap(fn, [tasks[i] for i in todo], shared):
            key = keys[todo[j]]
            out[key] = res
            if fh is not None:
                _write(fh, key, res)
            if on_result is not None:
                on_result(key, res)
            if postfix is not None:
                bar.set_postfix_str(postfix(res), refresh=False)
            bar.update(1)
    return [out[k] for k in keys]


def _record(key: str, result: Any) -> str:
    return json.dumps({"key": key, "result": result}) + "\n"


def _write(fh: IO[str], key: str, result: Any) -> None:
    fh.write(_record(key, result))
    fh.flush()
