"""Resumable jobs in ``spawn`` worker processes.

A job is finished when its folder holds the marker file the worker writes last (atomically), so
a killed run loses at most the jobs in flight and rerunning skips the finished ones. Workers use
the ``spawn`` context: a forked child of a process whose rayon pool has started hangs.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import traceback
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
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


def _call_packed(args: tuple[Callable[..., dict[str, Any]], str, dict[str, Any], int]) -> tuple[str, Any, str | None]:
    return _call(*args)


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
        ctx = mp.get_context("spawn")
        with ctx.Pool(max(workers, 1), maxtasksperchild=1) as procs:
            for result in procs.imap_unordered(_call_packed, [(fn, n, kw, threads) for n, kw in todo]):
                collect(*result)
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
