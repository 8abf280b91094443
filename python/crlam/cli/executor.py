"""The ``--executor`` options of ``crlam experiment``: where a sweep's runs go."""

from __future__ import annotations

import argparse

from crlam.cli.options import nonnegative_int
from crlam.errors import ConfigError
from crlam.experiments.executor import Executor
from crlam.experiments.pool import DEFAULT_RETRIES, LocalExecutor

__all__ = ["EXECUTORS", "add_executor_options", "executor_from_args"]

EXECUTORS = ("local", "dask")


def add_executor_options(parser: argparse.ArgumentParser) -> None:
    """``--executor``, ``--scheduler``, ``--keep-maps`` and ``--retries`` (the parser has ``--workers``)."""
    g = parser.add_argument_group("where the runs go")
    g.add_argument(
        "--executor",
        choices=EXECUTORS,
        default="local",
        help="local: --workers spawned processes on this machine (default). dask: a Dask cluster, the one at "
        '--scheduler or else a LocalCluster of --workers processes; needs pip install "crlam[cluster]". '
        "The results are the same either way",
    )
    g.add_argument(
        "--scheduler",
        default=None,
        metavar="ADDRESS",
        help="address of a running Dask scheduler, e.g. tcp://HOST:8786 (with --executor dask; its workers replace --workers)",
    )
    g.add_argument(
        "--keep-maps",
        action="store_true",
        help="with --executor dask, also send back every run's map (belief.npz; hundreds of MB for a large log). "
        "The local executor always writes it",
    )
    g.add_argument(
        "--retries",
        type=nonnegative_int,
        default=DEFAULT_RETRIES,
        help=f"a run whose worker or process died (out of memory, a killed node) is started again this often, then "
        f"recorded as failed (default: {DEFAULT_RETRIES}; with --scheduler the scheduler's allowed-failures "
        "setting counts the worker deaths)",
    )


def executor_from_args(args: argparse.Namespace) -> Executor:
    """The executor the options ask for.

    Raises
    ------
    ConfigError
        For ``--scheduler`` or ``--keep-maps`` without ``--executor dask``."""
    if args.executor == "local":
        if args.scheduler is not None or args.keep_maps:
            raise ConfigError("--scheduler and --keep-maps go with --executor dask")
        return LocalExecutor(args.workers, retries=args.retries)
    from crlam.experiments.dask_executor import DaskExecutor

    executor = DaskExecutor(args.scheduler, workers=args.workers, keep_maps=args.keep_maps, retries=args.retries)
    # Before the experiment folder is made: a sweep that cannot start leaves nothing behind.
    executor.check_scheduler()
    return executor
