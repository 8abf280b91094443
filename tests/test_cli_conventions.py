"""The command-line conventions, checked on the whole parser: groups in every --help, -o/--out,
-q and -v wherever there is output, one flag name per destination, the renamed flags' old
spellings, one list syntax, dataset names and ``-`` for standard input wherever a file is read,
and existing outputs refused without --force."""

from __future__ import annotations

import argparse
import ast
import gzip
import io
import json
import math
import subprocess
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np
import pytest

from crlam.cli import COMMANDS, build_parser, main
from crlam.cli.conventions import resolve_input
from crlam.io.datasets import DatasetNotFoundError

ROOT = Path(__file__).resolve().parents[1]

#: Leaves that write nothing: no -o/--out. (data fetch writes into its --cache.)
NO_OUT = {"crlam data list", "crlam data fetch", "crlam ros play"}
#: Leaves without progress output: no -q/-v.
NO_PROGRESS = {"crlam data list"}
DEFAULT_GROUPS = {"options", "optional arguments", "positional arguments"}


def _leaves(parser: argparse.ArgumentParser, prog: str = "crlam") -> list[tuple[str, argparse.ArgumentParser]]:
    subs = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    if not subs:
        return [(prog, parser)]
    return [leaf for a in subs for name, child in a.choices.items() for leaf in _leaves(child, f"{prog} {name}")]


#: One parser for the checks that only parse (building one takes a moment).
PARSER = build_parser()
LEAVES = _leaves(PARSER)


def _visible(parser: argparse.ArgumentParser) -> list[argparse.Action]:
    return [a for a in parser._actions if a.help != argparse.SUPPRESS and not isinstance(a, argparse._HelpAction)]


def _flags(parser: argparse.ArgumentParser) -> dict[str, argparse.Action]:
    return {flag: a for a in _visible(parser) for flag in a.option_strings}


def test_the_walk_sees_every_command() -> None:
    progs = {prog for prog, _ in LEAVES}
    assert {f"crlam {c}" for c in COMMANDS if c not in ("data", "diagnose", "experiment", "ros")} <= progs
    assert {"crlam ros slam", "crlam ros localize", "crlam ros explore", "crlam ros play"} <= progs
    assert {"crlam data fetch", "crlam experiment table1", "crlam experiment iig", "crlam diagnose likelihood-bias"} <= progs


@pytest.mark.parametrize("prog,parser", LEAVES, ids=[p for p, _ in LEAVES])
def test_every_argument_sits_in_a_named_group(prog: str, parser: argparse.ArgumentParser) -> None:
    loose = [
        a.option_strings or a.dest
        for g in parser._action_groups
        if g.title in DEFAULT_GROUPS
        for a in g._group_actions
        if a.help != argparse.SUPPRESS and not isinstance(a, argparse._HelpAction)
    ]
    assert not loose, f"{prog}: arguments outside a named group: {loose}"
    titles = [g.title for g in parser._action_groups if g._group_actions and g.title not in DEFAULT_GROUPS]
    assert "resource limits" in titles and len(titles) >= 2, titles
    assert all(f"\n{t}:" in parser.format_help() for t in titles)


@pytest.mark.parametrize("prog,parser", LEAVES, ids=[p for p, _ in LEAVES])
def test_output_quiet_and_verbose_everywhere(prog: str, parser: argparse.ArgumentParser) -> None:
    flags = _flags(parser)
    if prog not in NO_OUT:
        assert flags.get("-o") is flags.get("--out") is not None, f"{prog}: no -o/--out"
        assert "--force" in flags, f"{prog}: an existing output needs --force (or --resume)"
    if prog not in NO_PROGRESS:
        assert flags.get("-q") is flags.get("--quiet") is not None, f"{prog}: no -q/--quiet"
        assert flags.get("-v") is flags.get("--verbose") is not None, f"{prog}: no -v/--verbose"


def test_one_flag_name_per_destination_across_commands() -> None:
    names: dict[str, set[str]] = defaultdict(set)
    for _, parser in LEAVES:
        for a in _visible(parser):
            long = [f for f in a.option_strings if f.startswith("--")]
            if long:
                names[a.dest].add(long[0])
    assert {d: n for d, n in names.items() if len(n) > 1} == {}


def test_lists_are_space_separated_everywhere() -> None:
    # Every list option takes its items as separate words (nargs "+"); none is a comma string.
    for prog, parser in LEAVES:
        for a in _visible(parser):
            text = (a.help or "").lower()
            assert "comma-separated" not in text, (prog, a.option_strings)
            if isinstance(a.default, list):
                assert a.nargs in ("+", "*"), (prog, a.option_strings)


#: (argv, destination, value): each old spelling still parses to the new flag's destination.
RENAMED = [
    (["info", "m.pgm", "--function", "crmi", "-o", "o", "--z-max", "3"], "max_range", 3.0),
    (["info", "m.pgm", "--function", "ucrmi", "-o", "o", "--particles", "7"], "ucrmi_particles", 7),
    (["explore", "-o", "o", "--world-resolution", "0.1"], "resolution", 0.1),
    (["explore", "-o", "o", "--particles", "9"], "ucrmi_particles", 9),
    (["map", "x.log", "-o", "o", "--model", "mixture"], "crm_model", "mixture"),
    (["map", "x.log", "-o", "o", "--beam-stride", "3"], "map_stride", 3),
    (["diagnose", "likelihood-bias", "x.log", "-o", "o", "--model", "ijrr"], "crm_model", "ijrr"),
    (["eval", "t.tum", "--reference", "r.tum", "--json", "r.json"], "out", "r.json"),
    (["bench", "--json", "b.json"], "out", "b.json"),
    (["experiment", "real-logs", "-o", "o", "--seeds", "2"], "runs", 2),
    (["experiment", "iig", "-o", "o", "--particles", "5"], "ucrmi_particles", 5),
    (["experiment", "explore", "-o", "o", "--particles", "4"], "slam_particles", 4),
]


@pytest.mark.parametrize("argv,dest,value", RENAMED, ids=[" ".join(r[0][:2]) + " " + r[0][-2] for r in RENAMED])
def test_old_spellings_still_parse_and_warn(
    argv: list[str], dest: str, value: object, capsys: pytest.CaptureFixture[str]
) -> None:
    args = PARSER.parse_args(argv)
    assert getattr(args, dest) == value
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("crlam: warning: ") and argv[-2] in err[0] and "deprecated" in err[0], err


def test_old_spellings_are_hidden_from_help() -> None:
    for prog, parser in LEAVES:
        text = parser.format_help()
        for old in ("--z-max", "--world-resolution", "--seeds", "--beam-stride", "--json"):
            assert old not in text, (prog, old)


def test_convert_takes_its_output_by_flag_and_still_reads_the_old_positional(capsys: pytest.CaptureFixture[str]) -> None:
    args = PARSER.parse_args(["convert", "a.clf", "b.mcap"])
    assert args.legacy_output == "b.mcap" and args.out is None
    args = PARSER.parse_args(["convert", "a.clf", "-o", "b.mcap"])
    assert args.out == "b.mcap" and args.legacy_output is None


def test_the_older_comma_lists_still_parse_with_a_warning(capsys: pytest.CaptureFixture[str]) -> None:
    spaced = PARSER.parse_args(["experiment", "iig", "-o", "o", "--functions", "crmi", "ucrmi"])
    assert spaced.functions == ["crmi", "ucrmi"] and capsys.readouterr().err == ""
    comma = PARSER.parse_args(["experiment", "iig", "-o", "o", "--functions", "crmi,ucrmi"])
    assert comma.functions == ["crmi", "ucrmi"]
    err = capsys.readouterr().err
    assert "comma-separated lists are deprecated" in err and "--functions crmi ucrmi" in err
    alphas = PARSER.parse_args(["experiment", "explore", "-o", "o", "--alphas", "0,0.5", "1"])
    assert alphas.alphas == [0.0, 0.5, 1.0]
    methods = PARSER.parse_args(["experiment", "table1", "-o", "o", "--methods", "ogm,clam"])
    assert methods.methods == ["ogm", "clam"]
    with pytest.raises(SystemExit):
        PARSER.parse_args(["experiment", "table1", "-o", "o", "--methods", "ogm,bogus"])
    with pytest.raises(SystemExit):
        PARSER.parse_args(["experiment", "explore", "-o", "o", "--alphas", "0", "nan"])


def test_commands_import_the_shared_modules_never_each_other() -> None:
    shared = {"options", "conventions", "executor", "failures", "live"}
    for name in COMMANDS:
        tree = ast.parse((ROOT / "python" / "crlam" / "cli" / f"{name}.py").read_text())
        for node in ast.walk(tree):
            if isinstance(node, ast.ImportFrom) and node.module and node.module.startswith("crlam.cli"):
                parts = node.module.split(".")
                assert node.module != "crlam.cli" and len(parts) == 3 and parts[2] in shared, (name, node.module)
    for name in shared:
        text = (ROOT / "python" / "crlam" / "cli" / f"{name}.py").read_text()
        assert not any(f"crlam.cli.{c} " in text or f"crlam.cli.{c}\n" in text for c in COMMANDS), name


# ------------------------------------------------------------------ inputs: dataset names and "-"


@pytest.fixture()
def data_folder(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    root = tmp_path / "data"
    (root / "intel").mkdir(parents=True)
    monkeypatch.setenv("CRLAM_DATA", str(root))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.chdir(tmp_path)
    return root


def test_a_dataset_name_resolves_and_an_existing_path_wins(data_folder: Path) -> None:
    rel = data_folder / "intel" / "intel.relations"
    rel.write_text("0 1 0.1 0 0 0 0 0\n")
    assert resolve_input("intel-relations") == str(rel)
    Path("intel-relations").write_text("a local file of that name\n")
    assert resolve_input("intel-relations") == "intel-relations"


def test_unknown_names_and_missing_datasets_are_clear_errors(data_folder: Path) -> None:
    with pytest.raises(DatasetNotFoundError, match="not a dataset name.*intel-relations.*crlam data list"):
        resolve_input("no-such-thing.log")
    with pytest.raises(DatasetNotFoundError, match="crlam data fetch aces"):
        resolve_input("aces")


def _trajectory(path: Path, n: int = 5) -> None:
    path.write_text("".join(f"{i}.0 {0.1 * i} 0 0 0 0 0 1\n" for i in range(n)))


def test_eval_takes_a_dataset_name_for_the_relations(data_folder: Path, capsys: pytest.CaptureFixture[str]) -> None:
    (data_folder / "intel" / "intel.relations").write_text("0 1 0.1 0 0 0 0 0\n1 3 0.2 0 0 0 0 0\n")
    _trajectory(Path("est.tum"))
    assert main(["eval", "est.tum", "--relations", "intel-relations", "-o", "r.json"]) == 0
    report = json.loads(Path("r.json").read_text())
    assert report["relations"].endswith("intel.relations") and report["summary"]["n"] == 2
    assert math.isclose(report["summary"]["trans_mean_m"], 0.0, abs_tol=1e-9)
    assert main(["eval", "est.tum", "--relations", "aces-relations"]) == 2
    assert "crlam data fetch aces-relations" in capsys.readouterr().err


def _stdin(monkeypatch: pytest.MonkeyPatch, data: bytes) -> None:
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(data)))


def test_eval_reads_the_trajectory_from_standard_input(tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys) -> None:  # type: ignore[no-untyped-def]
    _trajectory(tmp_path / "ref.tum")
    _stdin(monkeypatch, (tmp_path / "ref.tum").read_bytes())
    assert main(["eval", "-", "--reference", str(tmp_path / "ref.tum"), "-q"]) == 0
    out = capsys.readouterr().out
    assert out.lstrip().startswith("MAE x (m)") and "RMSE position (m)  0" in out
    _stdin(monkeypatch, b"")
    assert main(["eval", "-", "--reference", str(tmp_path / "ref.tum")]) == 2
    assert "standard input is empty" in capsys.readouterr().err


def _carmen(n: int = 12) -> bytes:
    ranges = " ".join(["2.0"] * 180)
    return "".join(f"FLASER 180 {ranges} {0.05 * i} 0 0 {0.05 * i} 0 0 {i}.0 host {i}.0\n" for i in range(n)).encode()


def test_map_reads_a_compressed_log_from_a_pipe_with_python_dash_m_crlam_cli(tmp_path: Path) -> None:
    r = subprocess.run(
        [sys.executable, "-m", "crlam.cli", "map", "-", "-o", str(tmp_path / "m"), "--quiet", "--resolution", "0.1"],
        input=gzip.compress(_carmen()),
        capture_output=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stderr.decode()
    assert json.loads((tmp_path / "m" / "mapping.json").read_text())["n_scans"] == 12


# ------------------------------------------------------------------ outputs


@pytest.fixture()
def inputs(tmp_path: Path) -> dict[str, str]:
    (tmp_path / "log.clf").write_bytes(_carmen(3))
    _trajectory(tmp_path / "t.tum")
    taken = tmp_path / "taken"
    taken.mkdir()
    (taken / "keep.txt").write_text("not crlam's")
    (tmp_path / "taken.json").write_text("{}")
    # A map of the Cave's size (100 x 100 px at 0.2 m/px, walls round a free room): the IIG
    # experiment's default map is a dataset, which a fresh clone does not have.
    room = np.full((100, 100), 255, dtype=np.uint8)
    room[[0, -1], :] = room[:, [0, -1]] = 0
    (tmp_path / "room.pgm").write_bytes(b"P5\n100 100\n255\n" + room.tobytes())
    return {
        "log": str(tmp_path / "log.clf"),
        "map": str(tmp_path / "room.pgm"),
        "tum": str(tmp_path / "t.tum"),
        "dir": str(taken),
        "file": str(tmp_path / "taken.json"),
    }


EXISTING = [
    "demo -o {dir} -q",
    "simulate -o {dir} -q",
    "map {log} -o {dir} -q",
    "slam {log} -o {dir} -q",
    "eval {tum} --reference {tum} -o {file}",
    "info --belief {log} --function crmi -o {dir}",
    "explore -o {dir} -q",
    "diagnose likelihood-bias {log} --log-poses -o {dir} -q",
    "convert {log} -o {file}",
    "bench --quick -o {file}",
    "experiment table1 -o {dir} -q",
    "experiment real-logs -o {dir} -q",
    "experiment iig --map {map} -o {dir} -q",
    "experiment explore -o {dir} -q",
]


@pytest.mark.parametrize("case", EXISTING, ids=[c.split(" -o")[0] for c in EXISTING])
def test_an_existing_output_is_refused_without_force(case: str, inputs: dict[str, str], capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(case.format(**inputs).split()) == 2
    err = capsys.readouterr().err
    assert "already exists" in err and "--force" in err, err
    assert (Path(inputs["dir"]) / "keep.txt").exists() and Path(inputs["file"]).read_text() == "{}"


def test_verbose_prints_the_settings_and_quiet_only_the_result(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _trajectory(tmp_path / "t.tum")
    assert main(["eval", str(tmp_path / "t.tum"), "--reference", str(tmp_path / "t.tum"), "-v"]) == 0
    captured = capsys.readouterr()
    assert "crlam eval: arguments" in captured.err and "align = 'none'" in captured.err
    assert '"metric": "reference"' in captured.err  # the full report
    assert "errors against a reference trajectory" in captured.out
    with pytest.raises(SystemExit):
        main(["eval", str(tmp_path / "t.tum"), "--reference", str(tmp_path / "t.tum"), "-v", "-q"])


# ------------------------------------------------------------------ the documentation's commands


def _documented_commands() -> list[tuple[str, str]]:
    """Every ``crlam ...`` command of a bash block in the README, BENCHMARKS.md, docs/ and the
    results' READMEs: (file, command line)."""
    import re
    import shlex

    files = [ROOT / "README.md", ROOT / "BENCHMARKS.md", *sorted((ROOT / "docs").rglob("*.md"))]
    files += sorted((ROOT / "results").rglob("README.md"))
    out = []
    for path in files:
        for block in re.findall(r"^```(?:bash|sh|console)\n(.*?)^```", path.read_text(encoding="utf-8"), flags=re.S | re.M):
            for line in block.replace("\\\n", " ").splitlines():
                words = shlex.split(line, comments=True)
                segment: list[str] = []
                for word in [*words, ";"]:
                    if word in ("|", "&&", ";", "||"):
                        while segment and re.fullmatch(r"[A-Z_]+=\S*", segment[0]):
                            segment.pop(0)  # an environment assignment before the command
                        if segment[:1] == ["crlam"]:
                            out.append((str(path.relative_to(ROOT)), " ".join(segment)))
                        segment = []
                    else:
                        segment.append(word)
    return out


DOCUMENTED = _documented_commands()


def test_the_documentation_has_commands_to_check() -> None:
    assert len(DOCUMENTED) > 40
    assert any(cmd.startswith("crlam slam intel ") for _, cmd in DOCUMENTED)


@pytest.mark.parametrize("where,command", DOCUMENTED, ids=[f"{w}:{c[:60]}" for w, c in DOCUMENTED])
def test_every_documented_command_parses_with_the_current_names(where: str, command: str, capsys) -> None:  # type: ignore[no-untyped-def]
    import shlex

    try:
        PARSER.parse_args(shlex.split(command)[1:])
    except SystemExit as e:
        assert e.code == 0, f"{where}: {command}\n{capsys.readouterr().err}"
    err = capsys.readouterr().err
    assert "deprecated" not in err, f"{where}: {command}\n{err}"


def test_progress_totals_count_the_scans_of_a_log(tmp_path: Path) -> None:
    from crlam.io.logs import count_scans

    text = b"PARAM robot_front_laser_max 80\n" + _carmen(12) + b"ODOM 0 0 0 0 0 0 1 h 1\n"
    (tmp_path / "log.clf.gz").write_bytes(gzip.compress(text))
    assert count_scans(tmp_path / "log.clf.gz") == 12
    assert count_scans(tmp_path / "log.clf.gz", max_scans=5) == 5
    (tmp_path / "bag").mkdir()
    (tmp_path / "bag" / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    assert count_scans(tmp_path / "bag") is None and count_scans(tmp_path / "missing.log") is None
