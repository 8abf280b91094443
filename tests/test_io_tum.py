"""Tests of TUM trajectory files (crlam.io.tum)."""

from __future__ import annotations

import math
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from crlam.errors import DataFormatError
from crlam.io import Trajectory, read_tum, write_tum
from crlam.pose import wrap_angle


@settings(max_examples=80, deadline=None)
@given(n=st.integers(1, 50), data=st.data())
def test_round_trip(n: int, data: st.DataObject) -> None:
    stamps = data.draw(arrays(np.float64, n, elements=st.floats(0.0, 2e9)))
    xy = data.draw(arrays(np.float64, (n, 2), elements=st.floats(-1e4, 1e4)))
    theta = data.draw(arrays(np.float64, n, elements=st.floats(-math.pi, math.pi)))
    poses = np.column_stack([xy, theta])
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "traj.tum"
        write_tum(p, stamps, poses, header="estimate")
        first = p.read_bytes()
        write_tum(p, stamps, poses, header="estimate")
        assert p.read_bytes() == first
        traj = read_tum(p)
    assert len(traj) == n
    np.testing.assert_allclose(traj.timestamps, stamps, rtol=0, atol=1e-6)
    np.testing.assert_allclose(traj.poses[:, :2], xy, rtol=0, atol=1e-8)
    assert np.all(np.abs(wrap_angle(traj.poses[:, 2] - theta)) < 1e-8)
    assert np.all(traj.poses[:, 2] <= math.pi) and np.all(traj.poses[:, 2] > -math.pi)


def test_file_layout_and_evo_style_input(tmp_path: Path) -> None:
    p = tmp_path / "t.txt"
    write_tum(p, [1.5], [[1.0, -2.0, math.pi / 2]])
    tokens = p.read_text().split()
    assert len(tokens) == 8 and tokens[0] == "1.500000000" and tokens[3] == "0.000000000"
    assert float(tokens[6]) == pytest.approx(math.sqrt(0.5)) and float(tokens[7]) == pytest.approx(math.sqrt(0.5))
    # An evo/TUM file with comments, a non-zero z and a slightly unnormalised quaternion.
    q = math.sin(0.3), math.cos(0.3)
    p.write_text(f"# timestamp x y z qx qy qz qw\n\n10.0 1 2 0.5 0 0 {q[0] * 1.0001} {q[1] * 1.0001}\n")
    traj = read_tum(p)
    assert isinstance(traj, Trajectory)
    np.testing.assert_allclose(traj.poses, [[1.0, 2.0, 0.6]], atol=1e-12)


BAD = {
    "few_fields": ("1.0 2.0 3.0 0 0 0 1", "qw"),
    "many_fields": ("1.0 2.0 3.0 0 0 0 0 1 5", "n_fields"),
    "not_number": ("1.0 2.0 y 0 0 0 0 1", "y"),
    "nan_stamp": ("nan 2.0 3.0 0 0 0 0 1", "timestamp"),
    "tilted": ("1.0 2.0 3.0 0 0.2 0 0 0.98", "quaternion"),
    "not_unit": ("1.0 2.0 3.0 0 0 0 0 2", "quaternion"),
}


@pytest.mark.parametrize("case", sorted(BAD))
def test_malformed(tmp_path: Path, case: str) -> None:
    line, field = BAD[case]
    p = tmp_path / "bad.tum"
    p.write_text(f"# header\n0.0 0 0 0 0 0 0 1\n{line}\n")
    with pytest.raises(DataFormatError) as info:
        read_tum(p)
    msg = str(info.value)
    assert str(p) in msg and "line 3" in msg and f"field {field}" in msg, msg


def test_empty_and_bad_inputs(tmp_path: Path) -> None:
    p = tmp_path / "e.tum"
    p.write_text("# nothing\n")
    with pytest.raises(DataFormatError, match="no poses"):
        read_tum(p)
    with pytest.raises(DataFormatError, match="poses"):
        write_tum(p, [1.0, 2.0], [[0, 0, 0]])
    with pytest.raises(DataFormatError, match="non-finite"):
        write_tum(p, [1.0], [[0, np.inf, 0]])
