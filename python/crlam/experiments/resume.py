"""What makes an experiment folder safe to resume.

An experiment records the settings its runs depend on in ``experiment.json`` when it starts. A
resumed experiment (``--resume``, or the API's default) compares them with the settings asked for
and refuses on any difference, so runs of another map, budget or protocol are never reported
under the new settings; ``--force`` replaces the folder instead. Settings of the sweep's extent
(how many seeds, which functions) may change between resumes: runs are added, or left out of the
report. While the sweep runs, the folder holds an ``INCOMPLETE`` file; it becomes ``COMPLETE``
when every run of the last sweep finished.

A run whose result file is missing, unreadable or not what it should be is not finished: it is
run again (into a staging folder that replaces its old one), never a traceback.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from crlam.errors import ConfigError
from crlam.io.run_folder import COMPLETE, INCOMPLETE, check_output

__all__ = ["SETTINGS_FILE", "close_experiment", "file_digest", "input_digest", "load_json_dict", "open_experiment"]

SETTINGS_FILE = "experiment.json"


def load_json_dict(path: str | os.PathLike[str]) -> dict[str, Any] | None:
    """The JSON object in ``path``, or None when it is missing, unreadable or not an object."""
    try:
        value = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return None
    return value if isinstance(value, dict) else None


def file_digest(path: str | os.PathLike[str]) -> str:
    """SHA-256 of a file's bytes (what identifies an input whatever its path)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            h.update(block)
    return h.hexdigest()


def input_digest(path: str | os.PathLike[str]) -> str:
    """SHA-256 identifying an input file by content; a Nav2 map YAML is identified by its own bytes
    and those of the image it names (the image is what a changed map changes)."""
    p = Path(path)
    h = hashlib.sha256(file_digest(p).encode())
    if p.suffix.lower() in (".yaml", ".yml"):
        from crlam.io.lines import read_small_text
        from crlam.io.structured import load_yaml_text

        try:
            doc = load_yaml_text(read_small_text(p, "map YAML"), str(p))
            image = p.parent / str(doc["image"])
            h.update(file_digest(image).encode())
        except (OSError, ValueError, KeyError, TypeError):
            pass  # the map itself will fail to load with a clear error
    return h.hexdigest()


def _normal(v: Any) -> Any:
    return json.loads(json.dumps(v, sort_keys=True, default=str))


def _differences(stored: Mapping[str, Any], fixed: Mapping[str, Any], items: Mapping[str, Any]) -> list[str]:
    diffs = []
    have_fixed = stored.get("settings", {})
    for key, want in _normal(dict(fixed)).items():
        have = have_fixed.get(key, "(not recorded)")
        if have != want:
            diffs.append(f"{key}: stored {have!r}, requested {want!r}")
    have_items = stored.get("inputs", {})
    for key, want in _normal(dict(items)).items():
        if key in have_items and have_items[key] != want:
            diffs.append(f"{key}: stored {have_items[key]!r}, requested {want!r}")
    return diffs


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def open_experiment(
    out: str | os.PathLike[str],
    experiment: str,
    settings: Mapping[str, Any],
    *,
    inputs: Mapping[str, Any] | None = None,
    resume: bool = True,
    force: bool = False,
    report_only: bool = False,
    runs_check_themselves: bool = False,
) -> Path:
    """Readies the folder of an experiment and returns it.

    ``settings`` are the values every run depends on: a resumed folder must have been made with
    exactly these. ``inputs`` identify per-item inputs (e.g. ``{"world:office": digest}``): an
    item both folders know must match, new items may be added. A folder that exists is refused
    unless ``resume`` (or ``report_only``) and its ``experiment.json`` agrees, or ``force``, which
    empties it first. A folder without ``experiment.json`` (made before crlam recorded it) is
    refused, unless ``runs_check_themselves``: the SLAM sweeps compare every finished run's own
    ``config.toml`` with its requested settings.

    Raises
    ------
    ConfigError
        Naming every difference, or why the folder cannot be resumed.
    """
    continuing = (resume or report_only) and Path(out).is_dir()
    root = check_output(out, force=force, resume=continuing, resumable=True, what="experiment folder")
    inputs = dict(inputs or {})
    if root.is_dir() and any(root.iterdir()):
        if force:
            for child in root.iterdir():
                if child.is_dir() and not child.is_symlink():
                    shutil.rmtree(child)
                else:
                    child.unlink()
        else:
            stored = load_json_dict(root / SETTINGS_FILE)
            if stored is None and runs_check_themselves and not (root / SETTINGS_FILE).exists():
                stored = {"experiment": experiment, "settings": _normal(dict(settings)), "inputs": {}}
            if stored is None:
                raise ConfigError(
                    f"experiment folder {root} has no readable {SETTINGS_FILE} (made by an older crlam, or not an "
                    "experiment folder): its runs cannot be checked against these settings; use --force to redo them, "
                    "or another --out"
                )
            if stored.get("experiment") != experiment:
                raise ConfigError(f"{root} is a folder of experiment {stored.get('experiment')!r}, not {experiment!r}")
            diffs = _differences(stored, settings, inputs)
            if diffs:
                raise ConfigError(
                    f"experiment folder {root} was made with other settings than this command asks for (use --force to "
                    "redo every run, or another --out):\n  " + "\n  ".join(diffs)
                )
            inputs = {**stored.get("inputs", {}), **_normal(inputs)}
    if report_only:
        return root
    root.mkdir(parents=True, exist_ok=True)
    record = {"experiment": experiment, "settings": _normal(dict(settings)), "inputs": _normal(inputs)}
    _write_atomic(root / SETTINGS_FILE, json.dumps(record, indent=2, sort_keys=True) + "\n")
    (root / COMPLETE).unlink(missing_ok=True)
    _write_atomic(
        root / INCOMPLETE,
        f"crlam experiment {experiment}: runs in progress (pid {os.getpid()}); the finished ones are in runs/. "
        "Rerun the command with --resume to continue.\n",
    )
    return root


def close_experiment(root: Path, *, n_runs: int, failed: Mapping[str, str]) -> None:
    """Marks the folder ``COMPLETE`` when no run failed; else ``INCOMPLETE`` names the failures."""
    if failed:
        names = ", ".join(sorted(failed)[:10]) + (" ..." if len(failed) > 10 else "")
        _write_atomic(
            root / INCOMPLETE,
            f"{len(failed)} of {n_runs} runs failed ({names}); see report.md. Rerun with --resume to retry them.\n",
        )
        return
    (root / INCOMPLETE).unlink(missing_ok=True)
    _write_atomic(root / COMPLETE, f"all {n_runs} runs finished\n")
