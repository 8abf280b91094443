"""Named SLAM presets: the TOML files, their resolution, the CLI's overrides, --config and deviations."""

from __future__ import annotations

import json
import re
import sys
from dataclasses import fields
from pathlib import Path
from typing import Any

import numpy as np
import pytest

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - Python 3.10
    import tomli as tomllib

import crlam.slam.preset_files as preset_files
import crlam.slam.presets as presets
from crlam.cli import build_parser, main, slam_config_of
from crlam.errors import ConfigError
from crlam.experiments.slam_run import run_slam_log
from crlam.io.relations import write_relations
from crlam.io.tum import read_tum
from crlam.pose import between
from crlam.sim.simulate import SimulationConfig, simulate, write_simulation
from crlam.slam import SlamConfig

FIELDS = [f.name for f in fields(SlamConfig) if f.name != "preset"]


@pytest.fixture(scope="module")
def office(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("office")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=40, seed=4)), d)
    return d


def _raw(name: str) -> dict[str, Any]:
    """The [slam] table of a preset file as written (arrays as tuples), '(unset)' lines as None."""
    path = presets.preset_path(name)
    text = path.read_text()
    table = tomllib.loads(text)["slam"]
    out = {k: tuple(v) if isinstance(v, list) else v for k, v in table.items()}
    for k in re.findall(r"^#\s*(\w+)\s*=\s*\(unset\)", text, re.M):
        out[k] = None
    return out


def test_the_shipped_presets_and_the_default() -> None:
    assert {"paper", "robust"} <= set(presets.list_presets())
    assert presets.DEFAULT_PRESET == "robust" and presets.PAPER_PRESET == "paper"
    assert SlamConfig.from_preset().preset == "robust"
    for name in presets.list_presets():
        assert presets.preset_path(name).parent == Path(presets.__file__).parent  # shipped inside the package
        assert presets.preset_description(name)


@pytest.mark.parametrize("name", ["paper", "robust"])
def test_a_preset_resolves_to_its_file_over_the_paper_defaults(name: str) -> None:
    raw = _raw(name)
    assert set(raw) <= set(FIELDS)
    cfg = SlamConfig.from_preset(name)
    assert cfg.preset == name
    default = SlamConfig()
    for f in FIELDS:
        want = raw[f] if f in raw else getattr(default, f)
        assert getattr(cfg, f) == want, f
        if isinstance(want, float):
            assert isinstance(getattr(cfg, f), float), f  # TOML integers become floats where the field is one
    assert presets.load_preset(name) == {k: raw[k] for k in raw}


def test_the_paper_preset_writes_every_field_and_is_the_plain_constructor() -> None:
    assert set(_raw("paper")) == set(FIELDS)
    assert SlamConfig.from_preset("paper") == SlamConfig()
    assert SlamConfig.from_preset("paper").deviations() == []
    assert SlamConfig().deviations() == []


def test_every_robust_value_carries_its_reason() -> None:
    # Each setting has an inline comment or sits in a block of settings under a comment.
    lines = presets.preset_path("robust").read_text().splitlines()
    start = lines.index("[slam]")
    setting = re.compile(r"^\w+\s*=")
    for i, line in enumerate(lines[start + 1 :], start + 1):
        if setting.match(line) and "#" not in line:
            j = i - 1
            while setting.match(lines[j]):
                j -= 1
            assert lines[j].startswith("#"), f"robust.toml line {i + 1} has no comment: {line}"


def test_robust_lists_exactly_its_values_that_differ_from_the_paper() -> None:
    robust, paper = presets.load_preset("robust"), presets.paper_settings()
    expected = [
        f"{k} = {robust[k]!r} (paper: {paper[k]!r})"
        for k in FIELDS
        if k in robust and robust[k] != paper[k] and k not in presets.NOT_DEVIATIONS
    ]
    assert expected, "the robust preset is the paper's"
    assert SlamConfig.from_preset("robust").deviations() == expected


def test_deviations_cover_every_filter_setting_and_skip_the_others() -> None:
    quiet = SlamConfig(seed=7, mode_bandwidth=(1.0, 1.0), smoothing_lag=3, preset="robust")
    assert quiet.deviations() == []
    loud = SlamConfig(
        motion="thrun",
        motion_params=(0.1, 0.1, 0.002, 0.1),
        max_range=20.0,
        resolution=0.1,
        particles=30,
        linear_update=0.5,
        weight_stride=2,
        sigma_range=0.05,
        batch_kernel="full_ray",
        init_sigma=(0.1, 0.1, 0.0),
        resample_threshold=0.7,
        ogm_map="hit_rate",
    )
    names = [d.split(" = ")[0] for d in loud.deviations()]
    assert names == [
        "particles",
        "resolution",
        "max_range",
        "batch_kernel",
        "weight_stride",
        "resample_threshold",
        "motion",
        "motion_params",
        "linear_update",
        "init_sigma",
        "sigma_range",
        "ogm_map",
    ]
    assert "motion_params = (0.1, 0.1, 0.002, 0.1) (paper: None)" in loud.deviations()
    assert "max_range = 20.0 (paper: 8.0)" in loud.deviations()


def test_overrides_win_and_unknown_names_are_errors() -> None:
    cfg = SlamConfig.from_preset("robust", particles=3, tempering=7.0)
    robust = presets.load_preset("robust")
    assert cfg.particles == 3 and cfg.tempering == 7.0 and cfg.proposal == robust["proposal"]
    with pytest.raises(ConfigError, match=r"unknown preset 'nope'.*nope\.toml.*paper, robust"):
        SlamConfig.from_preset("nope")
    with pytest.raises(ConfigError, match="particels"):
        SlamConfig.from_preset("paper", particels=3)
    with pytest.raises(ConfigError, match=r"paper\.toml.*SlamConfig\.tempering"):
        SlamConfig.from_preset("paper", tempering=-1.0)


def test_a_presets_loop_closing_gives_way_to_rbpf_ogm() -> None:
    preset = {"method": "clam", "loop_closing": "graph"}
    assert SlamConfig.settle_preset_settings(preset, {"method": "ogm"})["loop_closing"] == "off"
    assert SlamConfig.settle_preset_settings(preset, {"particles": 3})["loop_closing"] == "graph"
    # Asked for by name, it stays, and the config's check says why it cannot be.
    both = SlamConfig.settle_preset_settings(preset, {"method": "ogm", "loop_closing": "graph"})
    with pytest.raises(ConfigError, match="loop_closing"):
        SlamConfig(**both)


@pytest.mark.parametrize(
    ("body", "key"),
    [
        ("[slam]\nparticels = 3\n", "particels"),
        ('[slam]\nparticles = "many"\n', "particles"),
        ("[slam]\nparticles = 2.5\n", "particles"),
        ("[slam]\nlattice_step = [0.1]\n", "lattice_step"),
        ("[slam]\ntempering = -1.0\n", "tempering"),
        ('[slam]\nproposal = "magic"\n', "proposal"),
        ("[slam]\n# particles = (unset)\n", "particles"),
        ("[slam]\nparticles = 3\n[extra]\nx = 1\n", "extra"),
        ("[slam\n", "not valid TOML"),
    ],
)
def test_a_bad_preset_file_names_the_file_and_the_key(
    body: str, key: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(preset_files, "_DIR", tmp_path)  # where crlam.slam.presets reads its files
    preset_files._load_preset.cache_clear()
    (tmp_path / "bad.toml").write_text(body)
    try:
        with pytest.raises(ConfigError) as e:
            presets.resolve("bad", {})
        assert str(tmp_path / "bad.toml") in str(e.value) and key in str(e.value), e.value
    finally:
        preset_files._load_preset.cache_clear()


def test_a_bad_config_file_names_the_file_and_the_key(tmp_path: Path) -> None:
    path = tmp_path / "config.toml"
    path.write_text('[run]\nlog = "x.clf"\n\n[slam]\nparticles = 3\nwobble = 1\n')
    with pytest.raises(ConfigError, match=rf"{re.escape(str(path))}.*'wobble'"):
        presets.load_config_file(path)
    path.write_text('[slam]\npreset = "nope"\n')
    with pytest.raises(ConfigError, match="unknown preset 'nope'"):
        presets.load_config_file(path)
    path.write_text("[slam]\nmotion_params = [0.1]\n")
    with pytest.raises(ConfigError, match=rf"{re.escape(str(path))}.*motion_params"):
        presets.load_config_file(path)
    with pytest.raises(ConfigError, match="no such config file"):
        presets.load_config_file(tmp_path / "missing.toml")


def _parse(argv: list[str]) -> Any:
    return build_parser().parse_args(argv)


def test_no_slam_flag_has_a_default_of_its_own() -> None:
    # Only flags the user types may override the preset: every SLAM flag parses to None when absent.
    parser = build_parser()
    sub = parser._subparsers._group_actions[0].choices  # type: ignore[union-attr]
    experiment = sub["experiment"]._subparsers._group_actions[0].choices
    for name, p in (("slam", sub["slam"]), ("table1", experiment["table1"]), ("real-logs", experiment["real-logs"])):
        flags = [a for a in p._actions if a.dest in FIELDS]
        assert len(flags) >= 10, name
        for a in flags:
            assert a.default is None, f"crlam {name} {a.option_strings}: default {a.default!r}"


def test_cli_flags_override_the_preset_and_nothing_else() -> None:
    base = ["slam", "log.clf", "--out", "o"]
    config, max_scans = slam_config_of(_parse(base))
    assert config == SlamConfig.from_preset("robust") and config.preset == "robust" and max_scans is None
    config, _ = slam_config_of(_parse([*base, "--preset", "paper"]))
    assert config == SlamConfig() and config.preset == "paper"
    argv = [*base, "--particles", "3", "--tempering", "7", "--lattice-step", "0.2", "0.1", "--seed", "4"]
    config, _ = slam_config_of(_parse(argv))
    assert config == SlamConfig.from_preset("robust", particles=3, tempering=7.0, lattice_step=(0.2, 0.1), seed=4)
    assert config.proposal == presets.load_preset("robust")["proposal"]
    config, _ = slam_config_of(_parse([*argv, "--preset", "paper"]))
    assert config == SlamConfig(particles=3, tempering=7.0, lattice_step=(0.2, 0.1), seed=4)
    with pytest.raises(SystemExit):
        _parse([*base, "--preset", "nope"])
    with pytest.raises(SystemExit):
        _parse([*base, "--preset", "paper", "--config", "c.toml"])


def test_the_default_run_records_the_preset(office: Path, tmp_path: Path) -> None:
    from dataclasses import replace

    res = run_slam_log(office / "log.clf", tmp_path, max_scans=8, progress=False, figures=False)
    metrics = json.loads((tmp_path / "metrics.json").read_text())
    # The preset's settings, with the odometry noise the run fitted (8 scans: too few steps, so
    # GMapping's defaults, recorded as such) written in, so that config.toml repeats the run.
    noise = metrics["motion_noise_estimate"]
    assert noise["fitted"] is False and noise["params"] == [0.1, 0.2, 0.1, 0.2]
    run_config = replace(SlamConfig.from_preset(), motion_params=tuple(noise["params"]))
    assert res.run.config == run_config
    assert metrics["preset"] == "robust"
    assert metrics["deviations_from_paper"] == run_config.deviations()
    stored = presets.load_config_file(tmp_path / "config.toml")
    assert stored.preset == "robust" and set(stored.settings) == set(FIELDS)
    assert '\npreset = "robust"\n' in (tmp_path / "config.toml").read_text()


def test_config_round_trips_through_a_second_run(office: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = str(office / "log.clf")
    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    flags = ["--preset", "paper", "--particles", "3", "--seed", "2", "--linear-update", "0.2", "--angular-update", "0.2"]
    assert main(["slam", log, "--out", str(a), *flags, "--motion", "thrun", "--max-scans", "30", "--quiet"]) == 0
    assert main(["slam", log, "--out", str(b), "--config", str(a / "config.toml"), "--quiet"]) == 0
    assert (a / "config.toml").read_text() == (b / "config.toml").read_text()
    assert (a / "trajectory.tum").read_bytes() == (b / "trajectory.tum").read_bytes()
    ma, mb = (json.loads((d / "metrics.json").read_text()) for d in (a, b))
    assert ma["preset"] == mb["preset"] == "paper" and ma["n_scans"] == mb["n_scans"] == 30
    assert ma["deviations_from_paper"] == mb["deviations_from_paper"]
    assert [d.split(" = ")[0] for d in ma["deviations_from_paper"]] == [
        "particles",
        "motion",
        "linear_update",
        "angular_update",
    ]
    # Flags beside --config still override it; the rest is the file's.
    assert main(["slam", log, "--out", str(c), "--config", str(a / "config.toml"), "--particles", "2", "--quiet"]) == 0
    stored_a, stored_c = (presets.load_config_file(d / "config.toml") for d in (a, c))
    assert stored_c.settings == stored_a.settings | {"particles": 2} and stored_c.preset == "paper"
    assert stored_c.max_scans == 30
    assert not np.array_equal(read_tum(a / "trajectory.tum").poses, read_tum(c / "trajectory.tum").poses)
    assert "preset paper; differs from the paper in: particles, motion" in capsys.readouterr().out


def test_table1_uses_the_paper_preset_unless_told(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    import crlam.experiments.table1 as table1

    seen: dict[str, Any] = {}

    def fake(out: Path, **kw: Any) -> dict[str, Any]:
        seen.update(kw)
        (out / "table.md").parent.mkdir(parents=True, exist_ok=True)
        (out / "table.md").write_text("table\n")
        return {}

    monkeypatch.setattr(table1, "run_table1", fake)
    assert main(["experiment", "table1", "--out", str(tmp_path), "--quiet"]) == 0
    assert seen["base"] == SlamConfig() and seen["base"].preset == "paper" and seen["particles"] == 100
    argv = ["experiment", "table1", "--out", str(tmp_path), "--preset", "robust", "--particles", "7", "--quiet"]
    assert main(argv) == 0
    assert seen["base"] == SlamConfig.from_preset("robust", particles=7, max_range=8.0) and seen["particles"] == 7


def test_real_logs_sweeps_use_the_robust_preset(office: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    import crlam.experiments.real_logs as real_logs

    # The Python helper without a base config: the default preset.
    res = real_logs.run_real_logs(tmp_path / "api", datasets=(), report_only=True, progress=False)
    assert res["preset"] == "robust" and res["config"] == SlamConfig.from_preset().to_dict()

    # The command, on a tiny simulated "intel" log with relations between ground-truth poses.
    gt = read_tum(office / "groundtruth.tum")
    rel = tmp_path / "gt.relations"
    write_relations(rel, gt.timestamps[:-2], gt.timestamps[2:], between(gt.poses[:-2], gt.poses[2:]))
    files = {"intel": office / "log.clf", "intel-relations": rel}
    monkeypatch.setattr(real_logs, "find_dataset", lambda name: files[name])
    out = tmp_path / "cli"
    argv = ["experiment", "real-logs", "--out", str(out), "--datasets", "intel", "--methods", "clam", "ogm"]
    argv += ["--particles", "2", "--runs", "1", "--ranges", "8", "--max-scans", "12", "--workers", "1", "--quiet"]
    assert main(argv) == 0
    run, ogm = (next((out / "runs").glob(f"intel_{m}_*")) for m in ("clam", "ogm"))
    # RBPF-OGM runs the preset without its loop closing (re-anchoring needs RBPF-CLAM's CRMs).
    ogm_settings = presets.load_config_file(ogm / "config.toml").settings
    assert ogm_settings["method"] == "ogm" and ogm_settings["loop_closing"] == "off"
    stored = presets.load_config_file(run / "config.toml")
    assert stored.preset == "robust"
    fitted = json.loads((run / "metrics.json").read_text())["motion_noise_estimate"]["params"]
    assert SlamConfig(**stored.settings) == SlamConfig.from_preset(
        "robust", particles=2, max_range=8.0, motion_params=tuple(fitted)
    )
    assert json.loads((run / "metrics.json").read_text())["preset"] == "robust"
    assert json.loads((out / "results.json").read_text())["preset"] == "robust"
