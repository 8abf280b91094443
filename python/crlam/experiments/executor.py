"""The executor interface: how the runs of an experiment's sweep are carried out.

Every ``crlam experiment`` hands its unfinished runs to one :class:`Executor`:

- :class:`crlam.experiments.pool.LocalExecutor` (``--executor local``, the default): spawned
  worker processes on this machine, writing their run folders themselves;
- :class:`crlam.experiments.dask_executor.DaskExecutor` (``--executor dask``): the workers of a
  Dask cluster, which send each finished run's files back to this process, which writes them.

Whatever the executor, the sweep loop around it (:func:`crlam.experiments.pool.run_jobs`) is the
same: finished runs are skipped, each finished run is recorded as it arrives, a failed run is
reported with its error and the others go on, and the progress bar counts runs. A run's numbers
depend only on its arguments (its seed among them), never on the executor or the worker count.

This module holds only the interface, so that both executors and the sweeps can import it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

__all__ = ["Collect", "Executor", "Job", "RunLayout"]

Job = tuple[str, dict[str, Any]]
"""(name, keyword arguments of the worker function)."""

Collect = Callable[[str, Any, "str | None"], None]
"""``collect(name, result, error)``: called once per run as it ends (result None on failure)."""


@dataclass(frozen=True)
class RunLayout:
    """What a run reads and writes, for executors whose workers do not share this machine's disk.

    Attributes
    ----------
    folder:
        The keyword argument holding the run's folder (as this process sees it). A remote worker
        runs the job with a scratch folder of its own instead and sends the files back.
    inputs:
        Keyword arguments holding paths of files or folders the run reads. Those that exist
        here are sent to the workers; other values (``None``, a built-in world's name) pass
        unchanged.
    maps:
        File names of a run's maps (hundreds of MB for large logs): sent back only when asked
        for (``--keep-maps``); the local executor always writes them.
    """

    folder: str = "folder"
    inputs: tuple[str, ...] = ()
    maps: tuple[str, ...] = ()


class Executor(Protocol):
    """Runs jobs somewhere and reports each one as it ends."""

    def describe(self) -> str:
        """Where the runs go, for the sweep's first line (e.g. "2 local worker processes")."""
        ...

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
        """Runs ``fn(**kwargs)`` for every job and calls ``collect`` once per job, in the order
        they end. By the time ``collect(name, result, None)`` is called, the run's folder holds
        its files with the marker written last.

        ``threads``: rayon threads of each run (the environment variable ``RAYON_NUM_THREADS``
        of the process running it). ``fresh_process``: every run in a process of its own, so that
        per-process measurements (peak memory) are the run's alone."""
        ...
