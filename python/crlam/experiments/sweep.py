"""Resumable sweeps of SLAM runs in parallel worker processes.

Every run writes its own folder; ``metrics.json`` is written last (atomically), so a folder with
it is a finished run. Re-running a sweep skips finished runs and redoes only the rest: a killed
sweep loses at most the runs that were in flight. A finished run is only reused when the settings
in its ``config.toml`` are the ones the sweep asks for; otherwise the sweep stops with a
``ConfigError`` rather than mix settings in one table. Workers are started with the ``spawn``
context, because a forked child of a process whose rayon pool has started hangs.
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from crlam.errors import ConfigError, CrlamError
from crlam.experiments.executor import Executor, RunLayout
from crlam.experiments.pool import run_jobs
from crlam.experiments.resume import load_json_dict
from crlam.io.npz_check import check_npz
from crlam.io.run_folder import staged_folder
from crlam.io.structured import load_toml_text
from crlam.io.tum import read_tum
from crlam.slam import SlamConfig

__all__ = ["RunSpec", "run_is_finished", "run_sweep", "load_metrics", "stored_setting_differences"]

_UNSET_LINE = re.compile(r"^# (\w+) = \(unset\)$", re.MULTILINE)

#: A SLAM run reads its log, reference and relations and writes ``metrics.json`` last; its map
#: (``belief.npz``, hundreds of MB for a large log) is the file a remote executor may leave out.
SLAM_RUN_LAYOUT = RunLayout(inputs=("log", "reference", "relations"), maps=("belief.npz",))


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
    """A run is finished when its metrics.json (written last) reads as a JSON object and the files
    the report reads back, where present, read too: a run with a corrupt file is done again."""
    if load_json_dict(folder / "metrics.json") is None:
        return False
    try:
        if (folder / "config.toml").is_file():
            load_toml_text((folder / "config.toml").read_text(), str(folder / "config.toml"))
        if (folder / "trajectory.tum").is_file():
            read_tum(folder / "trajectory.tum")
        if (folder / "belief.npz").is_file():
            check_npz(folder / "belief.npz", "belief archive")
    except (CrlamError, OSError, ValueError):
        return False
    return True


def load_metrics(folder: Path) -> dict[str, Any]:
    """The metrics of a finished run (an empty dict if they cannot be read)."""
    return load_json_dict(folder / "metrics.json") or {}


def _normalised(v: Any) -> Any:
    return list(v) if isinstance(v, tuple) else v


def stored_setting_differences(spec: RunSpec, folder: Path) -> list[str]:
    """The settings of the finished run in ``folder`` that differ from ``spec``, as
    ``"name: stored X, requested Y"`` (empty when they agree).

    Compared: every ``SlamConfig`` field and ``max_scans``; not the file paths (data may move) and
    not the preset's name (the values it resolved to are compared), nor the ``motion_params`` a
    run with ``motion_noise = "estimate"`` fitted to its log when the request leaves them unset.
    ``None`` is written as an ``# name = (unset)`` comment. A field the file does not name at all
    did not exist when the run was made; the run then had that field's default behaviour, so it
    matches a request for the default. A run folder without ``config.toml`` is not checked."""
    path = folder / "config.toml"
    if not path.is_file():
        return []
    text = path.read_text()
    doc = load_toml_text(text, str(path), lambda message: ConfigError(f"{path}: {message}"))
    unset = set(_UNSET_LINE.findall(text))
    stored_slam = doc.get("slam", {})
    default = SlamConfig().to_dict()
    diffs = []
    requested = spec.config.to_dict()
    for key, want in requested.items():
        if key == "preset":
            continue  # provenance, not a setting: the values themselves are compared
        if key == "motion_params" and want is None and requested.get("motion_noise") == "estimate":
            continue  # the run fitted them to its log and wrote them down (crlam.slam.motion_noise)
        want = _normalised(want)
        if key in stored_slam:
            have = stored_slam[key]
        elif key in unset:
            have = None
        else:
            have = _normalised(default[key])
        if have != want:
            diffs.append(f"{key}: stored {have!r}, requested {want!r}")
    run_section = doc.get("run", {})
    have_scans = run_section.get("max_scans")
    if have_scans != spec.max_scans:
        diffs.append(f"max_scans: stored {have_scans!r}, requested {spec.max_scans!r}")
    return diffs


def _check_finished_runs(specs: Sequence[RunSpec], root: Path) -> None:
    problems = []
    for s in specs:
        folder = s.folder(root)
        if run_is_finished(folder):
            diffs = stored_setting_differences(s, folder)
            if diffs:
                problems.append(f"{folder}: " + "; ".join(diffs))
    if problems:
        raise ConfigError(
            f"{len(problems)} finished run(s) under {root} were made with other settings than this command asks "
            "for (use another output folder, --force to redo every run, or delete those run folders to redo them):\n  "
            + "\n  ".join(problems)
        )


def _run_spec(
    spec_dict: dict[str, Any], folder: str, log: str, reference: str | None = None, relations: str | None = None
) -> dict[str, Any]:
    """One SLAM run in a worker (module level, so that ``spawn`` can pickle it). The paths are
    arguments of their own (not in ``spec_dict``): an executor may point them at copies."""
    from crlam.experiments.slam_run import run_slam_log

    d = dict(spec_dict)
    cfg = SlamConfig(**d.pop("config"))
    # Staged: the run's folder appears (replacing an older, unfinished or corrupt one) only whole.
    with staged_folder(Path(folder), command=f"crlam experiment run {Path(folder).name}") as stage:
        res = run_slam_log(
            log,
            stage,
            cfg,
            reference=reference,
            relations=relations,
            max_scans=d["max_scans"],
            progress=False,
        )
    return dict(res.metrics)


def _spec_dict(spec: RunSpec) -> dict[str, Any]:
    d = asdict(spec)
    for k in ("name", "log", "reference", "relations"):
        del d[k]
    d["config"] = spec.config.to_dict()
    for k in ("motion_params", "init_sigma", "lattice_step", "mode_bandwidth"):
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
    executor: Executor | None = None,
    verbose: bool = False,
) -> tuple[dict[str, dict[str, Any]], dict[str, str]]:
    """Runs every unfinished spec; returns ({name: metrics} of all finished runs, {name: error}).

    ``executor`` carries the runs out (default: ``workers`` local processes; see
    :mod:`crlam.experiments.executor`).

    ``report_only`` runs nothing and returns the runs finished so far (an interim report of a
    sweep that is still going on elsewhere or was stopped).

    Raises
    ------
    ConfigError
        When a finished run's ``config.toml`` holds other settings than its spec (see
        ``stored_setting_differences``); nothing is run then."""
    root.mkdir(parents=True, exist_ok=True)
    by_name = {s.name: s for s in specs}
    _check_finished_runs(specs, root)
    if report_only:
        return {s.name: load_metrics(s.folder(root)) for s in specs if run_is_finished(s.folder(root))}, {}
    threads = max((s.threads for s in specs), default=1)
    paths = [{"log": s.log, "reference": s.reference, "relations": s.relations} for s in specs]
    jobs = [(s.name, {"spec_dict": _spec_dict(s), "folder": str(s.folder(root)), **p}) for s, p in zip(specs, paths)]
    return run_jobs(
        jobs,
        _run_spec,
        lambda n: run_is_finished(by_name[n].folder(root)),
        lambda n: load_metrics(by_name[n].folder(root)),
        workers=workers,
        threads=threads,
        progress=progress,
        verbose=verbose,
        # Each SLAM run reports its own peak RSS.
        fresh_process=True,
        desc="runs",
        executor=executor,
        layout=SLAM_RUN_LAYOUT,
    )
