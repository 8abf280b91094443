"""Resumable sweeps of SLAM runs in parallel worker processes.

Every run writes its own folder; ``metrics.json`` is written last (atomically), so a folder with
it is a finished run. Re-running a sweep skips finished runs and redoes only the rest: a killed
sweep loses at most the runs that were in flight. Workers are started with the ``spawn``
context, because a forked child of a process whose rayon pool has started hangs.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from crlam.experiments.pool import run_jobs
from crlam.slam import SlamConfig

__all__ = ["RunSpec", "run_is_finished", "run_sweep", "load_metrics"]


@dataclass(frozen=True)
class RunSpec:
    """One SLAM run of a sweep."""

    name: str
    log: str
    config: SlamConfig
    reference: str | None = None
    relations: str | None = None
    max_scans: int | None = None
    threads: int = 1

    def folder(self, root: Path) -> Path:
        return root / "runs" / self.name


def run_is_finished(folder: Path) -> bool:
    """A run is finished when its metrics.json exists (it is written last)."""
    return (folder / "metrics.json").is_file()


def load_metrics(folder: Path) -> dict[str, Any]:
    return json.loads((folder / "metrics.json").read_text())


def _run_spec(spec_dict: dict[str, Any], root: str) -> dict[str, Any]:
    """One SLAM run in a worker (module level, so that ``spawn`` can pickle it)."""
    from crlam.experiments.slam_run import run_slam_log

    d = dict(spec_dict)
    cfg = SlamConfig(**d.pop("config"))
    spec = RunSpec(config=cfg, **d)
    res = run_slam_log(
        spec.log,
        spec.folder(Path(root)),
        cfg,
        reference=spec.reference,
        relations=spec.relations,
        max_scans=spec.max_scans,
        progress=False,
    )
    return dict(res.metrics)


def _spec_dict(spec: RunSpec) -> dict[str, Any]:
    d = asdict(spec)
    d["config"] = spec.config.to_dict()
    for k in ("motion_params", "init_sigma"):
        if d["config"].get(k) is not None:
            d["config"][k] = tuple(d["config"][k])
    return d


def run_sweep(
    specs: Sequence[RunSpec],
    root: Path,
    *,
    workers: int = 1,
    progress: bool = True,
    report_only: bool = False,
) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """Runs every unfinished spec; returns ({name: metrics} of all finished runs, {name: error}).

    ``report_only`` runs nothing and returns the runs finished so far (an interim report of a
    sweep that is still going on elsewhere or was stopped)."""
    root.mkdir(parents=True, exist_ok=True)
    by_name = {s.name: s for s in specs}
    if report_only:
        return {s.name: load_metrics(s.folder(root)) for s in specs if run_is_finished(s.folder(root))}, {}
    threads = max((s.threads for s in specs), default=1)
    jobs = [(s.name, {"spec_dict": _spec_dict(s), "root": str(root)}) for s in specs]
    return run_jobs(
        jobs,
        _run_spec,
        lambda n: run_is_finished(by_name[n].folder(root)),
        lambda n: load_metrics(by_name[n].folder(root)),
        workers=workers,
        threads=threads,
        progress=progress,
        # Each SLAM run reports its own peak RSS.
        fresh_process=True,
        desc="runs",
    )
