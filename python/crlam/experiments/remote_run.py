"""One run on a machine that does not share the client's disk (the worker side of the Dask executor).

A task gets the job, the run's input files (sent once per worker and kept in the worker's scratch
folder under their content hash) and returns the run's result together with the files of its
folder, which the client writes. On the worker the run happens in a child process of its own:

- its peak memory is its own (``peak_rss_mb`` of a reused worker would be the worker's);
- ``RAYON_NUM_THREADS`` is set before rayon starts, whatever ran in the worker before;
- a run killed by the OOM killer or a native crash leaves the worker up: the task raises
  :class:`RunProcessDied` and Dask starts it again (``retries``);
- the child is a new interpreter (``subprocess``: fork and exec at once, so no copy of the worker
  goes on running, whose rayon pool may have started) and ends itself when its worker is gone.

Paths the worker saw in place of the client's (the input files, the scratch run folder) are
replaced by the client's in the result and in the run's text files, so the run folder reads as
if the run had been made on the client.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import shutil
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from crlam.experiments.executor import RunLayout
from crlam.experiments.pool import _call, _death_reason, _exit_with_parent

__all__ = ["InputFiles", "RemoteResult", "RunProcessDied", "child_main", "input_files", "run_remote"]

#: Files whose text may name a path (rewritten from the worker's paths to the client's).
TEXT_SUFFIXES = frozenset({".json", ".toml", ".yaml", ".yml", ".csv", ".tum", ".md", ".txt"})
#: Map files that come with a map file of the same stem (a Nav2 YAML and its image).
_MAP_IMAGE_SUFFIXES = (".pgm", ".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff")
_POLL_S = 0.5


class RunProcessDied(RuntimeError):
    """The process running a job ended without a result (killed, out of memory, native crash)."""


@dataclass(frozen=True)
class InputFiles:
    """A file or folder a run reads, as sent to the workers.

    ``files`` maps paths relative to a fresh folder to their bytes; ``main`` is the path (in
    that folder) that stands for ``client_path``; ``digest`` names the content."""

    client_path: str
    main: str
    digest: str
    files: dict[str, bytes]


@dataclass(frozen=True)
class RemoteResult:
    """What a task sends back: the job's result or its error, and the run folder's files
    (relative path -> bytes; empty on error)."""

    result: dict[str, Any] | None
    error: str | None
    files: dict[str, bytes]


def _companions(path: Path) -> list[Path]:
    """Files read together with a map file: a Nav2 YAML's image, an image's YAML of the same stem."""
    suffix = path.suffix.lower()
    if suffix in (".yaml", ".yml"):
        from crlam.io.structured import load_yaml_text

        try:
            doc = load_yaml_text(path.read_text(), str(path))
        except (OSError, ValueError):
            return []
        image = doc.get("image") if isinstance(doc, dict) else None
        if isinstance(image, str) and not Path(image).is_absolute() and ".." not in Path(image).parts:
            return [p for p in [path.parent / image] if p.is_file()]
        return []
    if suffix in _MAP_IMAGE_SUFFIXES:
        return [p for p in (path.with_suffix(".yaml"), path.with_suffix(".yml")) if p.is_file()]
    return []


def input_files(client_path: str) -> InputFiles:
    """The files to send for an input path of a run: a file (with its map companions, see
    ``_companions``) or every file under a folder (a ROS 2 bag)."""
    path = Path(client_path)
    files: dict[str, bytes] = {}
    if path.is_dir():
        for f in sorted(path.rglob("*")):
            if f.is_file():
                files[(Path(path.name) / f.relative_to(path)).as_posix()] = f.read_bytes()
    else:
        files[path.name] = path.read_bytes()
        for c in _companions(path):
            files.setdefault(c.relative_to(path.parent).as_posix(), c.read_bytes())
    h = hashlib.sha256()
    for rel in sorted(files):
        h.update(rel.encode() + b"\0" + hashlib.sha256(files[rel]).digest())
    return InputFiles(client_path=client_path, main=path.name, digest=h.hexdigest()[:32], files=files)


def _materialise(root: Path, payload: InputFiles) -> Path:
    """The input's files in ``root/<digest>/`` (written once per worker; a rename makes the
    folder appear whole, so concurrent tasks of one worker never read a half-written copy)."""
    target = root / payload.digest
    if not target.is_dir():
        root.mkdir(parents=True, exist_ok=True)
        tmp = Path(tempfile.mkdtemp(dir=root, prefix=".incoming-"))
        for rel, data in payload.files.items():
            (tmp / rel).parent.mkdir(parents=True, exist_ok=True)
            (tmp / rel).write_bytes(data)
        try:
            os.rename(tmp, target)
        except OSError:  # another task of this worker got there first
            shutil.rmtree(tmp, ignore_errors=True)
    return target / payload.main


def _scratch_root() -> Path:
    """The worker's own scratch folder (Dask removes it with the worker), else the temp folder."""
    try:
        from distributed import get_worker

        return Path(get_worker().local_directory)
    except (ImportError, ValueError):
        return Path(tempfile.gettempdir())


def _task_released() -> Callable[[], bool]:
    """A test for "the client no longer wants this task" (it was cancelled or the client left),
    so that the run's process is stopped instead of running on for nobody."""
    try:
        from distributed import get_worker

        worker = get_worker()
        key = worker.get_current_task()
    except (ImportError, ValueError):
        return lambda: False

    def released() -> bool:
        ts = worker.state.tasks.get(key)
        return ts is None or ts.state in ("cancelled", "released", "forgotten")

    return released


def _child_env() -> dict[str, str]:
    """The worker's environment with its import path, so the child imports what the worker does
    (the job's function is pickled by reference)."""
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}


def _run_in_child(fn: Callable[..., dict[str, Any]], name: str, kwargs: dict[str, Any], threads: int, stage: Path) -> Any:
    job, out = stage / "job.pickle", stage / "result.pickle"
    job.write_bytes(pickle.dumps((fn, name, kwargs, threads, os.getpid())))
    code = "import sys; from crlam.experiments.remote_run import child_main; child_main(sys.argv[1], sys.argv[2])"
    proc = subprocess.Popen([sys.executable, "-c", code, str(job), str(out)], env=_child_env(), stdin=subprocess.DEVNULL)
    released = _task_released()
    try:
        while proc.poll() is None:
            if released():
                raise RunProcessDied(f"{name}: the client no longer waits for this run; its process was stopped")
            time.sleep(_POLL_S)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    if not out.is_file():
        raise RunProcessDied(_death_reason(proc.returncode))
    return pickle.loads(out.read_bytes())


def child_main(job_path: str, out_path: str) -> None:
    """Entry point of a run's process: runs the pickled job and pickles ``(result, error)``."""
    out = Path(out_path)
    try:
        fn, name, kwargs, threads, parent = pickle.loads(Path(job_path).read_bytes())
    except Exception as e:  # noqa: BLE001 - a job this interpreter cannot load is that job's error
        answer: tuple[Any, str | None] = (None, f"{type(e).__name__}: the run's process could not load the job: {e}")
    else:
        threading.Thread(target=_exit_with_parent, args=(parent, 1.0), daemon=True).start()
        _, result, err = _call(fn, name, kwargs, threads)
        answer = (result, err)
    tmp = out.with_name(out.name + ".tmp")
    tmp.write_bytes(pickle.dumps(answer))
    os.replace(tmp, out)


def _replacements(pairs: dict[str, str]) -> list[tuple[str, str]]:
    """(worker path, client path) pairs as they appear in plain and in JSON/TOML-escaped text,
    longest first (a scratch path never is a prefix of another's replacement)."""
    out = []
    for worker, client in pairs.items():
        out.append((worker, client))
        escaped = (json.dumps(worker)[1:-1], json.dumps(client)[1:-1])
        if escaped[0] != worker:
            out.append(escaped)
    return sorted(out, key=lambda p: -len(p[0]))


def _rewrite(value: Any, subs: list[tuple[str, str]]) -> Any:
    if isinstance(value, str):
        for a, b in subs:
            value = value.replace(a, b)
        return value
    if isinstance(value, dict):
        return {k: _rewrite(v, subs) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return type(value)(_rewrite(v, subs) for v in value)
    return value


def _folder_files(folder: Path, layout: RunLayout, keep_maps: bool, subs: list[tuple[str, str]]) -> Iterator[tuple[str, bytes]]:
    for f in sorted(folder.rglob("*")):
        if not f.is_file() or f.name.endswith(".tmp") or (f.name in layout.maps and not keep_maps):
            continue
        data = f.read_bytes()
        if f.suffix.lower() in TEXT_SUFFIXES:
            try:
                data = _rewrite(data.decode("utf-8"), subs).encode("utf-8")
            except UnicodeDecodeError:
                pass
        yield f.relative_to(folder).as_posix(), data


def run_remote(
    fn: Callable[..., dict[str, Any]],
    name: str,
    kwargs: dict[str, Any],
    threads: int,
    layout: RunLayout,
    keep_maps: bool,
    inputs: dict[str, InputFiles],
    client_version: str,
) -> RemoteResult:
    """One job on a worker (the Dask task): inputs from ``inputs`` (keyword -> files), the run in
    a child process writing to a scratch folder, its files and result sent back.

    Raises
    ------
    RunProcessDied
        When the child ended without a result; Dask then retries the task."""
    from crlam import __version__

    if __version__ != client_version:
        return RemoteResult(None, f"VersionMismatch: this worker has crlam {__version__}, the client {client_version}", {})
    root = _scratch_root()
    kw = dict(kwargs)
    paths: dict[str, str] = {}
    for key, payload in inputs.items():
        local = _materialise(root / "crlam-inputs", payload)
        kw[key] = str(local)
        paths[str(local)] = payload.client_path
    (root / "crlam-runs").mkdir(parents=True, exist_ok=True)
    stage = Path(tempfile.mkdtemp(dir=root / "crlam-runs", prefix="run-"))
    try:
        folder = stage / "run"
        paths[str(folder)] = str(kwargs[layout.folder])
        kw[layout.folder] = str(folder)
        result, err = _run_in_child(fn, name, kw, threads, stage)
        if err is not None:
            return RemoteResult(None, err, {})
        subs = _replacements(paths)
        files = dict(_folder_files(folder, layout, keep_maps, subs)) if folder.is_dir() else {}
        return RemoteResult(_rewrite(result, subs), None, files)
    finally:
        shutil.rmtree(stage, ignore_errors=True)
