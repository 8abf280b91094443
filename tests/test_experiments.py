"""Experiment harness: resumable sweeps in spawn workers, tables and figures (tiny sizes)."""

from __future__ import annotations

import json
import math
import multiprocessing
import os
import signal
import time
from pathlib import Path

try:
    import tomllib
except ModuleNotFoundError:  # Python 3.10
    import tomli as tomllib

import pytest

from crlam.errors import ConfigError
from crlam.experiments.slam_run import write_toml
from crlam.experiments.sweep import RunSpec, run_is_finished, run_sweep, stored_setting_differences
from crlam.experiments.table1 import run_table1
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig


@pytest.fixture(scope="module")
def office_log(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("office")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=40, seed=2)), d)
    return d


def _specs(log: Path) -> list[RunSpec]:
    ref = str(log / "groundtruth.tum")
    cfg = [SlamConfig(particles=4, seed=k, weight_stride=4) for k in range(3)]
    return [RunSpec(f"clam_s{k}", str(log / "log.clf"), c, reference=ref) for k, c in enumerate(cfg)]


def test_sweep_resumes_and_only_redoes_unfinished_runs(office_log: Path, tmp_path: Path) -> None:
    specs = _specs(office_log)
    done, errors = run_sweep(specs, tmp_path, workers=2, progress=False)
    assert not errors and set(done) == {s.name for s in specs}
    for s in specs:
        assert run_is_finished(s.folder(tmp_path))
        assert (s.folder(tmp_path) / "trajectory.tum").is_file() and (s.folder(tmp_path) / "config.toml").is_file()
    stamp = {s.name: (s.folder(tmp_path) / "metrics.json").stat().st_mtime_ns for s in specs}
    # A "killed" sweep: one run lost its completion marker; only that one is redone.
    (specs[1].folder(tmp_path) / "metrics.json").unlink()
    done2, _ = run_sweep(specs, tmp_path, workers=1, progress=False)
    assert set(done2) == set(done)
    assert (specs[0].folder(tmp_path) / "metrics.json").stat().st_mtime_ns == stamp[specs[0].name]
    assert (specs[1].folder(tmp_path) / "metrics.json").stat().st_mtime_ns != stamp[specs[1].name]
    # Same seed, same trajectory (the redone run reproduces the first one).
    m1, m2 = done[specs[1].name], done2[specs[1].name]
    assert m1["reference"] == m2["reference"]


def test_a_failing_run_is_reported_and_the_sweep_goes_on(office_log: Path, tmp_path: Path) -> None:
    specs = [*_specs(office_log)[:1], RunSpec("broken", str(tmp_path / "missing.clf"), SlamConfig(particles=2))]
    done, errors = run_sweep(specs, tmp_path, workers=1, progress=False)
    assert set(done) == {specs[0].name} and "broken" in errors


def _fake_finished_run(folder: Path, slam: dict[str, object], max_scans: int | None = None) -> None:
    folder.mkdir(parents=True)
    write_toml(folder / "config.toml", {"run": {"log": "x.clf", "max_scans": max_scans}, "slam": slam})
    (folder / "metrics.json").write_text(json.dumps({"wall_time_s": 1.0}))


def test_a_finished_run_with_other_settings_stops_the_sweep(tmp_path: Path) -> None:
    asked = SlamConfig(particles=30, tempering=90.0, motion="thrun", motion_params=(0.1, 0.1, 0.2, 0.05))
    spec = RunSpec("run", "x.clf", asked)
    _fake_finished_run(spec.folder(tmp_path), asked.to_dict())
    assert stored_setting_differences(spec, spec.folder(tmp_path)) == []
    done, _ = run_sweep([spec], tmp_path, report_only=True, progress=False)
    assert set(done) == {"run"}

    other = RunSpec("run", "x.clf", SlamConfig(particles=30, tempering=1.0, motion="thrun", motion_params=(0.1, 0.1, 0.2, 0.05)))
    assert stored_setting_differences(other, other.folder(tmp_path)) == ["tempering: stored 90.0, requested 1.0"]
    for report_only in (True, False):
        with pytest.raises(ConfigError, match="tempering: stored 90.0, requested 1.0"):
            run_sweep([other], tmp_path, report_only=report_only, progress=False)
    shorter = RunSpec("run", "x.clf", asked, max_scans=100)
    assert stored_setting_differences(shorter, shorter.folder(tmp_path)) == ["max_scans: stored None, requested 100"]


def test_unset_and_missing_settings_of_a_stored_run(tmp_path: Path) -> None:
    # None is stored as an "(unset)" comment: it differs from a value.
    spec = RunSpec("a", "x.clf", SlamConfig(motion="thrun", motion_params=(0.1, 0.1, 0.2, 0.05)))
    _fake_finished_run(spec.folder(tmp_path), SlamConfig(motion="thrun").to_dict())
    assert stored_setting_differences(spec, spec.folder(tmp_path)) == [
        "motion_params: stored None, requested [0.1, 0.1, 0.2, 0.05]"
    ]
    # A setting the file does not name did not exist yet: the run had the default behaviour.
    old = {k: v for k, v in SlamConfig().to_dict().items() if k != "cause_kernel"}
    for name, kernel, expected in (("b", "midpoint", []), ("c", "chord", ["cause_kernel: stored 'midpoint', requested 'chord'"])):
        s = RunSpec(name, "x.clf", SlamConfig(cause_kernel=kernel))
        _fake_finished_run(s.folder(tmp_path), old)
        assert stored_setting_differences(s, s.folder(tmp_path)) == expected


@pytest.mark.slow
def test_table1_protocol_small(tmp_path: Path) -> None:
    res = run_table1(tmp_path, runs=2, scans=40, particles=3, methods=("clam",), workers=1, progress=False)
    assert res["rows"]["clam"]["n_runs"] == 2
    table = (tmp_path / "table.md").read_text()
    assert "RBPF-CLAM" in table and "±" in table
    # Every run records the other trajectories; the table lists each over both runs.
    others = res["rows"]["clam"]["other_estimates"]
    assert set(others) == {"reference_best_path", "reference_max_weight", "reference_mode", "reference_smoothed"}
    assert all(o["n_runs"] == 2 for o in others.values())
    assert "| RBPF-CLAM | lineage smoother | 2 |" in table
    for f in ("fig2_trajectories.png", "fig2_errors.png", "errors_all_runs.png", "table.csv", "results.json"):
        assert (tmp_path / f).stat().st_size > 0
    again = run_table1(tmp_path, runs=2, scans=40, particles=3, methods=("clam",), workers=1, progress=False)
    assert json.dumps(again["rows"], sort_keys=True) == json.dumps(res["rows"], sort_keys=True)
    # Finished runs kept without their maps (as committed results are) still resume.
    (tmp_path / "runs" / "clam_run00" / "belief.npz").unlink()
    kept = run_table1(tmp_path, runs=2, scans=40, particles=3, methods=("clam",), workers=1, progress=False)
    assert json.dumps(kept["rows"], sort_keys=True) == json.dumps(res["rows"], sort_keys=True)
    assert (tmp_path / "fig2_trajectories.png").stat().st_size > 0
    # An interim report of a longer protocol runs nothing and covers the finished runs only.
    (tmp_path / "table.md").unlink()
    interim = run_table1(tmp_path, runs=5, scans=40, particles=3, methods=("clam",), workers=1, progress=False, report_only=True)
    assert interim["rows"]["clam"]["runs"] == ["clam_run00", "clam_run01"] and interim["rows"]["clam"]["n_runs"] == 2
    assert not (tmp_path / "runs" / "clam_run02").exists() and (tmp_path / "table.md").is_file()


@pytest.mark.realdata
@pytest.mark.slow
def test_real_logs_harness_on_a_slice_of_aces(data_dir: Path, tmp_path: Path) -> None:
    from crlam.experiments.real_logs import run_real_logs

    res = run_real_logs(
        tmp_path,
        datasets=("aces",),
        methods=("clam", "ogm"),
        particles=(3,),
        seeds=1,
        ranges=("8",),
        # The paper's proposal on the sweep's former default grid and odometry model (the default is
        # now the robust preset: tests/test_presets.py).
        base=SlamConfig.from_preset("paper", resolution=0.1, motion="thrun"),
        workers=1,
        max_scans=300,
        progress=False,
    )
    assert not res["errors"], res["errors"]
    assert {(r["method"], r["particles"]) for r in res["rows"]} == {("clam", 3), ("ogm", 3)}
    assert all(math.isfinite(r["trans_best_path_m"]) for r in res["rows"])
    # RBPF-OGM draws from its improved proposal and records the means; RBPF-CLAM's odometry proposal does not.
    means = {r["method"]: r["trans_best_path_means_m"] for r in res["rows"]}
    assert math.isfinite(means["ogm"]) and math.isnan(means["clam"])
    table = (tmp_path / "table.md").read_text()
    assert "RBPF-CLAM" in table and "RBPF-OGM" in table and "Cartographer" in table


@pytest.mark.realdata
def test_real_logs_command_passes_the_update_triggers_to_every_run(
    data_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from crlam.cli import main

    argv = ["experiment", "real-logs", "--out", str(tmp_path), "--datasets", "aces", "--methods", "ogm"]
    argv += ["--particles", "2", "--runs", "1", "--ranges", "8", "--max-scans", "200", "--workers", "1"]
    argv += ["--motion", "thrun", "--motion-params", "0.1", "0.1", "0.002", "0.1"]
    assert main([*argv, "--linear-update", "1.0", "--angular-update", "0.5", "--quiet"]) == 0
    (run,) = (tmp_path / "runs").iterdir()
    metrics = json.loads((run / "metrics.json").read_text())
    slam = tomllib.loads((run / "config.toml").read_text())["slam"]
    assert slam["linear_update"] == 1.0 and slam["angular_update"] == 0.5
    assert slam["motion"] == "thrun" and slam["motion_params"] == [0.1, 0.1, 0.002, 0.1]
    assert 0 < metrics["n_processed"] < metrics["n_scans"] == 200
    # --report-only with one more seed: the table has the finished run, nothing new is run.
    argv[argv.index("--runs") + 1] = "2"
    assert main([*argv, "--linear-update", "1.0", "--angular-update", "0.5", "--quiet", "--report-only"]) == 0
    assert [p.name for p in (tmp_path / "runs").iterdir()] == [run.name]
    assert "RBPF-OGM" in (tmp_path / "table.md").read_text()
    # A baseline-only sweep may keep GMapping's match; the finished run was made with the draw,
    # so resuming it with another pose rule is refused before anything runs.
    triggers = ["--linear-update", "1.0", "--angular-update", "0.5", "--quiet", "--report-only"]
    assert main([*argv, *triggers, "--proposal-pose", "match"]) == 2
    assert "proposal_pose: stored 'sample', requested 'match'" in capsys.readouterr().err
    # ... and so is resuming it with another odometry model.
    other = [*argv[: argv.index("--motion-params")], "--motion-params", "0.1", "0.1", "0.1", "0.1"]
    assert main([*other, *triggers]) == 2
    assert "motion_params" in capsys.readouterr().err
    # With RBPF-CLAM runs in the sweep, 'match' needs the likelihood-mode proposal (the robust preset's,
    # so the paper's odometry proposal is asked for here).
    clam = [*argv[: argv.index("--methods")], "--methods", "ogm", "clam", *argv[argv.index("--methods") + 2 :]]
    assert main([*clam, *triggers, "--proposal", "odometry", "--proposal-pose", "match"]) == 2
    assert "proposal='likelihood_mode'" in capsys.readouterr().err


def _child_peak_rss(_: int) -> float:
    from crlam.experiments.slam_run import peak_rss_mb

    return peak_rss_mb()


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs Linux /proc")
def test_peak_rss_of_a_spawned_worker_is_its_own_not_its_parents() -> None:

    from crlam.experiments.slam_run import peak_rss_mb

    ballast = bytearray(300 * 1024 * 1024)
    ballast[::4096] = b"\x01" * len(ballast[::4096])  # touch every page
    assert peak_rss_mb() > 300
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        child = pool.map(_child_peak_rss, [0])[0]
    assert 0 < child < 200, child
    del ballast


def test_fresh_process_jobs_run_in_spawned_workers_and_all_finish(tmp_path: Path) -> None:
    from crlam.experiments.pool import run_jobs

    jobs = [(f"j{i}", {"value": i}) for i in range(3)]
    for workers in (1, 2):
        done, errors = run_jobs(jobs, dict, lambda n: False, lambda n: {}, workers=workers, progress=False, fresh_process=True)
        assert not errors and done == {f"j{i}": {"value": i} for i in range(3)}


def _die_or_echo(value: int) -> dict[str, int]:
    if value == 1:
        os.kill(os.getpid(), signal.SIGKILL)  # what the OOM killer does
    return {"value": value}


def test_a_worker_killed_mid_job_fails_that_job_only(tmp_path: Path) -> None:
    from crlam.experiments.pool import run_jobs

    jobs = [(f"j{i}", {"value": i}) for i in range(4)]
    done, errors = run_jobs(jobs, _die_or_echo, lambda n: False, lambda n: {}, workers=2, progress=False, fresh_process=True)
    assert done == {f"j{i}": {"value": i} for i in (0, 2, 3)}
    assert list(errors) == ["j1"]
    assert "SIGKILL" in errors["j1"] and "out of memory" in errors["j1"]


def _die_once(value: int, marker: str) -> dict[str, int]:
    if not Path(marker).exists():
        Path(marker).write_text("")
        os.kill(os.getpid(), signal.SIGKILL)
    return {"value": value}


def test_a_run_whose_process_died_is_started_again(tmp_path: Path) -> None:
    from crlam.experiments.pool import LocalExecutor, run_jobs

    jobs = [("j0", {"value": 0, "marker": str(tmp_path / "died")})]
    done, errors = run_jobs(jobs, _die_once, lambda n: False, lambda n: {}, progress=False, fresh_process=True)
    assert done == {"j0": {"value": 0}} and not errors
    # Without retries the death is the run's result.
    (tmp_path / "died").unlink()
    done, errors = run_jobs(
        jobs, _die_once, lambda n: False, lambda n: {}, progress=False, fresh_process=True, executor=LocalExecutor(retries=0)
    )
    assert not done and "SIGKILL" in errors["j0"] and "attempt 1 of 1" in errors["j0"]


def _slow_job(pidfile: str) -> dict[str, int]:
    tmp = Path(pidfile + ".tmp")
    tmp.write_text(str(os.getpid()))
    tmp.rename(pidfile)
    while True:  # runs until something ends it: the test checks that its sweep's death does
        time.sleep(1.0)


def _sweep_parent(pidfile: str) -> None:
    from crlam.experiments.pool import run_jobs

    run_jobs([("slow", {"pidfile": pidfile})], _slow_job, lambda n: False, lambda n: {}, progress=False, fresh_process=True)


def _alive(pid: int) -> bool:
    try:
        state = Path(f"/proc/{pid}/status").read_text()
    except FileNotFoundError:
        return False
    return "\nState:\tZ" not in state  # a zombie nobody reaped has ended too


@pytest.mark.skipif(not Path("/proc/self/status").is_file(), reason="needs Linux /proc")
def test_workers_end_when_the_sweep_process_is_killed(tmp_path: Path) -> None:
    pidfile = tmp_path / "pid"
    parent = multiprocessing.get_context("spawn").Process(target=_sweep_parent, args=(str(pidfile),))
    parent.start()
    # The limits below only stop a hung test; the outcome (the run ends after its sweep) does
    # not depend on how fast it happens.
    hang_guard = time.monotonic() + 600
    while not pidfile.exists():
        assert time.monotonic() < hang_guard and parent.is_alive(), "the run never started"
        time.sleep(0.05)
    child = int(pidfile.read_text())
    assert _alive(child)
    os.kill(parent.pid, signal.SIGKILL)  # no cleanup runs in the parent
    parent.join()
    hang_guard = time.monotonic() + 600
    while _alive(child) and time.monotonic() < hang_guard:
        time.sleep(0.1)
    if _alive(child):
        os.kill(child, signal.SIGKILL)
        pytest.fail("the run went on without its sweep")


def _rayon_threads(value: int) -> dict[str, str]:
    return {"threads": os.environ.get("RAYON_NUM_THREADS", "unset"), "value": str(value)}


def test_the_threads_setting_reaches_every_run(office_log: Path, tmp_path: Path) -> None:
    from crlam.experiments.pool import run_jobs

    jobs = [(f"j{i}", {"value": i}) for i in range(2)]
    done, errors = run_jobs(jobs, _rayon_threads, lambda n: False, lambda n: {}, workers=2, threads=2, progress=False)
    assert not errors and {r["threads"] for r in done.values()} == {"2"}
    # A sweep passes its runs' thread count on, and the results do not depend on it.
    ref = str(office_log / "groundtruth.tum")
    trajectories = []
    for threads in (1, 2):
        spec = RunSpec("clam", str(office_log / "log.clf"), SlamConfig(particles=6, seed=3), reference=ref, threads=threads)
        _, errors = run_sweep([spec], tmp_path / f"t{threads}", workers=2, progress=False)
        assert not errors
        trajectories.append((tmp_path / f"t{threads}" / "runs" / "clam" / "trajectory.tum").read_text())
    assert trajectories[0] == trajectories[1]


def test_table1_reports_every_setting_that_differs_from_the_paper() -> None:
    from crlam.experiments.table1 import protocol_deviations

    assert protocol_deviations(SlamConfig(resolution=0.2, max_range=8.0)) == []
    devs = protocol_deviations(SlamConfig(resolution=0.1, max_range=8.0, cause_kernel="chord"))
    assert devs == ["resolution = 0.1 (paper: 0.2)", "cause_kernel = 'chord' (paper: 'midpoint')"]


@pytest.mark.slow
def test_table1_command_takes_the_grid_and_reports_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from crlam.cli import main

    argv = ["experiment", "table1", "--out", str(tmp_path), "--runs", "1", "--scans", "20", "--particles", "2"]
    assert main([*argv, "--methods", "clam", "--resolution", "0.1", "--workers", "1", "--verbose"]) == 0
    err = capsys.readouterr().err  # -v: the settings, the base configuration and each finished run
    assert "crlam experiment table1: base settings" in err and "  resolution = 0.1" in err
    assert "clam_run00 finished (1 of 1)" in err
    config = (tmp_path / "runs" / "clam_run00" / "config.toml").read_text()
    assert "resolution = 0.1\n" in config
    assert "resolution = 0.1 (paper: 0.2)" in (tmp_path / "table.md").read_text()
    results = json.loads((tmp_path / "results.json").read_text())
    assert results["protocol"]["resolution"] == 0.1
    # The folder holds 0.1 m runs: resuming it with the paper's grid is refused, not mixed.
    assert main([*argv, "--methods", "clam", "--workers", "1", "--quiet"]) != 0
