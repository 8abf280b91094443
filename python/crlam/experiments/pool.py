"""Resumable jobs: the sweep loop (:func:`run_jobs`) and the local executor (``spawn`` worker processes).

A job is finished when its folder holds the marker file written last (atomically), so a killed
run loses at most the jobs in flight and rerunning skips the finished ones. Workers use the
``spawn`` context: a forked child of a process whose rayon pool has started hangs. Other
executors (:mod:`crlam.experiments.dask_executor`) plug into the same loop through
:class:`crlam.experiments.executor.Executor`.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import sys
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from tqdm import tqdm

from crlam.experiments.executor import Collect, Executor, Job, RunLayout

__all__ = ["DEFAULT_RETRIES", "Job", "LocalExecutor", "run_jobs", "write_atomic"]

#: How often a run whose process died is started again before it is recorded as failed.
DEFAULT_RETRIES = 2


def write_atomic(path: Path, text: str) -> None:
    """Writes ``text`` to ``path`` through a temporary file and a rename."""
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def _call(fn: Callable[..., dict[str, Any]], name: str, kwargs: dict[str, Any], threads: int) -> tuple[str, Any, str | None]:
    os.environ["RAYON_NUM_THREADS"] = str(threads)
    try:
        return name, fn(**kwargs), None
    except Exception as e:  # noqa: BLE001 - reported per job, the others go on
        return name, None, f"{type(e).__name__}: {e}\n{traceback.format_exc(limit=3)}"


def _exit_with_parent(parent: int, period: float) -> None:
    """Ends this worker once its parent is gone (the parent was killed: nobody would collect the
    run, and a resumed sweep would start the same run a second time next to it)."""
    while os.getppid() == parent:
        time.sleep(period)
    os._exit(3)


def _call_and_send(
    conn: Connection,
    fn: Callable[..., dict[str, Any]],
    name: str,
    kwargs: dict[str, Any],
    threads: int,
    parent: int,
    watch_period: float = 1.0,
) -> None:
    threading.Thread(target=_exit_with_parent, args=(parent, watch_period), daemon=True).start()
    conn.send(_call(fn, name, kwargs, threads))
    conn.close()


def _death_reason(exitcode: int | None) -> str:
    if exitcode is not None and exitcode < 0:
        try:
            sig = signal.Signals(-exitcode).name
        except ValueError:
            sig = f"signal {-exitcode}"
        hint = " (killed: out of memory?)" if -exitcode == signal.SIGKILL else ""
        return f"WorkerDied: the worker process was ended by {sig}{hint} before returning a result"
    return f"WorkerDied: the worker process exited with code {exitcode} before returning a result"


def _run_fresh_processes(
    todo: Sequence[Job],
    fn: Callable[..., dict[str, Any]],
    workers: int,
    threads: int,
    collect: Collect,
    retries: int = 0,
) -> None:
    """Every job in its own spawned process, at most ``workers`` at a time. A process that dies
    without a result (killed by the OOM killer, a crash in native code) costs its job only: the
    job is started again, up to ``retries`` more times, and then reported as failed with the
    reason. (``multiprocessing.Pool`` would replace the worker and wait for the lost result forever.)"""
    ctx = mp.get_context("spawn")
    queue = list(todo)[::-1]
    attempts: dict[str, int] = {}
    running: dict[Connection, tuple[str, Any, dict[str, Any]]] = {}
    try:
        while queue or running:
            while queue and len(running) < max(workers, 1):
                name, kw = queue.pop()
                attempts[name] = attempts.get(name, 0) + 1
                recv, send = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_call_and_send, args=(send, fn, name, kw, threads, os.getpid()), daemon=True)
                proc.start()
                send.close()  # the child holds the only writer: EOF once it is gone
                running[recv] = (name, proc, kw)
            for conn in wait(list(running)):
                assert isinstance(conn, Connection)
                name, proc, kw = running.pop(conn)
                try:
                    result = conn.recv()
                except EOFError:
                    proc.join()
                    reason = _death_reason(proc.exitcode)
                    if attempts[name] <= retries:
                        tqdm.write(f"{name}: {reason.split(': ', 1)[1]}; starting it again (attempt {attempts[name] + 1})")
                        queue.append((name, kw))
                    else:
                        collect(name, None, f"{reason} (attempt {attempts[name]} of {retries + 1})")
                else:
                    collect(*result)
                    proc.join()
                finally:
                    conn.close()
    finally:
        for _, proc, _ in running.values():
            proc.terminate()
            proc.join()


class LocalExecutor:
    """This machine's worker processes (``--executor local``, the default).

    With more than one worker, or ``fresh_process``, every run gets a spawned process of its
    own, so a run that dies (out of memory) takes no other run with it and is started again
    (``retries`` times at most, then reported as failed). One worker without ``fresh_process``
    runs the jobs in this process. Workers write their run folders themselves (``layout`` is
    not needed: this process and its workers share the disk)."""

    def __init__(self, workers: int = 1, *, retries: int = DEFAULT_RETRIES) -> None:
        if workers < 1 or retries < 0:
            raise ValueError(f"workers must be >= 1 and retries >= 0, got {workers} and {retries}")
        self.workers = workers
        self.retries = retries

    def describe(self) -> str:
        return f"{self.workers} local worker process{'es' if self.workers != 1 else ''}"

    def run(
        self,
        todo: Sequence[Job],
        fn: Callable[..., dict[str, Any]],
        *,
        threads: int,
        fresh_process: bool,
        layout: RunLayout | None,
        collect: Collect,
    ) -> None:
        if fresh_process or self.workers > 1:
            _run_fresh_processes(todo, fn, self.workers, threads, collect, self.retries)
        else:
            for n, kw in todo:
                collect(*_call(fn, n, kw, threads))


def run_jobs(
    jobs: Sequence[Job],
    fn: Callable[..., dict[str, Any]],
    is_finished: Callable[[str], bool],
    load: Callable[[str], dict[str, Any]],
    *,
    workers: int = 1,
    threads: int = 1,
    progress: bool = True,
    desc: str = "runs",
    fresh_process: bool = False,
    executor: Executor | None = None,
    layout: RunLayout | None = None,
    verbose: bool = False,
) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """Runs the unfinished jobs (``fn(**kwargs)`` must be a module-level function writing its own
    result and returning it); returns ({name: result} of all finished jobs, {name: error}).

    ``executor`` carries the runs out (default: :class:`LocalExecutor` with ``workers``);
    ``layout`` says what each run reads and writes (needed by executors whose workers do not
    share this disk, such as Dask's).
    ``fresh_process`` runs every job in a new process (also with one worker), so that
    per-process measurements such as the peak resident memory belong to that job alone (a
    reused worker reports the largest peak of all the jobs it ran, and more).
    ``verbose`` prints a line (stderr) for every run that finishes."""
    names = [n for n, _ in jobs]
    if len(set(names)) != len(names):
        raise ValueError("job names must be unique")
    executor = executor or LocalExecutor(workers)
    done = {n: load(n) for n in names if is_finished(n)}
    todo = [(n, kw) for n, kw in jobs if n not in done]
    errors: dict[str, str] = {}
    if progress:
        print(f"{len(done)} of {len(jobs)} {desc} already finished; {len(todo)} to run on {executor.describe()}", flush=True)
    if not todo:
        return done, errors
    bar = tqdm(total=len(todo), desc=desc, unit="run", disable=not progress)

    def collect(name: str, result: Any, err: str | None) -> None:
        if result is not None:
            done[name] = result
            if verbose:
                tqdm.write(f"{name} finished ({len(done)} of {len(jobs)})", file=sys.stderr)
        else:
            errors[name] = err or "unknown error"
            tqdm.write(f"{name} failed: {errors[name].splitlines()[0]}")
        bar.update(1)

    try:
        executor.run(todo, fn, threads=threads, fresh_process=fresh_process, layout=layout, collect=collect)
    finally:
        bar.close()
    return done, errors
