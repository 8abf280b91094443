"""Property-based fuzzing of every parser of user files (Hypothesis): CARMEN logs, TUM
trajectories, relations, PGM images, Nav2 map YAML, belief.npz archives and ROS bags (ROS 1 .bag,
ROS 2 MCAP). Each gets inputs built from its grammar with hostile values and the bytes of a valid
file mutated (bytes flipped, inserted, deleted, truncated). A parser may return records or raise a
:class:`crlam.errors.CrlamError` (``DataFormatError``, ``ConfigError``, ``ResourceLimitError``);
any other exception, and records that break the documented invariants, fail. Every file is small,
so the suite runs in well under a minute; ``CRLAM_FUZZ_EXAMPLES`` sets the examples per parser
(150 by default) for a deeper run."""

from __future__ import annotations

import io
import json
import math
import os
import tempfile
import zipfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from crlam.errors import CrlamError

#: Examples per parser: 150 in CI (about a minute for the whole file); CRLAM_FUZZ_EXAMPLES=5000 for a deep run.
FUZZ = settings(
    max_examples=int(os.environ.get("CRLAM_FUZZ_EXAMPLES", "150")),
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)

NUMBER_TOKENS = st.sampled_from(
    ["0", "-0", "1", "-1", "0.5", "1e308", "-1e308", "1e-320", "nan", "inf", "-inf", "NaN", "1e999", "9" * 30, "0x10", "1_0", ""]
)
WORD_TOKENS = st.sampled_from(["FLASER", "RLASER", "ODOM", "ROBOTLASER1", "PARAM", "#", "host", "\x00", "é", "FLASER\x00"])
TOKENS = st.one_of(NUMBER_TOKENS, WORD_TOKENS, st.integers(-(2**70), 2**70).map(str), st.floats().map(repr))
ENDINGS = st.sampled_from(["\n", "\r\n", "\r"])


def _lines(first_words: list[str], max_tokens: int = 200) -> st.SearchStrategy[str]:
    line = st.tuples(st.sampled_from(first_words), st.lists(TOKENS, max_size=max_tokens), ENDINGS).map(
        lambda t: " ".join([t[0], *t[1]]) + t[2]
    )
    return st.lists(line, max_size=8).map("".join)


def _mutations(data: bytes) -> st.SearchStrategy[bytes]:
    """The bytes of a valid file with a few of them flipped, inserted or deleted, or truncated."""

    def apply(ops: list[tuple[int, int, int]]) -> bytes:
        b = bytearray(data)
        for kind, pos, value in ops:
            if not b:
                break
            i = pos % len(b)
            if kind == 0:
                b[i] ^= 1 << (value % 8)
            elif kind == 1:
                b.insert(i, value % 256)
            elif kind == 2:
                del b[i]
            else:
                del b[i:]
        return bytes(b)

    op = st.tuples(st.integers(0, 3), st.integers(0, 2**31), st.integers(0, 255))
    return st.lists(op, min_size=1, max_size=6).map(apply)


def _tmp_file(data: bytes, name: str) -> Path:
    d = Path(tempfile.mkdtemp(prefix="crlam-fuzz-"))
    p = d / name
    p.write_bytes(data)
    return p


def _only_crlam_errors(fn: Callable[[], Any]) -> Any:
    try:
        return fn()
    except CrlamError:
        return None


# ------------------------------------------------------------------ CARMEN


def _valid_carmen() -> bytes:
    ranges = " ".join(f"{1.0 + 0.01 * i:.2f}" for i in range(180))
    lines = ["PARAM robot_frontlaser_offset 0.1", "ODOM 0 0 0 0 0 0 1.0 host 1.0"]
    lines += [f"FLASER 180 {ranges} {0.1 * i} 0 0.1 {0.1 * i} 0 0.1 {2.0 + i} host {2.0 + i}" for i in range(3)]
    return ("\n".join(lines) + "\n").encode()


def _read_carmen_all(path: Path, on_error: str) -> list[Any]:
    from crlam.io.carmen import read_carmen

    return list(read_carmen(path, on_error=on_error))  # type: ignore[arg-type]


def _check_carmen_records(records: list[Any] | None) -> None:
    from crlam.io.carmen import LaserScan

    for r in records or []:
        if isinstance(r, LaserScan):
            assert r.ranges.shape == r.angles.shape and r.ranges.ndim == 1
            assert np.all(np.isfinite(r.angles))
            assert np.all(np.isfinite(r.pose)) and np.all(np.isfinite(r.odom))
            assert math.isfinite(r.timestamp)


@FUZZ
@given(text=_lines(["FLASER", "RLASER", "ODOM", "ROBOTLASER1", "PARAM", "#"]), on_error=st.sampled_from(["raise", "skip"]))
def test_carmen_grammar_fuzz(text: str, on_error: str) -> None:
    path = _tmp_file(text.encode("utf-8", "surrogatepass"), "log.clf")
    _check_carmen_records(_only_crlam_errors(lambda: _read_carmen_all(path, on_error)))


@FUZZ
@given(data=_mutations(_valid_carmen()), compress=st.sampled_from(["", "gz", "bz2"]))
def test_carmen_mutation_fuzz(data: bytes, compress: str) -> None:
    import bz2
    import gzip

    if compress == "gz":
        data = gzip.compress(data)
    elif compress == "bz2":
        data = bz2.compress(data)
    path = _tmp_file(data, "log.clf" + (f".{compress}" if compress else ""))
    _check_carmen_records(_only_crlam_errors(lambda: _read_carmen_all(path, "skip")))


@FUZZ
@given(data=_mutations(_valid_carmen()).map(lambda b: __import__("gzip").compress(b)).flatmap(_mutations))
def test_corrupt_compressed_carmen_fuzz(data: bytes) -> None:
    path = _tmp_file(data, "log.clf.gz")
    _check_carmen_records(_only_crlam_errors(lambda: _read_carmen_all(path, "raise")))


# ------------------------------------------------------------------ TUM and relations


def _valid_tum() -> bytes:
    return b"# t x y z qx qy qz qw\n" + b"".join(f"{i}.5 {i} 0 0 0 0 0 1\n".encode() for i in range(4))


@FUZZ
@given(text=_lines(["1.0", "2", "#", "nan", "1e308"], max_tokens=10))
def test_tum_grammar_fuzz(text: str) -> None:
    from crlam.io.tum import read_tum

    path = _tmp_file(text.encode("utf-8", "surrogatepass"), "t.tum")
    traj = _only_crlam_errors(lambda: read_tum(path))
    if traj is not None:
        assert traj.poses.shape == (len(traj.timestamps), 3)
        assert np.all(np.isfinite(traj.poses)) and np.all(np.isfinite(traj.timestamps))


@FUZZ
@given(data=_mutations(_valid_tum()))
def test_tum_mutation_fuzz(data: bytes) -> None:
    from crlam.io.tum import read_tum

    path = _tmp_file(data, "t.tum")
    _only_crlam_errors(lambda: read_tum(path))


@FUZZ
@given(text=_lines(["1.0", "2", "#", "nan"], max_tokens=10))
def test_relations_grammar_fuzz(text: str) -> None:
    from crlam.io.relations import read_relations

    path = _tmp_file(text.encode("utf-8", "surrogatepass"), "r.relations")
    rel = _only_crlam_errors(lambda: read_relations(path))
    if rel is not None:
        assert len(rel.t1) == len(rel.t2) and np.all(np.isfinite(rel.t1)) and np.all(np.isfinite(rel.t2))


@FUZZ
@given(data=_mutations(b"1.0 2.0 1 0 0 0 0 0.1\n2.0 3.0 0.5 0.1 0 0 0 0\n"))
def test_relations_mutation_fuzz(data: bytes) -> None:
    from crlam.io.relations import read_relations

    path = _tmp_file(data, "r.relations")
    _only_crlam_errors(lambda: read_relations(path))


# ------------------------------------------------------------------ PGM and Nav2 YAML


def _pgm(width: int, height: int, maxval: int, magic: bytes, body: bytes) -> bytes:
    return magic + f"\n# c\n{width} {height}\n{maxval}\n".encode() + body


PGM = st.builds(
    _pgm,
    st.integers(-2, 40),
    st.integers(-2, 40),
    st.sampled_from([0, 1, 255, 256, 65535, 65536, 2**40]),
    st.sampled_from([b"P5", b"P2", b"P6", b""]),
    st.binary(max_size=4000),
)


@FUZZ
@given(data=st.one_of(PGM, _mutations(_pgm(8, 6, 255, b"P5", bytes(range(48))))))
def test_pgm_fuzz(data: bytes) -> None:
    from crlam.io.nav2 import read_pgm
    from crlam.sim.world import read_pgm as read_world_pgm

    path = _tmp_file(data, "m.pgm")
    for reader in (read_pgm, read_world_pgm):
        img = _only_crlam_errors(lambda reader=reader: reader(path))
        if img is not None:
            assert img.ndim == 2 and img.size > 0


YAML_VALUES = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(2**70), 2**70),
    st.floats(),
    st.text(max_size=10),
    st.lists(st.one_of(st.floats(), st.integers(), st.text(max_size=3)), max_size=4),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2),
)


@FUZZ
@given(
    doc=st.dictionaries(
        st.sampled_from(["image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode", "x"]),
        YAML_VALUES,
        max_size=8,
    ),
    image=st.sampled_from(["m.pgm", "missing.pgm", "", "/dev/null", "."]),
    raw=st.one_of(st.none(), st.binary(max_size=200)),
)
def test_nav2_yaml_fuzz(doc: dict[str, Any], image: str, raw: bytes | None) -> None:
    import yaml

    from crlam.io.nav2 import read_nav2_map

    d = Path(tempfile.mkdtemp(prefix="crlam-fuzz-"))
    (d / "m.pgm").write_bytes(_pgm(6, 5, 255, b"P5", bytes(range(30))))
    doc = {"image": image, **doc} if "image" not in doc else doc
    text = raw if raw is not None else yaml.safe_dump(doc).encode()
    (d / "map.yaml").write_bytes(text)
    m = _only_crlam_errors(lambda: read_nav2_map(d / "map.yaml"))
    if m is not None:
        assert m.occupancy.ndim == 2 and m.resolution > 0 and np.all(np.isfinite(m.origin))


# ------------------------------------------------------------------ belief.npz


def _valid_belief() -> bytes:
    from crlam.io.belief import save_belief
    from crlam.mapping import ConfidenceRichMap, MappingConfig

    crm = ConfidenceRichMap(MappingConfig(resolution=0.5))
    crm.update(np.zeros(3), np.linspace(-1, 1, 20), np.full(20, 2.0))
    p = Path(tempfile.mkdtemp(prefix="crlam-fuzz-")) / "b.npz"
    save_belief(p, crm.to_archive())
    return p.read_bytes()


VALID_BELIEF = _valid_belief()

ARRAYS = st.one_of(
    st.sampled_from(
        [
            np.array("crlam-belief"),
            np.array(1),
            np.array(2**40),
            np.array(0.2),
            np.array(-1.0),
            np.array(np.nan),
            np.zeros((2, 2, 10), np.float32),
            np.full((2, 2, 10), 0.1, np.float32),
            np.full((1, 1, 3), np.inf, np.float32),
            np.linspace(0.05, 0.95, 10),
            np.zeros(2),
            np.zeros((0, 3, 2), np.float32),
            np.array("{}"),
            np.array('{"config_json": "{\\"resolution\\": 7}"}'),
            np.array([b"bytes"]),
        ]
    ),
    st.builds(
        np.zeros, st.tuples(st.integers(0, 4), st.integers(0, 4), st.integers(0, 12)), st.sampled_from(["f4", "f8", "i4", "u1"])
    ),
)


def _npz(members: dict[str, np.ndarray]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        for name, a in members.items():
            b = io.BytesIO()
            np.lib.format.write_array(b, a, allow_pickle=False)
            z.writestr(name + ".npy", b.getvalue())
    return buf.getvalue()


@FUZZ
@given(
    data=st.one_of(
        _mutations(VALID_BELIEF),
        st.dictionaries(
            st.sampled_from(["format", "format_version", "beliefs", "levels", "origin", "resolution", "metadata", "x"]),
            ARRAYS,
            max_size=8,
        ).map(_npz),
    )
)
def test_belief_archive_fuzz(data: bytes) -> None:
    from crlam.io.belief import load_belief
    from crlam.mapping import ConfidenceRichMap

    path = _tmp_file(data, "belief.npz")
    archive = _only_crlam_errors(lambda: load_belief(path))
    if archive is not None:
        archive.validate()
        _only_crlam_errors(lambda: ConfidenceRichMap.from_archive(archive))


# ------------------------------------------------------------------ ROS bags


def _valid_bags() -> dict[str, bytes]:
    import sys

    sys.path.insert(0, str(Path(__file__).parent))
    from test_io_rosbag import BagSpec, write_bag  # the synthetic bags of the ROS bag tests

    d = Path(tempfile.mkdtemp(prefix="crlam-fuzz-"))
    spec = BagSpec(n_scans=4, static=[("base_link", "laser", (0.1, 0.0, 0.2), (0.0, 0.0, 0.0))])
    ros1 = write_bag(d / "a", spec, kind="ros1")
    from crlam.io.convert import carmen_to_bag

    log = d / "log.clf"
    log.write_bytes(_valid_carmen())
    carmen_to_bag(log, d / "b.mcap")
    return {".bag": ros1.read_bytes(), ".mcap": (d / "b.mcap").read_bytes()}


@pytest.fixture(scope="module")
def valid_bags() -> dict[str, bytes]:
    return _valid_bags()


@pytest.mark.parametrize("suffix", [".bag", ".mcap"])
def test_ros_bag_mutation_fuzz(suffix: str, valid_bags: dict[str, bytes]) -> None:
    from crlam.io.rosbag import read_bag

    original = valid_bags[suffix]
    assert len(list(read_bag(_tmp_file(original, "x" + suffix)))) > 0

    @FUZZ
    @given(data=_mutations(original))
    def fuzz(data: bytes) -> None:
        path = _tmp_file(data, "x" + suffix)
        records = _only_crlam_errors(lambda: list(read_bag(path)))
        _check_carmen_records(records)

    fuzz()


def test_fuzz_inputs_are_really_hostile() -> None:
    """The mutation strategy changes the bytes (a guard against a fuzz suite that tests nothing)."""
    seen: list[bytes] = []

    @settings(max_examples=20, deadline=None)
    @given(data=_mutations(_valid_tum()))
    def collect(data: bytes) -> None:
        seen.append(data)

    collect()
    assert sum(d != _valid_tum() for d in seen) >= 15
    assert json.loads(json.dumps({"n": len(seen)}))["n"] == 20
