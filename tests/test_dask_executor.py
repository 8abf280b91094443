"""The Dask executor (``--executor dask``) on a LocalCluster of 2 workers: same results as the
local executor, killed workers cost only their run, interrupted sweeps resume (tiny sizes)."""

from __future__ import annotations

import json
import logging
import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

distributed = pytest.importorskip("distributed")

from crlam.errors import ConfigError  # noqa: E402
from crlam.experiments.dask_executor import DaskExecutor  # noqa: E402
from crlam.experiments.executor import RunLayout  # noqa: E402
from crlam.experiments.pool import run_jobs  # noqa: E402
from crlam.experiments.remote_run import input_files  # noqa: E402

#: Metrics that measure the machine, not the run.
TIMING = ("wall_time_s", "scans_per_s", "peak_rss_mb", "filter_peak_rss_mb", "command_peak_rss_mb")


@pytest.fixture(scope="module")
def cluster() -> Iterator[Any]:
    """Two single-threaded worker processes; a worker whose run dies is retried twice."""
    import dask

    with dask.config.set({"distributed.scheduler.allowed-failures": 2}):
        with distributed.LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=logging.ERROR
        ) as c:
            yield c


def _same_runs(local: Path, remote: Path, names: list[str]) -> None:
    """Both sweeps' run folders hold the same numbers, bit for bit (timings aside), and the paths
    in the remote one are the client's."""
    for name in names:
        a, b = local / "runs" / name, remote / "runs" / name
        tables = [f for f in sorted(a.rglob("*")) if f.suffix in (".tum", ".csv")]
        assert len(tables) >= 2
        for f in tables:
            rel = f.relative_to(a)
            assert (b / rel).read_bytes() == f.read_bytes(), f"{name}/{rel}"
        ma, mb = (json.loads((d / "metrics.json").read_text()) for d in (a, b))
        for m in (ma, mb):
            for k in TIMING:
                m.pop(k)
        assert json.loads(json.dumps(ma).replace(str(local), str(remote))) == mb
        assert (b / "config.toml").read_text() == (a / "config.toml").read_text().replace(str(local), str(remote))


def test_table1_on_dask_gives_the_local_results(tmp_path: Path) -> None:
    """Without a scheduler address the executor starts (and stops) a LocalCluster of its own."""
    from crlam.experiments.table1 import run_table1

    kw: dict[str, Any] = {"runs": 1, "scans": 40, "particles": 3, "methods": ("ogm", "clam"), "progress": False}
    local = run_table1(tmp_path / "local", workers=2, **kw)
    remote = run_table1(tmp_path / "dask", executor=DaskExecutor(workers=2), **kw)
    assert not local["errors"] and not remote["errors"]
    for m in ("ogm", "clam"):
        assert remote["rows"][m]["metrics"] == local["rows"][m]["metrics"]
        assert remote["rows"][m]["n_runs"] == 1
    _same_runs(tmp_path / "local", tmp_path / "dask", ["ogm_run00", "clam_run00"])
    run = tmp_path / "dask" / "runs" / "clam_run00"
    assert json.loads((run / "metrics.json").read_text())["log"] == str(tmp_path / "dask" / "simulation" / "log.clf")
    # The map is sent back only when asked for.
    assert (tmp_path / "local" / "runs" / "clam_run00" / "belief.npz").is_file()
    assert not (run / "belief.npz").exists() and not list(run.glob("*.tmp"))


@pytest.mark.realdata
def test_real_logs_on_dask_give_the_local_results(data_dir: Path, tmp_path: Path, cluster: Any) -> None:
    from crlam.experiments.real_logs import run_real_logs

    kw: dict[str, Any] = {
        "datasets": ("aces",),
        "methods": ("clam",),
        "particles": (3,),
        "seeds": 2,
        "ranges": ("8",),
        "max_scans": 200,
        "progress": False,
    }
    local = run_real_logs(tmp_path / "local", workers=2, **kw)
    remote = run_real_logs(tmp_path / "dask", executor=DaskExecutor(cluster.scheduler_address, keep_maps=True), **kw)
    assert not local["errors"] and not remote["errors"] and len(remote["rows"]) == 1
    for k, v in local["rows"][0].items():
        if k not in ("wall_time_s", "peak_rss_mb"):
            assert remote["rows"][0][k] == v or (v != v and remote["rows"][0][k] != remote["rows"][0][k]), k
    names = ["aces_clam_3p_8m_seed0", "aces_clam_3p_8m_seed1"]
    _same_runs(tmp_path / "local", tmp_path / "dask", names)
    # --keep-maps: the map came back, the same map.
    with (
        np.load(tmp_path / "local" / "runs" / names[0] / "belief.npz") as a,
        np.load(tmp_path / "dask" / "runs" / names[0] / "belief.npz") as b,
    ):
        assert sorted(a.files) == sorted(b.files) and all(np.array_equal(a[k], b[k]) for k in a.files)


@pytest.mark.filterwarnings("ignore:No artists with labels")  # one variant: the figures have no legend
def test_explore_on_dask_ships_a_map_world_with_its_image(tmp_path: Path, cluster: Any) -> None:
    from crlam.experiments.explore_sweep import run_explore_experiment
    from crlam.io.nav2 import write_nav2_map

    occupied = np.zeros((60, 60), dtype=bool)
    occupied[[0, -1], :] = occupied[:, [0, -1]] = True
    write_nav2_map(tmp_path / "room.pgm", occupied.astype(float), resolution=0.05, origin=(0.0, 0.0, 0.0))
    kw: dict[str, Any] = {"worlds": [str(tmp_path / "room.yaml")], "functions": ["frontier"], "runs": 1, "budget": 4.0}
    local = run_explore_experiment(tmp_path / "local", workers=1, progress=False, **kw)
    remote = run_explore_experiment(tmp_path / "dask", executor=DaskExecutor(cluster.scheduler_address), progress=False, **kw)
    assert not local.errors and not remote.errors
    drop = ("decision_ms_mean", "name")
    assert [{k: v for k, v in r.items() if k not in drop} for r in remote.rows] == [
        {k: v for k, v in r.items() if k not in drop} for r in local.rows
    ]
    assert remote.rows[0]["world"] == str(tmp_path / "room.yaml")
    assert (tmp_path / "dask" / "runs" / "room-frontier-s00" / "progress.csv").is_file()


def _gated(value: int, folder: str, started: str, gate: str) -> dict[str, int]:
    """Notes its start (with the pid of the worker that runs it), waits until the test creates
    ``gate``, writes its marker: the test decides when a run may end, not the clock."""
    Path(started).mkdir(parents=True, exist_ok=True)
    (Path(started) / f"{value}-{os.getpid()}-{os.getppid()}").write_text("")
    while not Path(gate).exists():
        time.sleep(0.02)
    Path(folder).mkdir(parents=True, exist_ok=True)
    (Path(folder) / "metrics.json").write_text(json.dumps({"value": value}))
    return {"value": value}


def _wait_for(condition: Any, what: str, hang_guard_s: float = 600.0) -> None:
    """Polls until ``condition()`` holds. The limit only stops a hung test (it fails it, saying
    what never happened); no outcome depends on how fast the machine is."""
    give_up = time.monotonic() + hang_guard_s
    while not condition():
        assert time.monotonic() < give_up, f"hung: {what} did not happen within {hang_guard_s:.0f} s"
        time.sleep(0.02)


def test_a_worker_killed_mid_sweep_costs_only_its_run(tmp_path: Path, cluster: Any) -> None:
    """Every run waits for the gate file, so the first run to start is still running when its
    worker is killed, whatever the machine's speed."""
    root, started, gate = tmp_path / "sweep", tmp_path / "started", tmp_path / "gate"
    jobs = [
        (f"j{i}", {"value": i, "folder": str(root / "runs" / f"j{i}"), "started": str(started), "gate": str(gate)})
        for i in range(3)
    ]
    answer: dict[str, Any] = {}

    def sweep() -> None:
        answer["out"] = run_jobs(
            jobs,
            _gated,
            lambda n: (root / "runs" / n / "metrics.json").is_file(),
            lambda n: json.loads((root / "runs" / n / "metrics.json").read_text()),
            executor=DaskExecutor(cluster.scheduler_address),
            layout=RunLayout(),
            progress=False,
        )

    t = threading.Thread(target=sweep)
    t.start()
    _wait_for(lambda: started.is_dir() and any(started.iterdir()), "the first run's start")
    value, _, worker = (int(x) for x in next(started.iterdir()).name.split("-"))
    os.kill(worker, signal.SIGKILL)  # the worker process dies mid-run (its run waits for the gate)
    gate.touch()
    _wait_for(lambda: not t.is_alive(), "the end of the sweep")
    done, errors = answer["out"]
    assert not errors and done == {f"j{i}": {"value": i} for i in range(3)}
    starts = [p.name.split("-")[0] for p in started.iterdir()]
    assert starts.count(str(value)) == 2 and len(starts) == 4, starts  # only the killed run ran again
    for i in range(3):
        assert json.loads((root / "runs" / f"j{i}" / "metrics.json").read_text()) == {"value": i}


def _fails(value: int, folder: str) -> dict[str, int]:
    if value == 1:
        raise ValueError("bad input in run 1")
    if value == 2:
        os.kill(os.getpid(), signal.SIGKILL)  # what the OOM killer does
    Path(folder).mkdir(parents=True, exist_ok=True)
    (Path(folder) / "metrics.json").write_text("{}")
    return {"value": value}


def test_failed_runs_are_recorded_with_their_error(tmp_path: Path, cluster: Any) -> None:
    jobs = [(f"j{i}", {"value": i, "folder": str(tmp_path / f"j{i}")}) for i in range(3)]
    done, errors = run_jobs(
        jobs,
        _fails,
        lambda n: False,
        lambda n: {},
        executor=DaskExecutor(cluster.scheduler_address, retries=1),
        layout=RunLayout(),
        progress=False,
    )
    assert done == {"j0": {"value": 0}}
    assert errors["j1"].startswith("ValueError: bad input in run 1")
    # The run's own process was killed on every attempt: retried, then recorded, the worker unharmed.
    assert "RunProcessDied" in errors["j2"] and "SIGKILL" in errors["j2"]
    assert not (tmp_path / "j1").exists() and not (tmp_path / "j2").exists()


def _hold_runs_but(first: str, gate: str) -> None:
    """In a worker process: every run but ``first`` waits for the file ``gate`` before its
    process starts (the runs' module looks the function up at call time)."""
    from crlam.experiments import remote_run

    original = getattr(remote_run, "_ungated_run_in_child", remote_run._run_in_child)

    def gated(fn: Any, name: str, kwargs: dict[str, Any], threads: int, stage: Path) -> Any:
        while name != first and not Path(gate).exists():
            time.sleep(0.02)
        return original(fn, name, kwargs, threads, stage)

    remote_run._ungated_run_in_child = original  # type: ignore[attr-defined]
    remote_run._run_in_child = gated


def _release_runs() -> None:
    from crlam.experiments import remote_run

    if hasattr(remote_run, "_ungated_run_in_child"):
        remote_run._run_in_child = remote_run._ungated_run_in_child
        del remote_run._ungated_run_in_child


def test_an_interrupted_sweep_resumes(tmp_path: Path, cluster: Any) -> None:
    """The client is interrupted (Ctrl-C) after its first finished run, while the other runs are
    held on the workers until the test lets them go (no race with the clock); the same command
    with --resume then runs only the runs that were not finished."""
    out, gate = tmp_path / "t1", tmp_path / "gate"
    argv = ["experiment", "table1", "--out", str(out), "--runs", "4", "--scans", "40", "--particles", "3", "--methods", "clam"]
    argv += ["--executor", "dask", "--scheduler", cluster.scheduler_address, "--quiet"]
    with distributed.Client(cluster) as control:
        control.run(_hold_runs_but, "clam_run00", str(gate))
        try:
            env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
            # SIGINT at its default in the client: a shell running pytest in the background (no job
            # control) starts it ignored, and Python then installs no KeyboardInterrupt handler.
            client = subprocess.Popen(
                [sys.executable, "-m", "crlam.cli", *argv],
                env=env,
                stderr=subprocess.PIPE,
                text=True,
                preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
            )
            _wait_for(lambda: (out / "runs" / "clam_run00" / "COMPLETE").exists() or client.poll() is not None, "run 0")
            assert client.poll() is None, "the sweep ended while three of its runs were held"
            client.send_signal(signal.SIGINT)
            _, err = client.communicate(timeout=600)  # a hang guard only
            assert client.returncode == 130 and "interrupted" in err, err
        finally:
            gate.touch()  # the held runs of the interrupted client go on and are dropped
            control.run(_release_runs)
    finished = {p.parent.name: p.stat().st_mtime_ns for p in out.glob("runs/*/COMPLETE")}
    assert set(finished) == {"clam_run00"}
    from crlam.cli import main

    assert main(argv) == 2  # an existing experiment folder is continued only when asked to
    assert main([*argv, "--resume"]) == 0
    assert {p.parent.name for p in out.glob("runs/*/COMPLETE")} == {f"clam_run{k:02d}" for k in range(4)}
    assert {n: (out / "runs" / n / "COMPLETE").stat().st_mtime_ns for n in finished} == finished
    assert "| RBPF-CLAM | 4 |" in (out / "table.md").read_text()


def test_input_files_of_a_map_and_of_a_bag_folder(tmp_path: Path) -> None:
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    (tmp_path / "m.pgm").write_bytes(b"P5 1 1 255\n\x00")
    (tmp_path / "other.pgm").write_bytes(b"x")
    assert sorted(input_files(str(tmp_path / "m.yaml")).files) == ["m.pgm", "m.yaml"]
    assert sorted(input_files(str(tmp_path / "m.pgm")).files) == ["m.pgm", "m.yaml"]
    bag = tmp_path / "bag"
    (bag / "sub").mkdir(parents=True)
    (bag / "metadata.yaml").write_text("x")
    (bag / "sub" / "bag_0.db3").write_bytes(b"db")
    shipped = input_files(str(bag))
    assert shipped.main == "bag" and sorted(shipped.files) == ["bag/metadata.yaml", "bag/sub/bag_0.db3"]
    # The same content, the same name on the workers; other content, another.
    assert input_files(str(bag)).digest == shipped.digest
    (bag / "metadata.yaml").write_text("y")
    assert input_files(str(bag)).digest != shipped.digest


def test_executor_options_are_checked(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    from crlam.cli import main

    argv = ["experiment", "table1", "--out", str(tmp_path), "--runs", "1", "--scans", "5", "--quiet"]
    assert main([*argv, "--scheduler", "tcp://127.0.0.1:1"]) == 2  # --scheduler needs --executor dask
    assert main([*argv, "--keep-maps"]) == 2
    assert not (tmp_path / "runs").exists()
    monkeypatch.setitem(sys.modules, "distributed", None)  # Dask not installed
    with pytest.raises(ConfigError, match="crlam\\[cluster\\]"):
        DaskExecutor().run(
            [("a", {"folder": str(tmp_path)})], dict, threads=1, fresh_process=True, layout=RunLayout(), collect=print
        )
