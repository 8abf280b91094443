"""Runs of a sweep on a Dask cluster (``--executor dask``).

With a scheduler address the runs go to that cluster (started by hand with ``dask scheduler`` and
``dask worker``, or by ``dask-jobqueue`` on a batch system); without one a
``distributed.LocalCluster`` of ``workers`` processes is started on this machine and stopped at the
end. Dask (``pip install "crlam[cluster]"``) is imported only here, and only when a sweep runs.

The guarantees are those of the local executor:

- no shared file system is needed: each run's input files are sent to the workers (once per
  worker), and each finished run's files come back to this process, which writes them through a
  staging folder (:mod:`crlam.io.run_folder`), so a run folder appears only whole; maps
  (``RunLayout.maps``) come back only with ``keep_maps``;
- a rerun skips finished runs (the sweep loop checks the markers before anything is sent);
- a worker killed mid-run costs only the runs it held: the scheduler starts them elsewhere, up to
  ``retries`` more times (the LocalCluster's ``allowed-failures``; a cluster of your own uses its
  scheduler's setting, Dask's default 3), and the run's own process dying (out of memory) is
  retried by the task's ``retries``; after that the run is recorded as failed with the reason;
- results do not depend on the executor: each run is the same function of the same arguments
  (its seed among them), in a process of its own on the worker (:mod:`crlam.experiments.remote_run`);
- worker processes are never forked from a process running rayon: the LocalCluster's nannies
  start their workers with the ``spawn`` method, and each run is a new interpreter.
"""

from __future__ import annotations

import logging
import secrets
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from crlam.errors import ConfigError
from crlam.experiments.executor import Collect, Job, RunLayout
from crlam.experiments.pool import DEFAULT_RETRIES
from crlam.experiments.remote_run import InputFiles, RemoteResult, input_files, run_remote

__all__ = ["DaskExecutor", "INSTALL_HINT", "write_run_files"]

#: Seconds between looks at the cluster's size while runs are in flight.
_TOP_UP_S = 2.0

INSTALL_HINT = 'the Dask executor needs Dask\'s distributed scheduler: pip install "crlam[cluster]"'


def _distributed() -> Any:
    try:
        import distributed
    except ImportError as e:
        raise ConfigError(INSTALL_HINT) from e
    return distributed


def write_run_files(folder: Path, files: dict[str, bytes]) -> None:
    """Writes a run's files into ``folder`` through a staging folder (:mod:`crlam.io.run_folder`):
    the folder appears, replacing an older unfinished or corrupt one, only when every file is
    written, whenever this process stops. The worker's own markers are not copied; the staging
    writes its own ``COMPLETE`` last."""
    from crlam.io.run_folder import COMPLETE, INCOMPLETE, staged_folder

    with staged_folder(folder, command="crlam experiment (run sent back by a Dask worker)") as stage:
        for rel in sorted(files):
            if rel in (COMPLETE, INCOMPLETE):
                continue
            path = stage / rel
            path.parent.mkdir(parents=True, exist_ok=True)
            path.write_bytes(files[rel])


class DaskExecutor:
    """The workers of a Dask cluster (see the module docstring).

    Parameters
    ----------
    scheduler:
        Address of a running scheduler (``tcp://HOST:8786``); None starts a LocalCluster.
    workers:
        Worker processes of the LocalCluster (one thread each: one run at a time per worker).
        Not used with a scheduler: the cluster's workers are.
    keep_maps:
        Also send back each run's maps (``RunLayout.maps``, e.g. ``belief.npz``).
    retries:
        How often a run whose worker or process died is started again before it is recorded
        as failed.
    """

    def __init__(
        self, scheduler: str | None = None, *, workers: int = 2, keep_maps: bool = False, retries: int = DEFAULT_RETRIES
    ) -> None:
        if workers < 1 or retries < 0:
            raise ValueError(f"workers must be >= 1 and retries >= 0, got {workers} and {retries}")
        self.scheduler = scheduler
        self.workers = workers
        self.keep_maps = keep_maps
        self.retries = retries

    def check_scheduler(self, timeout: float = 10.0) -> None:
        """Connect to the scheduler once and disconnect, so that a sweep that cannot start (no
        scheduler there, a malformed address, Dask not installed) fails before it makes its
        experiment folder (``crlam experiment --executor dask`` calls this first). Without a
        scheduler address only Dask's presence is checked.

        Raises
        ------
        ConfigError
            Naming the address and the reason.
        """
        distributed = _distributed()
        if not self.scheduler:
            return
        from distributed.comm import parse_address
        from distributed.comm.addressing import parse_host_port

        try:
            # The address first, without a client (a client made on a malformed address fails
            # late and complains again when it is collected).
            scheme, location = parse_address(self.scheduler)
            if scheme in ("tcp", "tls", "ws", "wss"):
                parse_host_port(location)
        except (ValueError, TypeError) as e:
            raise ConfigError(f"--scheduler {self.scheduler!r} is not a Dask address such as tcp://HOST:8786 ({e})") from e
        try:
            with distributed.Client(self.scheduler, timeout=timeout, set_as_default=False):
                pass
        except (OSError, ValueError, TypeError) as e:  # TimeoutError is an OSError
            reason = " ".join(str(e).split())[:200] or type(e).__name__
            raise ConfigError(
                f"cannot reach the Dask scheduler at {self.scheduler!r} ({reason}); nothing was started or written"
            ) from e

    def describe(self) -> str:
        if self.scheduler:
            return f"the Dask cluster at {self.scheduler}"
        return f"a local Dask cluster of {self.workers} worker process{'es' if self.workers != 1 else ''}"

    @contextmanager
    def client(self) -> Iterator[Any]:
        """A connected ``distributed.Client`` (and the LocalCluster behind it, if any), closed on exit."""
        distributed = _distributed()
        import dask

        if self.scheduler:
            with distributed.Client(self.scheduler) as client:
                yield client
            return
        settings = {
            # A task whose worker died is started again this often, then fails with KilledWorker.
            "distributed.scheduler.allowed-failures": self.retries,
            # Dask's default, stated because it matters: a forked child of a rayon process hangs.
            "distributed.worker.multiprocessing-method": "spawn",
        }
        with dask.config.set(settings):
            cluster = distributed.LocalCluster(
                n_workers=self.workers,
                threads_per_worker=1,
                processes=True,
                dashboard_address=":0",  # any free port (only served when bokeh is installed)
                silence_logs=logging.ERROR,
            )
            with cluster, distributed.Client(cluster) as client:
                yield client

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
        """Sends every job to the cluster and writes each finished run as it arrives (every run
        gets a process of its own on its worker, so ``fresh_process`` is always met)."""
        if layout is None:
            raise ConfigError("this sweep does not say what its runs read and write; run it with --executor local")
        distributed = _distributed()
        from crlam import __version__

        payloads = _inputs(todo, layout)
        with self.client() as client:
            if not client.scheduler_info()["workers"]:
                print(f"waiting for the first worker of {self.describe()}", flush=True)
                client.wait_for_workers(1)
            # Every worker holds the inputs before the first run, so none looks closer to the data
            # than another and the scheduler sends each run to an idle worker.
            shipped = {path: client.scatter(payload, broadcast=True, hash=False) for path, payload in payloads.items()}
            tag = secrets.token_hex(4)

            def submit(name: str, kw: dict[str, Any]) -> Any:
                inputs = {k: shipped[str(kw[k])] for k in layout.inputs if kw.get(k) is not None and str(kw[k]) in shipped}
                args = (fn, name, kw, threads, layout, self.keep_maps, inputs, __version__)
                return client.submit(run_remote, *args, key=f"crlam-{name}-{tag}", retries=self.retries, pure=False)

            # No more runs in flight than the cluster has threads: a worker that dies takes only the
            # runs it was running with it (each queued run it held would count as a failed attempt
            # too), and workers that join later (an adaptive cluster) get runs as they come.
            queue = list(todo)[::-1]
            pending: dict[Any, Job] = {}
            while queue or pending:
                slots = max(1, sum(client.nthreads().values()))
                while queue and len(pending) < slots:
                    job = queue.pop()
                    pending[submit(*job)] = job
                try:
                    finished = distributed.wait(list(pending), timeout=_TOP_UP_S, return_when="FIRST_COMPLETED").done
                except TimeoutError:
                    continue
                for future in finished:
                    self._collect(future, pending.pop(future), layout, collect)

    def _collect(self, future: Any, job: Job, layout: RunLayout, collect: Collect) -> None:
        """Writes a finished run's files (marker last) and reports it, or reports its error."""
        distributed = _distributed()
        name, kw = job
        try:
            answer: RemoteResult = future.result()
        except distributed.KilledWorker as e:
            collect(name, None, f"KilledWorker: every worker that ran it died ({self.retries + 1} attempts): {e}")
            return
        except Exception as e:  # noqa: BLE001 - reported per run, the others go on
            collect(name, None, f"{type(e).__name__}: {e}")
            return
        finally:
            future.release()
        if answer.error is not None or answer.result is None:
            collect(name, None, answer.error)
            return
        write_run_files(Path(kw[layout.folder]), answer.files)
        collect(name, answer.result, None)


def _inputs(todo: Sequence[Job], layout: RunLayout) -> dict[str, InputFiles]:
    """Every distinct input path of the jobs that exists here, read once."""
    out: dict[str, InputFiles] = {}
    for _, kw in todo:
        for key in layout.inputs:
            value = kw.get(key)
            if value is None or str(value) in out or not Path(str(value)).exists():
                continue
            out[str(value)] = input_files(str(value))
    return out
