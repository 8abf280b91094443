"""Resumable jobs in ``spawn`` worker processes.

A job is finished when its folder holds the marker file the worker writes last (atomically), so
a killed run loses at most the jobs in flight and rerunning skips the finished ones. Workers use
the ``spawn`` context: a forked child of a process whose rayon pool has started hangs.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import signal
import threading
import time
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from multiprocessing.connection import Connection, wait
from pathlib import Path
from typing import Any

from tqdm import tqdm

__all__ = ["Job", "run_jobs", "write_atomic"]

Job = tuple[str, dict[str, Any]]
"""(name, keyword arguments of the worker function)."""


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
    collect: Callable[[str, Any, str | None], None],
) -> None:
    """Every job in its own spawned process, at most ``workers`` at a time. A process that dies
    without a result (killed by the OOM killer, a crash in native code) fails its job only;
    ``multiprocessing.Pool`` would replace the worker and wait for the lost result forever."""
    ctx = mp.get_context("spawn")
    queue = list(todo)[::-1]
    running: dict[Connection, tuple[str, Any]] = {}
    try:
        while queue or running:
            while queue and len(running) < max(workers, 1):
                name, kw = queue.pop()
                recv, send = ctx.Pipe(duplex=False)
                proc = ctx.Process(target=_call_and_send, args=(send, fn, name, kw, threads, os.getpid()), daemon=True)
                proc.start()
                send.close()  # the child holds the only writer: EOF once it is gone
                running[recv] = (name, proc)
            for conn in wait(list(running)):
                assert isinstance(conn, Connection)
                name, proc = running.pop(conn)
                try:
                    result = conn.recv()
                except EOFError:
                    proc.join()
                    collect(name, None, _death_reason(proc.exitcode))
                else:
                    collect(*result)
                    proc.join()
                finally:
                    conn.close()
    finally:
        for _, proc in running.values():
            proc.terminate()
            proc.join()


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
) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """Runs the unfinished jobs (``fn(**kwargs)`` must be a module-level function writing its own
    result and returning it); returns ({name: result} of all finished jobs, {name: error}).

    ``fresh_process`` runs every job in a new spawned process (also with one worker), so that
    per-process measurements such as the peak resident memory belong to that job alone (a
    reused worker reports the largest peak of all the jobs it ran, and more)."""
    names = [n for n, _ in jobs]
    if len(set(names)) != len(names):
        raise ValueError("job names must be unique")
    done = {n: load(n) for n in names if is_finished(n)}
    todo = [(n, kw) for n, kw in jobs if n not in done]
    errors: dict[str, str] = {}
    if progress:
        print(f"{len(done)} of {len(jobs)} {desc} already finished; {len(todo)} to run with {workers} worker(s)", flush=True)
    if not todo:
        return done, errors
    bar = tqdm(total=len(todo), desc=desc, unit="run", disable=not progress)

    def collect(name: str, result: Any, err: str | None) -> None:
        if result is not None:
            done[name] = result
        else:
            errors[name] = err or "unknown error"
            tqdm.write(f"{name} failed: {errors[name].splitlines()[0]}")
        bar.update(1)

    if fresh_process:
        _run_fresh_processes(todo, fn, workers, threads, collect)
    elif workers <= 1:
        for n, kw in todo:
            collect(*_call(fn, n, kw, threads))
    else:
        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            futures = [pool.submit(_call, fn, n, kw, threads) for n, kw in todo]
            for f in as_completed(futures):
                collect(*f.result())
    bar.close()
    return done, errors
