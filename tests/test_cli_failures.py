"""The command line turns every expected failure into one error line and exit status 2: the
ordinary mistakes of issue 31 (finding 5) that gave tracebacks, and a sweep of hostile inputs
(missing files, folders, devices, binary files, absurd numbers) over the commands that read them."""

from __future__ import annotations

import struct
import zlib
from pathlib import Path

import pytest

from crlam.cli import main


def _flaser_log(path: Path, n: int = 3) -> Path:
    ranges = " ".join(["3.0"] * 180)
    path.write_text("".join(f"FLASER 180 {ranges} {0.1 * i} 0 0 {0.1 * i} 0 0 {i}.0 host {i}.0\n" for i in range(n)))
    return path


def _png(path: Path, width: int, height: int) -> Path:
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 100)) + chunk(b"IEND", b"")
    )
    return path


@pytest.fixture
def inputs(tmp_path: Path) -> dict[str, str]:
    log = _flaser_log(tmp_path / "a.log")
    (tmp_path / "afile").write_text("x")
    (tmp_path / "adir").mkdir()
    (tmp_path / "bin.yaml").write_bytes(b"\x00\x01\xff\xfe binary")
    (tmp_path / "bin.log").write_bytes(bytes(range(256)) * 100)
    (tmp_path / "ref.tum").write_text("".join(f"{i}.0 {0.1 * i} 0 0 0 0 0 1\n" for i in range(3)))
    _png(tmp_path / "huge.png", 20000, 20000)
    (tmp_path / "huge.yaml").write_text("image: huge.png\nresolution: 0.05\norigin: [0, 0, 0]\n")
    return {
        "log": str(log),
        "afile": str(tmp_path / "afile"),
        "adir": str(tmp_path / "adir"),
        "binyaml": str(tmp_path / "bin.yaml"),
        "binlog": str(tmp_path / "bin.log"),
        "ref": str(tmp_path / "ref.tum"),
        "hugepng": str(tmp_path / "huge.png"),
        "hugeyaml": str(tmp_path / "huge.yaml"),
        "missing": str(tmp_path / "missing.log"),
        "out": str(tmp_path / "out"),
    }


CASES = [
    # issue 31, finding 5
    "map {log} --out {afile} --quiet",
    "map {log} --out {afile}/sub --quiet",
    "map {log} --out /proc/crlam-test --quiet",
    "eval {log} --reference {ref} --out {adir}",
    "simulate --world {binyaml} --out {out} --quiet",
    "info {binyaml} --function crmi --out {out}",
    "slam {log} --config {binyaml} --out {out} --quiet",
    "simulate --world {hugeyaml} --out {out} --quiet",
    "explore --world {hugepng} --resolution 0.1 --out {out} --quiet",
    "explore --start nan nan --out {out} --quiet",
    "slam {log} --seed 1e23 --out {out} --quiet",
    "slam {log} --seed 99999999999999999999999 --out {out} --quiet",
    # hostile inputs
    "map {missing} --out {out} --quiet",
    "map {adir} --out {out} --quiet",
    "map /dev/zero --out {out} --quiet",
    "map {binlog} --out {out} --quiet",
    "slam {binlog} --out {out} --quiet",
    "eval {binlog} --reference {ref}",
    "eval {log} --reference {binlog}",
    "eval {log} --relations {binyaml}",
    "info --belief {binlog} --function crmi --out {out}",
    "info --belief {adir} --function crmi --out {out}",
    "experiment iig --map {binlog} --out {out} --quiet --runs 1",
    "experiment explore --alphas x --out {out} --quiet",
    "experiment iig --functions , --out {out} --quiet",
    "map {log} --out {out} --quiet --max-map-cells 0",
    "map {log} --out {out} --quiet --resolution 1e-300",
    "convert {binlog} -o {out}.mcap",
]


@pytest.mark.parametrize("case", CASES)
def test_expected_failures_are_one_error_line_and_status_2(
    case: str, inputs: dict[str, str], capsys: pytest.CaptureFixture[str]
) -> None:
    argv = case.format(**inputs).split()
    if "/dev/zero" in argv and not Path("/dev/zero").exists():
        pytest.skip("no /dev/zero")
    try:
        status = main(argv)
    except SystemExit as e:  # argparse's usage errors
        status = e.code
    assert status == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    # argparse's usage errors name the subcommand too (crlam experiment explore: error: ...).
    errors = [line for line in err.splitlines() if line.startswith(f"crlam {argv[0]}") and ": error: " in line]
    assert len(errors) == 1, err
