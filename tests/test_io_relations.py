"""Tests of the relations files (crlam.io.relations)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from crlam.errors import DataFormatError
from crlam.io import (
    DATASETS,
    Relations,
    data_root,
    read_relations,
    read_scans,
    write_relations,
)


def real(relative: str) -> Path:
    root = data_root()
    if root is None:
        pytest.skip("real datasets not found: set CRLAM_DATA to the data folder (default ../shared/data beside the repository)")
    path = root / relative
    if not path.exists():
        pytest.skip(f"dataset file {path} is missing")
    return path


def test_parse(tmp_path: Path) -> None:
    p = tmp_path / "r.relations"
    p.write_text("# comment\n90.239599 90.719599 0.422330 -0.000750 0.000000 0.000000 0.000000 0.017260\n\n1 2 3 4 0 0 0 -0.5\n")
    rel = read_relations(p)
    assert isinstance(rel, Relations) and len(rel) == 2
    np.testing.assert_array_equal(rel.t1, [90.239599, 1.0])
    np.testing.assert_array_equal(rel.t2, [90.719599, 2.0])
    np.testing.assert_array_equal(rel.delta, [[0.422330, -0.000750, 0.017260], [3, 4, -0.5]])


@settings(max_examples=50, deadline=None)
@given(n=st.integers(1, 30), data=st.data())
def test_round_trip(tmp_path_factory: pytest.TempPathFactory, n: int, data: st.DataObject) -> None:
    t1 = data.draw(arrays(np.float64, n, elements=st.floats(0, 1e9)))
    t2 = data.draw(arrays(np.float64, n, elements=st.floats(0, 1e9)))
    delta = data.draw(arrays(np.float64, (n, 3), elements=st.floats(-100, 100)))
    p = tmp_path_factory.mktemp("rel") / "x.relations"
    write_relations(p, t1, t2, delta)
    rel = read_relations(p)
    np.testing.assert_allclose(rel.t1, t1, rtol=0, atol=1e-6)
    np.testing.assert_allclose(rel.t2, t2, rtol=0, atol=1e-6)
    np.testing.assert_allclose(rel.delta, delta, rtol=0, atol=5.1e-7)


BAD = {
    "short": ("1 2 3 4 0 0 0", "yaw"),
    "long": ("1 2 3 4 0 0 0 1 1", "n_fields"),
    "text": ("1 2 3 four 0 0 0 1", "y"),
    "nan": ("1 nan 3 4 0 0 0 1", "t2"),
    "non_planar": ("1 2 3 4 0 0.1 0 1", "roll"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_malformed(tmp_path: Path, case: str) -> None:
    line, field = BAD[case]
    p = tmp_path / "bad.relations"
    p.write_text(f"1 2 3 4 0 0 0 1\n{line}\n")
    with pytest.raises(DataFormatError) as info:
        read_relations(p)
    msg = str(info.value)
    assert str(p) in msg and "line 2" in msg and f"field {field}" in msg, msg


def test_empty(tmp_path: Path) -> None:
    p = tmp_path / "e.relations"
    p.write_text("\n# nothing\n")
    with pytest.raises(DataFormatError, match="no relations"):
        read_relations(p)


@pytest.mark.realdata
@pytest.mark.parametrize(
    ("log", "relations", "n"),
    [
        ("aces", "aces-relations", 1279),
        ("intel", "intel-relations", 2984),
    ],
)
def test_real_relations_match_flaser_stamps(log: str, relations: str, n: int) -> None:
    rel = read_relations(real(DATASETS[relations].relative_path))
    assert len(rel) == n
    stamps = {s.timestamp for s in read_scans(real(DATASETS[log].relative_path)) if s.kind == "FLASER"}
    assert set(rel.t1.tolist()) <= stamps and set(rel.t2.tolist()) <= stamps
