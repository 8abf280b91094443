"""Tests of the CRM belief archive (crlam.io.belief)."""

from __future__ import annotations

import tempfile
import zipfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from crlam.errors import DataFormatError
from crlam.io import BeliefArchive, load_belief, save_belief


def make(ny: int = 3, nx: int = 4, k: int = 5, seed: int = 0) -> BeliefArchive:
    rng = np.random.default_rng(seed)
    w = rng.random((ny, nx, k))
    return BeliefArchive(
        beliefs=(w / w.sum(axis=2, keepdims=True)).astype(np.float32),
        levels=np.linspace(0.0, 1.0, k),
        origin=np.array([-3.5, 12.25]),
        resolution=0.05,
        metadata={"sensor_model": "crm", "n_levels": k, "floor": 1e-6},
    )


@settings(max_examples=40, deadline=None)
@given(
    shape=st.tuples(st.integers(1, 9), st.integers(1, 9), st.integers(1, 12)),
    data=st.data(),
    origin=arrays(np.float64, 2, elements=st.floats(-1e6, 1e6)),
    resolution=st.floats(1e-4, 100.0),
    metadata=st.dictionaries(
        st.text(max_size=8),
        st.one_of(st.text(max_size=8), st.integers(-(10**9), 10**9), st.floats(allow_nan=False, allow_infinity=False)),
        max_size=4,
    ),
)
def test_bitwise_round_trip(
    shape: tuple[int, int, int],
    data: st.DataObject,
    origin: np.ndarray,
    resolution: float,
    metadata: dict[str, str | int | float],
) -> None:
    w = data.draw(arrays(np.float64, shape, elements=st.floats(1e-3, 1.0)))
    beliefs = (w / w.sum(axis=2, keepdims=True)).astype(np.float32)
    levels = data.draw(arrays(np.float64, shape[2], elements=st.floats(-10.0, 10.0)))
    arc = BeliefArchive(beliefs=beliefs, levels=levels, origin=origin, resolution=resolution, metadata=metadata)
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "belief.npz"
        save_belief(p, arc)
        back = load_belief(p)
    assert back.beliefs.dtype == np.float32 and back.beliefs.shape == shape
    assert back.beliefs.tobytes() == beliefs.tobytes()
    assert back.levels.tobytes() == levels.tobytes()
    assert back.origin.tobytes() == origin.tobytes()
    assert back.resolution == resolution and back.metadata == metadata
    assert back.shape == shape[:2] and back.n_levels == shape[2]


def test_exact_name_is_used(tmp_path: Path) -> None:
    save_belief(tmp_path / "map.belief", make())
    assert (tmp_path / "map.belief").exists() and not (tmp_path / "map.belief.npz").exists()
    assert load_belief(tmp_path / "map.belief").metadata["n_levels"] == 5


def _bad_sum(a: BeliefArchive) -> None:
    a.beliefs[1, 2, 0] += 0.01


def _negative(a: BeliefArchive) -> None:
    a.beliefs[0, 0, :2] = [-0.5, a.beliefs[0, 0, 0] + a.beliefs[0, 0, 1] + 0.5]


def _nan(a: BeliefArchive) -> None:
    a.beliefs[2, 3, 4] = np.nan


def _levels(a: BeliefArchive) -> None:
    a.levels = np.linspace(0, 1, 4)


def _origin(a: BeliefArchive) -> None:
    a.origin = np.array([0.0, np.inf])


def _resolution(a: BeliefArchive) -> None:
    a.resolution = -1.0


def _meta(a: BeliefArchive) -> None:
    a.metadata["bad"] = [1, 2]  # type: ignore[assignment]


@pytest.mark.parametrize(
    ("mutate", "field"),
    [
        (_bad_sum, "beliefs[1,2]"),
        (_negative, "beliefs[0,0]"),
        (_nan, "beliefs[2,3]"),
        (_levels, "levels"),
        (_origin, "origin"),
        (_resolution, "resolution"),
        (_meta, "metadata"),
    ],
)
def test_save_validates(tmp_path: Path, mutate: object, field: str) -> None:
    arc = make()
    mutate(arc)  # type: ignore[operator]
    p = tmp_path / "b.npz"
    with pytest.raises(DataFormatError) as info:
        save_belief(p, arc)
    assert info.value.field == field and str(p) in str(info.value)
    assert not p.exists()


def _rewrite(path: Path, **changes: object) -> None:
    with np.load(path) as npz:
        arrays_ = {k: npz[k] for k in npz.files}
    arrays_.update(changes)  # type: ignore[arg-type]
    for key in [k for k, v in changes.items() if v is None]:
        del arrays_[key]
    with open(path, "wb") as fh:
        np.savez_compressed(fh, **arrays_)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("changes", "field"),
    [
        ({"format_version": np.array(99)}, "format_version"),
        ({"levels": None}, "levels"),
        ({"beliefs": np.zeros((3, 4, 5), np.float64)}, "beliefs"),
        ({"beliefs": np.full((3, 4, 5), 0.3, np.float32)}, "beliefs[0,0]"),
        ({"metadata": np.array("{not json")}, "metadata"),
        ({"format": np.array("something")}, "format"),
    ],
)
def test_load_validates(tmp_path: Path, changes: dict[str, object], field: str) -> None:
    p = tmp_path / "b.npz"
    save_belief(p, make())
    _rewrite(p, **changes)
    with pytest.raises(DataFormatError) as info:
        load_belief(p)
    assert info.value.field == field and str(p) in str(info.value)


def test_not_an_archive(tmp_path: Path) -> None:
    p = tmp_path / "junk.npz"
    p.write_bytes(b"hello")
    with pytest.raises(DataFormatError, match="not a belief archive"):
        load_belief(p)
    with zipfile.ZipFile(tmp_path / "empty.npz", "w"):
        pass
    with pytest.raises(DataFormatError):
        load_belief(tmp_path / "empty.npz")
    with pytest.raises(FileNotFoundError):
        load_belief(tmp_path / "missing.npz")
