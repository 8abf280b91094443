"""Shared fixtures: the real-data folder (``CRLAM_DATA``, default ``../shared/data``)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# Tests run from a clone with shared/ beside it; installed (non-editable) packages cannot find
# that folder from their own location, so point them at it here.
_SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
if "CRLAM_DATA" not in os.environ and _SHARED.is_dir():
    os.environ["CRLAM_DATA"] = str(_SHARED)


@pytest.fixture(scope="session")
def data_dir() -> Path:
    from crlam.io.datasets import data_root

    root = data_root()
    if root is None:
        pytest.skip("real datasets not found: set CRLAM_DATA to the shared data folder (../shared/data)")
    return root
