"""Resumable sweeps of SLAM runs in parallel worker processes.

Every run writes its own folder; ``metrics.json`` is written last (atomically), so a folder with
it is a finished run. Re-running a sweep skips finished runs and redoes only the rest: a killed
sweep loses at most the runs that were in flight. Workers are started with the ``spawn``
context, because a forked child of a process whose rayon pool has started hangs.
"""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import traceback
from collections.abc import Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from tqdm import tqdm

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


def _worker(spec_dict: dict[str, Any], root: str) -> tuple[str, dict[str, Any] | None, str | None]:
    # Each worker limits its own rayon pool so that workers x threads matches the machine.
    threads = int(spec_dict.pop("threads"))
    os.environ["RAYON_NUM_THREADS"] = str(threads)
    from crlam.experiments.slam_run import run_slam_log

    cfg = SlamConfig(**spec_dict.pop("config"))
    spec = RunSpec(config=cfg, threads=threads, **spec_dict)
    try:
        res = run_slam_log(
            spec.log,
            spec.folder(Path(root)),
            cfg,
            reference=spec.reference,
            relations=spec.relations,
            max_scans=spec.max_scans,
            progress=False,
        )
        return spec.name, res.metrics, None
    except Exception as e:  # noqa: BLE001 - reported per run, the sweep goes on
        return spec.name, None, f"{type(e).__name__}: {e}\n{traceback.format_exc(limit=3)}"


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
) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """Runs every unfinished spec; returns ({name: metrics} of all finished runs, {name: error})."""
    root.mkdir(parents=True, exist_ok=True)
    names = [s.name for s in specs]
    if len(set(names)) != len(names):
        raise ValueError("run names must be unique within a sweep")
    done = {s.name: load_metrics(s.folder(root)) for s in specs if run_is_finished(s.folder(root))}
    todo = [s for s in specs if s.name not in done]
    errors: dict[str, str] = {}
    if progress:
        print(f"{len(done)} of {len(specs)} runs already finished; {len(todo)} to run with {workers} worker(s)", flush=True)
    if not todo:
        return done, errors
    bar = tqdm(total=len(todo), desc="runs", unit="run", disable=not progress)
    if workers <= 1:
        for s in todo:
            name, metrics, err = _worker(_spec_dict(s), str(root))
            _collect(name, metrics, err, done, errors, bar)
    else:
        ctx = mp.get_context("spawn")
        with ProcessPoolExecutor(max_workers=workers, mp_context=ctx) as pool:
            futures = [pool.submit(_worker, _spec_dict(s), str(root)) for s in todo]
            for f in as_completed(futures):
                _collect(*f.result(), done, errors, bar)
    bar.close()
    return done, errors


def _collect(
    name: str,
    metrics: dict[str, Any] | None,
    err: str | None,
    done: dict[str, dict[str, Any]],
    errors: dict[str, str],
    bar: Any,
) -> None:
    if metrics is not None:
        done[name] = metrics
    else:
        errors[name] = err or "unknown error"
        tqdm.write(f"run {name} failed: {errors[name].splitlines()[0]}")
    bar.update(1)
