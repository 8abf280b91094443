"""Resource limits (crlam.limits): the inputs of issue 31 that exhausted memory or aborted the
process are refused before anything is allocated, with an error naming the input, the limit and
how to raise it; the smaller findings of the same campaign are errors too."""

from __future__ import annotations

import io
import os
import struct
import subprocess
import sys
import zipfile
import zlib
from collections.abc import Iterator
from dataclasses import fields
from pathlib import Path
from typing import IO

import numpy as np
import pytest

from crlam import _native
from crlam.cli import main
from crlam.errors import ConfigError, CrlamError, DataFormatError, NumericalError, ResourceLimitError
from crlam.limits import DEFAULTS, Limits, env_name, limits, set_limits


@pytest.fixture(autouse=True)
def _default_limits() -> Iterator[None]:
    """Every test starts and ends with the default limits (set_limits also sets the environment)."""
    saved = {f.name: os.environ.get(env_name(f.name)) for f in fields(Limits)}
    set_limits(**{f.name: getattr(DEFAULTS, f.name) for f in fields(Limits)})
    yield
    set_limits(**{f.name: getattr(DEFAULTS, f.name) for f in fields(Limits)})
    for name, value in saved.items():
        if value is None:
            os.environ.pop(env_name(name), None)
        else:
            os.environ[env_name(name)] = value


def _flaser_log(path: Path, positions: list[tuple[float, float]]) -> Path:
    ranges = " ".join(["3.0"] * 180)
    path.write_text("".join(f"FLASER 180 {ranges} {x} {y} 0 {x} {y} 0 {i}.0 host {i}.0\n" for i, (x, y) in enumerate(positions)))
    return path


def _cli_error(argv: list[str], capsys: pytest.CaptureFixture[str]) -> str:
    """Runs the CLI, expects exit status 2 and one error line; returns it."""
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert err and err[-1].startswith(f"crlam {argv[0]}: error: "), err
    return err[-1]


def _assert_limit_message(message: str, flag: str) -> None:
    assert "limit" in message and flag in message and "CRLAM_MAX_" in message, message


# ------------------------------------------------------------------ issue 31, finding 1


def test_a_pose_far_from_the_others_is_refused_before_the_map_grows(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = _flaser_log(tmp_path / "far.log", [(0.0, 0.0), (1.0, 0.0), (2000.0, 2000.0)])
    msg = _cli_error(["map", str(log), "--out", str(tmp_path / "out"), "--quiet"], capsys)
    _assert_limit_message(msg, "--max-map-cells")
    assert "map of" in msg and "cells" in msg
    assert not (tmp_path / "out" / "map.pgm").exists()


def test_a_tiny_cell_size_is_refused_before_the_first_scan_is_mapped(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = _flaser_log(tmp_path / "a.log", [(0.0, 0.0), (0.5, 0.0)])
    msg = _cli_error(["map", str(log), "--out", str(tmp_path / "out"), "--quiet", "--resolution", "0.001"], capsys)
    _assert_limit_message(msg, "--max-map-cells")
    assert "0.001 m cells" in msg


def test_raising_the_limit_on_the_command_line_lets_the_input_through(tmp_path: Path) -> None:
    log = _flaser_log(tmp_path / "a.log", [(0.0, 0.0), (60.0, 0.0)])
    assert main(["map", str(log), "--out", str(tmp_path / "small"), "--quiet", "--max-map-cells", "1000"]) == 2
    assert main(["map", str(log), "--out", str(tmp_path / "big"), "--quiet", "--max-map-cells", "1e6"]) == 0
    assert limits().map_cells == 10**6
    assert (tmp_path / "big" / "map.pgm").is_file()


def test_a_map_yaml_with_a_tiny_resolution_is_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from crlam.io.nav2 import write_pgm

    write_pgm(tmp_path / "m.pgm", np.full((100, 100), 254, dtype=np.uint8))
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 1e-4\norigin: [0, 0, 0]\n")
    msg = _cli_error(["info", str(tmp_path / "m.yaml"), "--function", "crmi", "--out", str(tmp_path / "o")], capsys)
    _assert_limit_message(msg, "--max-map-cells")


def _png_header_only(path: Path, width: int, height: int) -> Path:
    """A small PNG file that declares ``width x height`` pixels (its data is not decodable)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 8, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 1000)) + chunk(b"IEND", b"")
    )
    return path


@pytest.mark.parametrize("command", ["explore", "simulate"])
def test_a_huge_image_is_refused_before_it_is_decoded(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch, command: str
) -> None:
    from PIL import ImageFile

    png = _png_header_only(tmp_path / "big.png", 9000, 9000)
    (tmp_path / "big.yaml").write_text("image: big.png\nresolution: 0.05\norigin: [0, 0, 0]\n")
    decoded: list[str] = []
    original_load = ImageFile.ImageFile.load

    def load(self: ImageFile.ImageFile) -> object:  # counts decodes instead of timing them
        decoded.append(str(self.size))
        return original_load(self)

    monkeypatch.setattr(ImageFile.ImageFile, "load", load)
    # A bare image (read by the simulator's reader) and a Nav2 map (read by crlam.io.nav2).
    world = [str(png), "--resolution", "0.05"] if command == "explore" else [str(tmp_path / "big.yaml")]
    msg = _cli_error([command, "--world", *world, "--out", str(tmp_path / "o"), "--quiet"], capsys)
    assert decoded == [], decoded
    _assert_limit_message(msg, "--max-image-pixels")
    assert "81,000,000 pixels" in msg


def test_a_procedural_world_on_tiny_cells_is_refused_before_it_is_drawn(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    msg = _cli_error(["explore", "--world", "office", "--resolution", "0.0001", "--out", str(tmp_path / "o"), "--quiet"], capsys)
    _assert_limit_message(msg, "--max-map-cells")
    assert "world at 0.0001 m cells" in msg


def test_a_huge_simulation_is_refused_before_it_starts(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    msg = _cli_error(["simulate", "--scans", "100000000", "--out", str(tmp_path / "o"), "--quiet"], capsys)
    assert not (tmp_path / "o").exists()  # refused before the world is drawn or a scan simulated
    _assert_limit_message(msg, "--max-readings")


def test_a_huge_pgm_header_is_refused_before_its_raster_is_read(tmp_path: Path) -> None:
    from crlam.io.nav2 import read_pgm
    from crlam.sim.world import read_pgm as read_world_pgm

    p = tmp_path / "big.pgm"
    p.write_bytes(b"P5\n20000 20000\n255\n" + bytes(100))
    for reader in (read_pgm, read_world_pgm):
        with pytest.raises(ResourceLimitError, match="20000 x 20000"):
            reader(p)


def test_particle_counts_above_the_limit_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    log = _flaser_log(tmp_path / "a.log", [(0.0, 0.0), (0.5, 0.0)])
    msg = _cli_error(["slam", str(log), "--out", str(tmp_path / "o"), "--quiet", "--particles", "100000000"], capsys)
    _assert_limit_message(msg, "--max-particles")
    model = _native.SensorModel()
    with pytest.raises(ResourceLimitError, match="particles"):
        _native.ClamFilter(np.zeros(3), model, model, n_particles=10**8)
    set_limits(particles=10)
    with pytest.raises(ResourceLimitError, match="limit of 10"):
        _native.ClamFilter(np.zeros(3), model, model, n_particles=11)


def test_dense_copies_of_huge_rectangles_are_refused() -> None:
    m = _native.CrmMap(0.2)
    with pytest.raises(ResourceLimitError, match="--max-map-cells"):
        m.beliefs((0, 0, 100000, 100000))
    with pytest.raises(ResourceLimitError):
        m.derived_maps((0, 0, 100000, 100000))
    with pytest.raises(ResourceLimitError):
        _native.LogOddsMap(0.2).log_odds((0, 0, 100000, 100000))
    with pytest.raises(ResourceLimitError):
        _native.CrmMap(0.2, extent=(0, 0, 100000, 100000))
    with pytest.raises(ResourceLimitError):
        _native.traverse_ray(0.0, 0.0, 0.0, 1e6, 1e-6)
    assert m.beliefs((0, 0, 3, 2)).shape == (2, 3, 10)


def test_limits_reach_the_core_through_the_environment_of_a_new_process() -> None:
    code = "import crlam._native as n; from crlam.limits import limits; print(n.set_limits(), limits().image_pixels)"
    env = {**os.environ, "CRLAM_MAX_MAP_CELLS": "1234", "CRLAM_MAX_PARTICLES": "1e3", "CRLAM_MAX_IMAGE_PIXELS": "99"}
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout
    assert out.split() == ["(1234,", "1000)", "99"]
    bad = subprocess.run(
        [sys.executable, "-c", "import crlam"], env={**os.environ, "CRLAM_MAX_MAP_CELLS": "lots"}, capture_output=True, text=True
    )
    assert bad.returncode != 0 and "CRLAM_MAX_MAP_CELLS" in bad.stderr


def test_limit_values_are_checked() -> None:
    for bad in ("0", "-5", "1.5", "nan", "x"):
        with pytest.raises(ConfigError):
            set_limits(map_cells=bad)
    with pytest.raises(ConfigError, match="unknown"):
        set_limits(cells=5)
    assert set_limits(map_cells="2e7").map_cells == 20_000_000
    assert _native.set_limits()[0] == 20_000_000


# ------------------------------------------------------------------ issue 31, finding 4: belief.npz


def _belief(tmp_path: Path, name: str = "b.npz"):  # type: ignore[no-untyped-def]
    from crlam.mapping import ConfidenceRichMap, MappingConfig

    crm = ConfidenceRichMap(MappingConfig(resolution=0.5))
    crm.update(np.zeros(3), np.linspace(-1, 1, 30), np.full(30, 3.0))
    return crm.to_archive()


def _write_npz(path: Path, arrays: dict[str, np.ndarray], headers: dict[str, tuple[tuple[int, ...], str]] | None = None) -> Path:
    """An .npz whose members are the arrays, except those in ``headers``: a header declaring
    (shape, dtype) followed by a few bytes (a lying header)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as z:
        for name, a in arrays.items():
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.asarray(a), allow_pickle=False)
            z.writestr(name + ".npy", buf.getvalue())
        for name, (shape, descr) in (headers or {}).items():
            buf = io.BytesIO()
            np.lib.format.write_array_header_1_0(buf, {"descr": descr, "fortran_order": False, "shape": shape})
            z.writestr(name + ".npy", buf.getvalue() + bytes(64))
    return path


def _archive_arrays(archive) -> dict[str, np.ndarray]:  # type: ignore[no-untyped-def]
    import json

    from crlam.io.belief import FORMAT_NAME, FORMAT_VERSION

    return {
        "format": np.array(FORMAT_NAME),
        "format_version": np.array(FORMAT_VERSION, dtype=np.int64),
        "beliefs": archive.beliefs,
        "levels": archive.levels,
        "origin": archive.origin,
        "resolution": np.array(archive.resolution),
        "metadata": np.array(json.dumps(archive.metadata)),
    }


def test_a_zip_bomb_belief_is_refused_before_it_is_decompressed(tmp_path: Path) -> None:
    from crlam.io.belief import load_belief

    arrays = _archive_arrays(_belief(tmp_path))
    arrays["beliefs"] = np.zeros((1000, 2500, 10), dtype=np.float32)  # 100 MB of zeros, ~100 KB compressed
    bomb = _write_npz(tmp_path / "bomb.npz", arrays)
    assert bomb.stat().st_size < 1_000_000
    set_limits(archive_bytes=10_000_000)
    with pytest.raises(ResourceLimitError, match="--max-archive-bytes"):
        load_belief(bomb)
    set_limits(archive_bytes=DEFAULTS.archive_bytes, map_cells=1_000_000)
    with pytest.raises(ResourceLimitError, match="1000 x 2500 cells"):
        load_belief(bomb)


def test_an_array_header_claiming_more_than_its_member_holds_is_refused(tmp_path: Path) -> None:
    from crlam.io.belief import load_belief
    from crlam.planner import IigTree

    arrays = _archive_arrays(_belief(tmp_path))
    del arrays["beliefs"]
    p = _write_npz(tmp_path / "lie.npz", arrays, {"beliefs": ((3000, 3000, 10), "<f4")})
    with pytest.raises(DataFormatError, match="header declares"):
        load_belief(p)
    p = _write_npz(tmp_path / "tree.npz", {"meta": np.array("{}")}, {"positions": ((10**6, 10**6), "<f8")})
    with pytest.raises(CrlamError, match="header declares|--max-archive-bytes"):
        IigTree.load(p)


def test_a_belief_whose_stored_configuration_has_another_resolution_is_refused(tmp_path: Path) -> None:
    import json

    from crlam.io.belief import load_belief, save_belief
    from crlam.mapping import ConfidenceRichMap, MappingConfig

    archive = _belief(tmp_path)
    assert archive.resolution == 0.5
    good = tmp_path / "good.npz"
    save_belief(good, archive)
    assert ConfidenceRichMap.from_archive(load_belief(good)).config.resolution == 0.5
    cfg = json.loads(str(archive.metadata["config_json"]))
    archive.metadata["config_json"] = json.dumps({**cfg, "resolution": 0.2})
    save_belief(tmp_path / "bad.npz", archive)
    with pytest.raises(ConfigError, match="0.5 m.*resolution 0.2"):
        ConfidenceRichMap.from_archive(load_belief(tmp_path / "bad.npz"))
    with pytest.raises(ConfigError, match="resolution"):
        ConfidenceRichMap.from_archive(load_belief(good), MappingConfig(resolution=0.25))


# ------------------------------------------------------------------ issue 31, findings 5 and 6


def test_set_beliefs_at_extreme_cells_is_an_error_not_a_panic() -> None:
    m = _native.CrmMap(0.2)
    pmf = np.full((1, 1, 10), 0.1)
    for ix0 in (2**63 - 1, -(2**63), 2**46 + 1):
        with pytest.raises(CrlamError):
            m.set_beliefs(ix0, 0, pmf)
    m.set_beliefs(5, -7, pmf)
    assert m.cell(5, -7).shape == (10,)


def test_cell_of_a_non_finite_or_far_point_is_an_error() -> None:
    m = _native.CrmMap(0.2)
    with pytest.raises(NumericalError):
        m.cell_of(float("nan"), 0.0)
    with pytest.raises(NumericalError):
        m.cell_of(0.0, float("inf"))
    with pytest.raises(CrlamError):
        m.cell_of(1e300, 0.0)
    assert m.cell_of(-0.1, 0.3) == (-1, 1)


def test_a_download_that_sends_more_than_expected_is_stopped_at_once(tmp_path: Path) -> None:
    from crlam.io.fetch import ChecksumError, download

    read: list[int] = []

    def counting(url: str, timeout: float) -> IO[bytes]:
        """/dev/zero, counting the bytes the download reads from it (counted, not timed)."""
        stream = open("/dev/zero", "rb")  # noqa: SIM115 - closed by the download
        real_read = stream.read

        def read_counted(n: int = -1) -> bytes:
            block = real_read(n)
            read.append(len(block))
            return block

        stream.read = read_counted  # type: ignore[method-assign]
        return stream

    with pytest.raises(ChecksumError, match="expected 1,000"):
        download("file:///dev/zero", tmp_path / "z", sha256="0" * 64, size=1000, progress=False, opener=counting)
    assert sum(read) <= 1000 + (1 << 16)  # at most one read past the announced size
    read.clear()
    set_limits(download_bytes=100_000)
    with pytest.raises(ResourceLimitError, match="--max-download-bytes"):
        download("file:///dev/zero", tmp_path / "z", sha256="0" * 64, progress=False, opener=counting)
    assert sum(read) <= 100_000 + (1 << 16)  # at most one read past the limit
    assert list(tmp_path.iterdir()) == []


def test_an_experiment_with_no_function_is_an_error(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    _cli_error(["experiment", "iig", "--functions", ",", "--out", str(tmp_path / "o"), "--quiet"], capsys)
    _cli_error(["experiment", "explore", "--functions", ",", "--out", str(tmp_path / "o2"), "--quiet"], capsys)


def test_an_iig_start_inside_an_obstacle_is_an_error(tmp_path: Path) -> None:
    from crlam.info import load_map_prior, make_function
    from crlam.io.nav2 import write_pgm
    from crlam.planner import IigSettings, plan_iig

    img = np.full((40, 40), 255, dtype=np.uint8)
    img[10:30, 10:30] = 0  # an obstacle block in the middle (rows from the top)
    write_pgm(tmp_path / "m.pgm", img)
    prior = load_map_prior(tmp_path / "m.pgm")
    with pytest.raises(ConfigError, match="inside an obstacle"):
        plan_iig(make_function("crmi"), prior, IigSettings(start=(4.0, 4.0)))
    with pytest.raises(ConfigError, match="outside the map"):
        plan_iig(make_function("crmi"), prior, IigSettings(start=(-50.0, 4.0)))
    with pytest.raises(ConfigError, match="finite"):
        plan_iig(make_function("crmi"), prior, IigSettings(start=(float("nan"), 4.0)))


def test_duplicate_stamps_with_different_poses_in_an_estimate_are_an_error() -> None:
    from crlam.eval.trajectory import reference_errors

    ref_t, ref_p = np.arange(3.0), np.zeros((3, 3))
    est_p = np.array([[0.0, 0, 0], [1.0, 0, 0], [0.5, 0, 0]])
    with pytest.raises(DataFormatError, match="more than once"):
        reference_errors([0.0, 1.0, 1.0], est_p, ref_t, ref_p)
    r = reference_errors([0.0, 1.0, 1.0], np.array([[0.0, 0, 0], [1.0, 0, 0], [1.0, 0, 0]]), ref_t, ref_p)
    assert r.stamps.tolist() == [0.0, 1.0]


def test_inverted_nav2_thresholds_are_an_error(tmp_path: Path) -> None:
    from crlam.io.nav2 import read_nav2_map, write_pgm

    write_pgm(tmp_path / "m.pgm", np.full((4, 4), 254, dtype=np.uint8))
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\noccupied_thresh: 0.1\nfree_thresh: 0.6\n")
    with pytest.raises(DataFormatError, match="free_thresh <= occupied_thresh") as info:
        read_nav2_map(tmp_path / "m.yaml")
    assert str(info.value).count("free_thresh") >= 1 and "(field free_thresh)" in str(info.value)


def test_logs_with_carriage_return_line_endings_are_read(tmp_path: Path) -> None:
    from crlam.io.carmen import read_scans
    from crlam.io.relations import read_relations
    from crlam.io.tum import read_tum

    unix = _flaser_log(tmp_path / "unix.log", [(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)])
    cr = tmp_path / "cr.log"
    cr.write_bytes(unix.read_bytes().replace(b"\n", b"\r"))
    assert len(list(read_scans(cr))) == 3
    (tmp_path / "t.tum").write_bytes(b"1.0 0 0 0 0 0 0 1\r2.0 1 0 0 0 0 0 1\r")
    assert len(read_tum(tmp_path / "t.tum")) == 2
    (tmp_path / "r.relations").write_bytes(b"1.0 2.0 1 0 0 0 0 0\r2.0 3.0 1 0 0 0 0 0\r")
    assert len(read_relations(tmp_path / "r.relations").t1) == 2


def test_a_file_without_line_breaks_is_an_error_not_read_whole(tmp_path: Path) -> None:
    from crlam.io.carmen import read_scans

    big = tmp_path / "blob.log"
    big.write_bytes(b"x" * (3 << 20))
    with pytest.raises(DataFormatError, match="line longer than"):
        list(read_scans(big))
    if Path("/dev/zero").exists():
        with pytest.raises(DataFormatError, match="not a regular file"):
            list(read_scans("/dev/zero"))
