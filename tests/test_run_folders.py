"""Run folders that never lie (issue 31, findings 2 and 3): outputs are staged and renamed into
place complete, existing outputs are refused unless --force (or --resume for experiments), a
failed or interrupted rerun leaves the old folder untouched, experiments refuse to resume with
other settings, and unreadable run files are redone."""

from __future__ import annotations

import hashlib
import json
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import main
from crlam.errors import ConfigError
from crlam.io.run_folder import COMPLETE, INCOMPLETE, check_output, staged_file, staged_folder, staging_path


def _log(path: Path, n: int = 4, *, bad_line_at: int | None = None) -> Path:
    ranges = " ".join(["2.5"] * 180)
    lines = [f"FLASER 180 {ranges} {0.1 * i} 0 0 {0.1 * i} 0 0 {i}.0 host {i}.0\n" for i in range(n)]
    if bad_line_at is not None:
        lines.insert(bad_line_at, "FLASER 180 1 2 3\n")
    path.write_text("".join(lines))
    return path


def _digests(folder: Path) -> dict[str, str]:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}


def _leftovers(parent: Path, name: str) -> list[str]:
    return sorted(p.name for p in parent.iterdir() if p.name != name and name in p.name)


# ------------------------------------------------------------------ the staging helpers


def test_a_staged_folder_appears_complete_or_not_at_all(tmp_path: Path) -> None:
    out = tmp_path / "run"
    with staged_folder(out, command="test") as stage:
        assert stage == staging_path(out) and (stage / INCOMPLETE).is_file() and not out.exists()
        (stage / "a.txt").write_text("a")
    assert sorted(p.name for p in out.iterdir()) == [COMPLETE, "a.txt"]
    assert json.loads((out / COMPLETE).read_text())["state"] == "complete"
    with pytest.raises(RuntimeError), staged_folder(out) as stage:
        (stage / "b.txt").write_text("b")
        raise RuntimeError("the run failed")
    assert sorted(p.name for p in out.iterdir()) == [COMPLETE, "a.txt"], "the old folder is untouched"
    assert _leftovers(tmp_path, "run") == [], "no staging folder is left"
    with staged_folder(out) as stage:
        (stage / "c.txt").write_text("c")
    assert sorted(p.name for p in out.iterdir()) == [COMPLETE, "c.txt"], "nothing of the earlier run survives"


def test_a_stale_staging_folder_is_cleared_but_a_live_one_is_not(tmp_path: Path) -> None:
    out = tmp_path / "run"
    stale = staging_path(out)
    stale.mkdir()
    (stale / INCOMPLETE).write_text(json.dumps({"pid": 2**22 + 12345, "host": "nowhere"}))
    with staged_folder(out) as stage:
        (stage / "x").write_text("x")
    assert (out / "x").is_file() and not stale.exists()
    import os
    import socket

    stale.mkdir()
    (stale / INCOMPLETE).write_text(json.dumps({"pid": os.getppid(), "host": socket.gethostname()}))
    with pytest.raises(ConfigError, match="being written by process"), staged_folder(out):
        pass


def test_outputs_are_checked_before_any_work(tmp_path: Path) -> None:
    (tmp_path / "file").write_text("x")
    (tmp_path / "empty").mkdir()
    full = tmp_path / "full"
    full.mkdir()
    (full / "metrics.json").write_text("{}")
    assert check_output(tmp_path / "new") == tmp_path / "new"
    assert check_output(tmp_path / "empty") == tmp_path / "empty"
    for p in (tmp_path / "file", full):
        with pytest.raises(ConfigError, match="--force"):
            check_output(p)
        assert check_output(p, force=True) == p
    with pytest.raises(ConfigError, match="--resume"):
        check_output(full, resumable=True)
    with pytest.raises(ConfigError):
        check_output(tmp_path / "file" / "sub")


def test_force_never_replaces_a_folder_that_is_not_a_crlam_output(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    mine = tmp_path / "documents"
    mine.mkdir()
    (mine / "thesis.tex").write_text("years of work")
    with pytest.raises(ConfigError, match="does not look like an output of crlam"):
        check_output(mine, force=True)
    monkeypatch.chdir(mine)
    for p in (Path("."), Path(".."), tmp_path, Path("/")):
        with pytest.raises(ConfigError, match="will not replace it"):
            check_output(p, force=True)
    (mine / "mapping.json").write_text("{}")  # a map folder made before the COMPLETE marker existed
    monkeypatch.chdir(tmp_path)
    assert check_output(tmp_path / "documents", force=True) == tmp_path / "documents"
    assert (mine / "thesis.tex").is_file(), "checking replaces nothing"


def test_a_staged_file_keeps_its_name_and_suffix(tmp_path: Path) -> None:
    out = tmp_path / "bag.mcap"
    with staged_file(out) as stage:
        assert stage.name == "bag.mcap" and stage.parent.name == "bag.mcap.incomplete"
        stage.write_text("data")
    assert out.read_text() == "data" and _leftovers(tmp_path, "bag.mcap") == []


# ------------------------------------------------------------------ the commands


def test_a_map_folder_is_refused_replaced_only_with_force_and_kept_when_a_rerun_fails(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    log = _log(tmp_path / "a.log")
    out = tmp_path / "map"
    assert main(["map", str(log), "--out", str(out), "--quiet"]) == 0
    assert (out / COMPLETE).is_file()
    (out / "stray.txt").write_text("a file of an earlier run")
    before = _digests(out)
    capsys.readouterr()
    # An existing folder is refused before any work.
    assert main(["map", str(log), "--out", str(out), "--quiet"]) == 2
    assert "already exists" in capsys.readouterr().err and _digests(out) == before
    # A rerun that fails (a malformed line after some scans) leaves the old folder as it was.
    bad = _log(tmp_path / "bad.log", 6, bad_line_at=4)
    assert main(["map", str(bad), "--out", str(out), "--quiet", "--force"]) == 2
    assert _digests(out) == before and _leftovers(tmp_path, "map") == []
    # --force replaces the whole folder: nothing of the earlier run survives.
    assert main(["map", str(log), "--out", str(out), "--quiet", "--force", "--resolution", "0.1"]) == 0
    assert "stray.txt" not in _digests(out)
    assert json.loads((out / "mapping.json").read_text())["config"]["resolution"] == 0.1


def test_a_map_into_a_slam_folder_does_not_leave_the_slam_metrics_beside_it(tmp_path: Path) -> None:
    log = _log(tmp_path / "a.log", 6)
    out = tmp_path / "run"
    assert main(["slam", str(log), "--out", str(out), "--quiet", "--particles", "3", "--preset", "paper"]) == 0
    assert (out / "metrics.json").is_file() and (out / "trajectory.tum").is_file()
    assert main(["map", str(log), "--out", str(out), "--quiet"]) == 2
    assert (out / "metrics.json").is_file()
    assert main(["map", str(log), "--out", str(out), "--quiet", "--force"]) == 0
    assert not (out / "metrics.json").exists() and not (out / "trajectory.tum").exists()
    assert (out / "mapping.json").is_file() and (out / COMPLETE).is_file()


def test_an_output_that_cannot_be_written_is_refused_before_the_run(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = _log(tmp_path / "a.log")
    (tmp_path / "file").write_text("x")
    assert main(["slam", str(log), "--out", str(tmp_path / "file" / "run"), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert "cannot" in err and "scans" not in err


# ------------------------------------------------------------------ experiments


def _room(path: Path) -> Path:
    from crlam.io.nav2 import write_pgm

    img = np.full((40, 40), 255, dtype=np.uint8)
    img[24:26, 0:20] = 0
    write_pgm(path, img)
    return path


def test_an_iig_experiment_refuses_another_map_and_redoes_corrupt_runs(tmp_path: Path) -> None:
    from crlam.experiments import iig as iig_mod
    from crlam.experiments.iig import run_iig_experiment

    room = _room(tmp_path / "room.pgm")
    other = _room(tmp_path / "other.pgm")
    img = other.read_bytes()
    other.write_bytes(img[:-5] + b"\x00" * 5)  # another map: a few pixels differ
    out = tmp_path / "exp"
    kw = {"functions": ["gpvr"], "runs": 2, "workers": 1, "progress": False, "start": (2.0, 2.0), "max_wall_seconds": 30.0}
    res = run_iig_experiment(room, out, **kw)
    assert len(res.rows) == 2 and (out / COMPLETE).is_file() and not (out / INCOMPLETE).exists()
    with pytest.raises(ConfigError, match="already exists"):
        run_iig_experiment(room, out, **kw, resume=False)
    with pytest.raises(ConfigError, match="map_sha256"):
        run_iig_experiment(other, out, **kw)
    with pytest.raises(ConfigError, match="particles"):
        run_iig_experiment(room, out, **{**kw, "functions": ["ucrmi"]}, particles=7)
    # Corrupt run files are done again, not a traceback.
    (out / "runs" / "gpvr-s00" / "result.json").write_text("{not json")
    (out / "runs" / "gpvr-s01" / "tree.npz").write_bytes(b"garbage")
    calls: list[str] = []
    real = iig_mod.run_one

    def counting(**kwargs: object) -> dict[str, object]:
        calls.append(Path(str(kwargs["folder"])).name)
        return real(**kwargs)  # type: ignore[arg-type]

    iig_mod.run_one = counting  # type: ignore[assignment]
    try:
        again = run_iig_experiment(room, out, **kw)
    finally:
        iig_mod.run_one = real
    assert sorted(calls) == ["gpvr-s00", "gpvr-s01"] and len(again.rows) == 2
    # --force starts anew whatever the folder holds.
    (out / "stray").write_text("x")
    run_iig_experiment(other, out, **kw, force=True)
    assert not (out / "stray").exists()
    assert json.loads((out / "experiment.json").read_text())["settings"]["map_sha256"] != "x"


def test_the_experiment_command_needs_resume_or_force_for_an_existing_folder(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    room = _room(tmp_path / "room.pgm")
    out = tmp_path / "exp"
    base = ["experiment", "iig", "--map", str(room), "--out", str(out), "--quiet", "--functions", "gpvr", "--runs", "1"]
    base += ["--start", "2", "2", "--workers", "1"]
    assert main(base) == 0
    capsys.readouterr()
    assert main(base) == 2
    assert "--resume" in capsys.readouterr().err
    assert main([*base, "--resume"]) == 0
    assert main([*base, "--resume", "--max-seconds", "5"]) == 2
    assert "max_wall_seconds" in capsys.readouterr().err
    assert main([*base, "--force", "--max-seconds", "5"]) == 0


def test_an_explore_experiment_refuses_another_budget(tmp_path: Path) -> None:
    from crlam.experiments.explore_sweep import run_explore_experiment
    from crlam.io.nav2 import write_nav2_map
    from crlam.sim.world import World

    occ = np.zeros((60, 60), dtype=bool)
    occ[0, :] = occ[-1, :] = occ[:, 0] = occ[:, -1] = True
    room = World(occ, 0.1, name="room")
    write_nav2_map(tmp_path / "room.pgm", room.occupied.astype(float), resolution=0.1, origin=(0.0, 0.0, 0.0))
    out = tmp_path / "sweep"
    kw = {"worlds": [str(tmp_path / "room.yaml")], "functions": ["frontier"], "runs": 1, "budget": 3.0, "workers": 1}
    res = run_explore_experiment(out, **kw, progress=False)
    assert len(res.rows) == 1
    with pytest.raises(ConfigError, match="budget: stored 3.0, requested 4.0"):
        run_explore_experiment(out, **{**kw, "budget": 4.0}, progress=False)
    # A world file of the same name but other content is another input.
    occ2 = occ.copy()
    occ2[30, 10:20] = True
    write_nav2_map(tmp_path / "room.pgm", occ2.astype(float), resolution=0.1, origin=(0.0, 0.0, 0.0))
    with pytest.raises(ConfigError, match="world:room"):
        run_explore_experiment(out, **kw, progress=False)


def test_a_sweep_redoes_a_run_whose_metrics_are_corrupt(tmp_path: Path) -> None:
    from crlam.experiments.sweep import RunSpec, run_is_finished, run_sweep
    from crlam.slam import SlamConfig

    log = _log(tmp_path / "a.log", 5)
    spec = RunSpec("r0", str(log), SlamConfig.from_preset("paper", particles=2))
    done, errors = run_sweep([spec], tmp_path / "sweep", progress=False)
    folder = spec.folder(tmp_path / "sweep")
    assert not errors and run_is_finished(folder) and (folder / COMPLETE).is_file()
    (folder / "metrics.json").write_text('{"truncated": ')
    assert not run_is_finished(folder)
    done, errors = run_sweep([spec], tmp_path / "sweep", progress=False)
    assert not errors and run_is_finished(folder) and "n_scans" in done["r0"]
    (folder / "trajectory.tum").write_text("1.0 nonsense\n")
    assert not run_is_finished(folder)
