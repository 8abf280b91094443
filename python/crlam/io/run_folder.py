"""Output folders that never lie: written whole or not at all.

A command that writes a folder (``crlam map/slam/simulate/explore/info/...  --out DIR``) writes
into a staging folder beside it, ``DIR.incomplete``, which holds an ``INCOMPLETE`` file naming the
process that writes it. When every file is written, ``INCOMPLETE`` is removed, a ``COMPLETE`` file
is written last, and the staging folder is renamed to ``DIR`` (replacing an older ``DIR`` only
when asked to). So ``DIR`` is always a complete folder of one run: an interrupted run leaves the
old ``DIR`` untouched, and at most a ``DIR.incomplete`` folder, clearly marked, which the next run
into ``DIR`` clears. A Python exception (or Ctrl-C) removes the staging folder at once.

An output its writer creates itself (``crlam convert``'s bag folder or file) is written as
``DIR.incomplete/NAME`` and moved into place when complete.
"""

from __future__ import annotations

import ctypes
import json
import os
import shutil
import socket
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from crlam.errors import ConfigError

__all__ = [
    "COMPLETE",
    "INCOMPLETE",
    "check_output",
    "is_complete",
    "moved",
    "staged_file",
    "staged_folder",
    "staging_path",
]

COMPLETE = "COMPLETE"
INCOMPLETE = "INCOMPLETE"
_STAGING_SUFFIX = ".incomplete"


def staging_path(out: str | os.PathLike[str]) -> Path:
    """Where the output ``out`` is written until it is complete: ``NAME.incomplete`` beside it."""
    p = Path(out)
    return p.with_name(p.name + _STAGING_SUFFIX)


def is_complete(folder: str | os.PathLike[str]) -> bool:
    """True when ``folder`` holds the ``COMPLETE`` marker a staged run writes last."""
    return (Path(folder) / COMPLETE).is_file()


def _is_empty_dir(p: Path) -> bool:
    return p.is_dir() and not p.is_symlink() and not any(p.iterdir())


#: Files one of crlam's output folders holds at its top level (folders written before the
#: COMPLETE marker existed are recognised by these).
_CRLAM_FILES = (
    "mapping.json",
    "metrics.json",
    "config.toml",
    "simulation.json",
    "info.json",
    "summary.json",
    "experiment.json",
    "report.md",
    "results.json",
    "metadata.yaml",
)


def _refuse_to_replace(p: Path) -> str | None:
    """Why the existing output ``p`` must not be replaced by ``--force`` (None if it may be): a
    folder that holds the working directory, the home folder or the root, or one that is not an
    output of crlam, is never deleted by a flag."""
    if not p.is_dir() or p.is_symlink():
        return None
    resolved = p.resolve()
    for keep in (Path.cwd().resolve(), Path.home().resolve(), Path(resolved.anchor)):
        if resolved == keep or resolved in keep.parents:
            return f"it holds {keep}"
    if is_complete(p) or (p / INCOMPLETE).is_file() or any((p / name).is_file() for name in _CRLAM_FILES):
        return None
    return "it does not look like an output of crlam (no COMPLETE marker, no crlam summary file)"


def check_output(
    out: str | os.PathLike[str],
    *,
    force: bool = False,
    resume: bool = False,
    resumable: bool = False,
    what: str = "output folder",
) -> Path:
    """The up-front check of a command's output, made before any work: refuses an existing output
    (a file, or a folder that is not empty) unless ``force`` (it is replaced once the new output is
    complete) or ``resume`` (an existing folder is continued; for commands that are ``resumable``),
    and makes sure its parent folder can be created. Returns the output path.

    Raises
    ------
    ConfigError
        When the output exists and neither flag allows it, or its parent cannot hold it.
    """
    p = Path(out)
    if p.exists() or p.is_symlink():
        if resume and p.is_dir():
            return p
        if not (force or _is_empty_dir(p)):
            kind = "a file" if not p.is_dir() else ("a complete run folder" if is_complete(p) else "a folder")
            flags = "--resume to continue it or --force to replace it" if resumable else "--force to replace it"
            raise ConfigError(f"{what} {p} already exists ({kind}); use {flags}, or another --out")
        why = None if _is_empty_dir(p) else _refuse_to_replace(p)
        if why is not None:
            raise ConfigError(
                f"{what} {p} exists and --force will not replace it: {why}; remove it yourself or use another --out"
            )
    elif resume:
        raise ConfigError(f"--resume: {what} {p} does not exist")
    parent = p.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise ConfigError(f"cannot create the folder of {what} {p}: {e.strerror or e}") from e
    # A real write, not os.access: root passes every permission check on /sys or /proc.
    try:
        fd, probe = tempfile.mkstemp(dir=parent, prefix=f".{p.name}.", suffix=".probe")
        os.close(fd)
        os.unlink(probe)
    except OSError as e:
        raise ConfigError(f"cannot write {what} {p}: its folder {parent} refuses new files ({e.strerror or e})") from e
    return p


def moved(path: str | os.PathLike[str], stage: Path, final: Path) -> Path:
    """Where a file written under the staging folder ``stage`` is once it is renamed to ``final``."""
    p = Path(path)
    try:
        return final / p.relative_to(stage)
    except ValueError:
        return p


def _owner_alive(stage: Path) -> int | None:
    """The pid of a live process of this host still writing ``stage``, else None."""
    try:
        info = json.loads((stage / INCOMPLETE).read_text())
        pid, host = int(info["pid"]), str(info["host"])
    except (OSError, ValueError, KeyError, TypeError):
        return None
    if host != socket.gethostname() or pid == os.getpid():
        return None
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return None
    except PermissionError:
        return pid
    return pid


def _clear_stale(stage: Path) -> None:
    if not (stage.exists() or stage.is_symlink()):
        return
    pid = _owner_alive(stage) if stage.is_dir() else None
    if pid is not None:
        raise ConfigError(f"{stage} is being written by process {pid}; wait for it to end or stop it")
    if stage.is_dir() and not stage.is_symlink():
        shutil.rmtree(stage)
    else:
        stage.unlink()


def _remove(p: Path) -> None:
    if p.is_dir() and not p.is_symlink():
        shutil.rmtree(p, ignore_errors=True)
    else:
        p.unlink(missing_ok=True)


def _exchange(a: Path, b: Path) -> bool:
    """Swaps two paths in one atomic step (Linux ``renameat2(RENAME_EXCHANGE)``); False where the
    system cannot."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    if renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0:
        return True
    return False  # e.g. a file system without RENAME_EXCHANGE: the two renames below


def _move_into_place(stage: Path, out: Path, replace: bool) -> None:
    """Renames ``stage`` to ``out``. An existing ``out`` is swapped with ``stage`` atomically where
    the system can (then removed); elsewhere it is renamed aside first. The audit events
    ``crlam.run_folder.replace`` / ``.replaced`` mark the steps (the interrupted-write tests stop
    the process there)."""
    sys.audit("crlam.run_folder.replace", str(stage), str(out))
    if out.exists() or out.is_symlink():
        if not (replace or _is_empty_dir(out)):
            raise ConfigError(f"{out} appeared while this run was writing {stage}; the new output stays there")
        if out.is_dir() == stage.is_dir() and _exchange(stage, out):
            sys.audit("crlam.run_folder.replaced", str(stage), str(out))
            _remove(stage)  # now the old output
            return
        old = out.with_name(f".{out.name}.replaced-{os.getpid()}")
        _remove(old)
        os.rename(out, old)
        os.rename(stage, out)
        sys.audit("crlam.run_folder.replaced", str(old), str(out))
        _remove(old)
    else:
        os.rename(stage, out)
        sys.audit("crlam.run_folder.replaced", str(stage), str(out))


def _marker(command: str, state: str) -> str:
    from crlam import __version__

    return (
        json.dumps(
            {
                "state": state,
                "command": command,
                "pid": os.getpid(),
                "host": socket.gethostname(),
                "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
                "crlam": __version__,
            },
            indent=2,
        )
        + "\n"
    )


@contextmanager
def staged_folder(out: str | os.PathLike[str], *, replace: bool = True, command: str = "crlam") -> Iterator[Path]:
    """Yields the staging folder of ``out``; when the block ends normally the folder is marked
    ``COMPLETE`` (written last) and renamed to ``out``, replacing an existing ``out`` if
    ``replace``. When the block raises, the staging folder is removed and ``out`` is untouched.
    A stale staging folder of a process that is gone is cleared first; one of a live process is
    an error."""
    final = Path(out)
    stage = staging_path(final)
    _clear_stale(stage)
    final.parent.mkdir(parents=True, exist_ok=True)
    stage.mkdir()
    (stage / INCOMPLETE).write_text(_marker(command, "incomplete: being written, or the run was interrupted"))
    try:
        yield stage
        (stage / INCOMPLETE).unlink()
        tmp = stage / (COMPLETE + ".tmp")
        with open(tmp, "w") as fh:
            fh.write(_marker(command, "complete"))
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, stage / COMPLETE)
        _move_into_place(stage, final, replace)
    except BaseException:
        _remove(stage)
        raise


@contextmanager
def staged_file(out: str | os.PathLike[str], *, replace: bool = True) -> Iterator[Path]:
    """Like :func:`staged_folder` for an output its writer creates itself, a file or a folder
    (no markers inside): yields ``NAME.incomplete/NAME`` (not yet created; same name, so a writer
    choosing its format by suffix or naming files after it sees the final name), moved to ``out``
    when the block ends normally; the staging folder is removed when it raises."""
    final = Path(out)
    stage_dir = staging_path(final)
    _clear_stale(stage_dir)
    final.parent.mkdir(parents=True, exist_ok=True)
    stage_dir.mkdir()
    (stage_dir / INCOMPLETE).write_text(_marker("crlam", "incomplete: being written, or the run was interrupted"))
    stage = stage_dir / final.name
    try:
        yield stage
        if not (stage.exists() or stage.is_symlink()):
            raise ConfigError(f"nothing was written to {stage}")
        _move_into_place(stage, final, replace)
        _remove(stage_dir)
    except BaseException:
        _remove(stage_dir)
        raise
