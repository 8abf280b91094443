"""Interrupted writes: a command is killed (SIGKILL, no cleanup) at each of its write stages, and
the output folder is checked: the old folder is untouched or the new one complete, and anything
else left is clearly marked incomplete; the next run clears it.

The child counts every file it opens for writing under the staging folder and the two steps of
the final rename (audit events of :mod:`crlam.io.run_folder`), and kills itself at the k-th."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from crlam.io.run_folder import COMPLETE, INCOMPLETE

pytestmark = pytest.mark.skipif(sys.platform != "linux", reason="SIGKILL and audit hooks of a Linux child")

CHILD = r"""
import os, signal, sys
target = int(os.environ["CRLAM_TEST_KILL_AT"])
count = 0

def hook(event, args):
    global count
    stage = False
    if event == "open" and args and isinstance(args[0], (str, bytes, os.PathLike)):
        mode, flags = args[1], args[2]
        writing = (isinstance(mode, str) and any(c in mode for c in "wax+")) or (
            mode is None and isinstance(flags, int) and flags & (os.O_WRONLY | os.O_RDWR))
        stage = writing and ".incomplete" in os.fsdecode(args[0])
    elif event.startswith("crlam.run_folder.replace"):
        stage = True
    if stage:
        count += 1
        if count == target:
            os.kill(os.getpid(), signal.SIGKILL)

sys.addaudithook(hook)
from crlam.cli import main
status = main(sys.argv[1:])
print("STAGES", count)
sys.exit(status)
"""


def _run(argv: list[str], kill_at: int) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "CRLAM_TEST_KILL_AT": str(kill_at)}
    return subprocess.run([sys.executable, "-c", CHILD, *argv], env=env, capture_output=True, text=True, timeout=300)


def _digests(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def _log(path: Path, n: int = 5) -> Path:
    ranges = " ".join(["2.5"] * 180)
    path.write_text("".join(f"FLASER 180 {ranges} {0.1 * i} 0 0 {0.1 * i} 0 0 {i}.0 host {i}.0\n" for i in range(n)))
    return path


def _check_after_kill(parent: Path, name: str, old: dict[str, str] | None) -> str:
    """The state the killed run left: 'old' (untouched), 'new' (complete) or 'none'; asserts that
    whatever else is there is marked incomplete."""
    out = parent / name
    state = "none"
    if out.exists():
        if old is not None and _digests(out) == old:
            state = "old"
        else:
            assert (out / COMPLETE).is_file() and not (out / INCOMPLETE).exists(), sorted(_digests(out))
            assert json.loads((out / COMPLETE).read_text())["state"] == "complete"
            state = "new"
    for p in parent.iterdir():
        if p.name == name or name not in p.name:
            continue
        # A staging folder (named .incomplete: in progress, or the old run swapped out of the
        # way) or the old folder renamed aside (where the system cannot swap atomically).
        assert p.name == f"{name}.incomplete" or p.name.startswith(f".{name}.replaced-"), p.name
    return state


@pytest.mark.parametrize(
    "command",
    [
        ["map", "{log}", "--quiet"],
        ["slam", "{log}", "--quiet", "--particles", "2", "--preset", "paper"],
    ],
    ids=["map", "slam"],
)
def test_a_run_killed_at_any_write_stage_leaves_the_old_folder_or_the_new_one(tmp_path: Path, command: list[str]) -> None:
    log = _log(tmp_path / "a.log")
    argv = [a.format(log=log) for a in command]
    out = tmp_path / "run"
    first = _run([*argv, "--out", str(out)], 0)
    assert first.returncode == 0, first.stderr
    old = _digests(out)
    probe = _run([*argv, "--out", str(out), "--force"], 0)
    assert probe.returncode == 0, probe.stderr
    stages = int(probe.stdout.split("STAGES")[-1])
    assert stages >= 8
    old = _digests(out)
    seen = set()
    for k in range(1, stages + 1):
        killed = _run([*argv, "--out", str(out), "--force"], k)
        assert killed.returncode == -9, (k, killed.stderr[-2000:])
        state = _check_after_kill(tmp_path, "run", old)
        assert state in ("old", "new"), (k, state)
        seen.add(state)
        if state == "new":
            old = _digests(out)
    assert seen == {"old", "new"}, "the kill points cover both sides of the final rename"
    # The next run clears whatever the killed ones left.
    again = _run([*argv, "--out", str(out), "--force"], 0)
    assert again.returncode == 0, again.stderr
    assert sorted(p.name for p in tmp_path.iterdir() if "run" in p.name) == ["run"]


def test_a_fresh_run_killed_before_its_rename_leaves_no_output_folder(tmp_path: Path) -> None:
    log = _log(tmp_path / "a.log")
    out = tmp_path / "run"
    killed = _run(["map", str(log), "--quiet", "--out", str(out)], 3)
    assert killed.returncode == -9
    assert _check_after_kill(tmp_path, "run", None) == "none"
    assert (tmp_path / "run.incomplete" / INCOMPLETE).is_file()
    done = _run(["map", str(log), "--quiet", "--out", str(out)], 0)
    assert done.returncode == 0, done.stderr
    assert (out / COMPLETE).is_file() and not (tmp_path / "run.incomplete").exists()


def test_an_experiment_killed_mid_run_resumes_without_the_half_written_run(tmp_path: Path) -> None:
    import numpy as np

    from crlam.io.nav2 import write_pgm

    img = np.full((40, 40), 255, dtype=np.uint8)
    img[24:26, 0:20] = 0
    write_pgm(tmp_path / "room.pgm", img)
    args = ["--quiet", "--functions", "gpvr", "--runs", "2", "--start", "2", "2", "--workers", "1"]
    probe = _run(["experiment", "iig", "--map", str(tmp_path / "room.pgm"), "--out", str(tmp_path / "probe"), *args], 0)
    assert probe.returncode == 0, probe.stderr
    per_run = int(probe.stdout.split("STAGES")[-1]) // 2
    out = tmp_path / "exp"
    argv = ["experiment", "iig", "--map", str(tmp_path / "room.pgm"), "--out", str(out), *args]
    # Killed while the second run writes its tree: the first run is finished, the second is not.
    killed = _run(argv, per_run + 2)
    assert killed.returncode == -9
    runs = out / "runs"
    assert (runs / "gpvr-s00" / COMPLETE).is_file()
    assert not (runs / "gpvr-s01").exists() and (runs / "gpvr-s01.incomplete" / INCOMPLETE).is_file()
    assert (out / INCOMPLETE).is_file() and not (out / COMPLETE).exists()
    resumed = _run([*argv, "--resume"], 0)
    assert resumed.returncode == 0, resumed.stderr
    assert int(resumed.stdout.split("STAGES")[-1]) == per_run, "only the unfinished run is done again"
    assert (runs / "gpvr-s01" / COMPLETE).is_file() and not (runs / "gpvr-s01.incomplete").exists()
    assert (out / COMPLETE).is_file() and not (out / INCOMPLETE).exists()
