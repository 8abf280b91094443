"""Hypothesis fuzzing of the bag readers (issue 49): the recorded bags of the shared data folder
(``bags/``, skipped with a reason when absent) and a synthetic ROS 2 bag folder (always), cut
short, with bytes flipped, inserted or deleted, and with their ``metadata.yaml`` edited (values
replaced by hostile ones, keys dropped, file names pointed elsewhere). Every mutant must read, or
end in a :class:`crlam.errors.CrlamError` that names the bag: no other exception, no hang, no file
read outside the bag's folder. Readings stop after the first 400 records (the mutated bytes of a
chunk are met when the chunk is opened). ``CRLAM_FUZZ_EXAMPLES`` scales the examples (default:
25 per test, about 15 s for the file on 2 cores)."""

from __future__ import annotations

import itertools
import os
import shutil
import tempfile
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from bag_messages import write_mutated
from crlam.errors import CrlamError
from crlam.io import open_log
from test_io_rosbag import BagSpec

EXAMPLES = max(1, int(os.environ.get("CRLAM_FUZZ_EXAMPLES", "150")) // 6)
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large, HealthCheck.function_scoped_fixture],
    derandomize=True,  # the same mutants on every run: a failure in CI reproduces
)

#: Byte mutations: (kind, position as a fraction of the file, value). Kinds: 0 flip a byte,
#: 1 insert one, 2 delete one, 3 cut the file there.
BYTE_OPS = st.lists(st.tuples(st.integers(0, 3), st.floats(0.0, 1.0), st.integers(1, 255)), min_size=1, max_size=5)

#: Values a lying metadata.yaml puts in place of a field's.
HOSTILE_VALUES = st.one_of(
    st.sampled_from(
        [None, "", 0, -1, 99, 2**63, 1e308, float("nan"), [], {}, [None], "../../etc/passwd", "/etc/passwd", "ros1", "zstd"]
    ),
    st.text(max_size=20),
    st.integers(),
)


def _apply(data: bytes, ops: list[tuple[int, float, int]]) -> bytes:
    b = bytearray(data)
    for kind, where, value in ops:
        if not b:
            break
        i = min(int(where * len(b)), len(b) - 1)
        if kind == 0:
            b[i] ^= value
        elif kind == 1:
            b.insert(i, value)
        elif kind == 2:
            del b[i]
        else:
            del b[i:]
    return bytes(b)


def _read_some(path: Path) -> None:
    """Read the first 400 records; a CrlamError must name the bag."""
    try:
        for _ in itertools.islice(open_log(path), 400):
            pass
    except CrlamError as e:
        assert path.name in str(e), e


def _shared_bags(data_dir: Path) -> dict[str, Path]:
    bags = {p.name: p for p in sorted((data_dir / "bags").glob("*")) if p.suffix == ".bag" or (p / "metadata.yaml").is_file()}
    if not bags:
        pytest.skip(f"no ROS bags in {data_dir / 'bags'}")
    return bags


def _bag_file(bag: Path) -> Path:
    """The data file of a bag: itself, or the first file its folder's metadata names."""
    if bag.is_file():
        return bag
    names = yaml.safe_load((bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]["relative_file_paths"]
    return bag / names[0]


@pytest.fixture(scope="module")
def synthetic_folder() -> Path:
    """A ROS 2 bag folder (sqlite3) of the ROS bag tests' synthetic robot."""
    root = Path(tempfile.mkdtemp(prefix="crlam-fuzz-bags-"))
    return write_mutated(root / "synthetic", BagSpec(n_scans=6), storage="sqlite3", folder=True)


def _copy(bag: Path) -> Path:
    dst = Path(tempfile.mkdtemp(prefix="crlam-fuzz-")) / bag.name
    shutil.copytree(bag, dst) if bag.is_dir() else shutil.copy(bag, dst)
    return dst


def _mutate_bytes_and_read(bag: Path, ops: list[tuple[int, float, int]]) -> None:
    copy = _copy(bag)
    try:
        target = _bag_file(copy)
        target.write_bytes(_apply(target.read_bytes(), ops))
        _read_some(copy)
    finally:
        shutil.rmtree(copy.parent, ignore_errors=True)


def _edit_metadata_and_read(bag: Path, edits: list[tuple[int, Any, bool]]) -> None:
    copy = _copy(bag)
    try:
        meta = copy / "metadata.yaml"
        doc = yaml.safe_load(meta.read_text())
        info = doc["rosbag2_bagfile_information"]
        # The fields and a few nested ones (file names, topics).
        slots: list[tuple[Any, Any]] = [(info, k) for k in sorted(info)]
        slots += [(info["relative_file_paths"], i) for i in range(len(info["relative_file_paths"]))]
        for topic in info.get("topics_with_message_count", [])[:3]:
            slots += [(topic["topic_metadata"], k) for k in sorted(topic["topic_metadata"])]
        for index, value, drop in edits:
            container, key = slots[index % len(slots)]
            if drop and isinstance(container, dict):
                container.pop(key, None)
            else:
                container[key] = value
        meta.write_text(yaml.safe_dump(doc))
        _read_some(copy)
    finally:
        shutil.rmtree(copy.parent, ignore_errors=True)


METADATA_EDITS = st.lists(st.tuples(st.integers(0, 10_000), HOSTILE_VALUES, st.booleans()), min_size=1, max_size=4)


@FUZZ
@given(ops=BYTE_OPS)
def test_mutated_synthetic_bag_folder_reads_or_fails_cleanly(synthetic_folder: Path, ops: Any) -> None:
    _mutate_bytes_and_read(synthetic_folder, ops)


@FUZZ
@given(edits=METADATA_EDITS)
def test_synthetic_bag_with_edited_metadata_reads_or_fails_cleanly(synthetic_folder: Path, edits: Any) -> None:
    _edit_metadata_and_read(synthetic_folder, edits)


@FUZZ
@given(data=st.data(), ops=BYTE_OPS)
def test_mutated_recorded_bags_read_or_fail_cleanly(data_dir: Path, data: st.DataObject, ops: Any) -> None:
    bags = _shared_bags(data_dir)
    name = data.draw(st.sampled_from(sorted(bags)), label="bag")
    _mutate_bytes_and_read(bags[name], ops)


@FUZZ
@given(data=st.data(), edits=METADATA_EDITS)
def test_recorded_bag_folders_with_edited_metadata_read_or_fail_cleanly(data_dir: Path, data: st.DataObject, edits: Any) -> None:
    folders = {n: p for n, p in _shared_bags(data_dir).items() if p.is_dir()}
    if not folders:
        pytest.skip("no ROS 2 bag folder among the shared bags")
    name = data.draw(st.sampled_from(sorted(folders)), label="bag")
    _edit_metadata_and_read(folders[name], edits)
