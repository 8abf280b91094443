"""Shared fixtures and settings.

- The real-data folder: ``CRLAM_DATA``, default ``../shared/data`` beside the clone; an empty
  ``CRLAM_DATA`` means "no data folder" and every test that needs data skips with the reason.
- Hypothesis: no per-example deadline and no "too slow" health check, so that no outcome depends
  on the speed or the load of the machine (what a property test finds depends only on its
  examples).
"""

from __future__ import annotations

import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# Tests run from a clone with shared/ beside it; installed (non-editable) packages cannot find
# that folder from their own location, so point them at it here. CRLAM_DATA set (even to the
# empty string, "no data") is left as it is.
_SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
if "CRLAM_DATA" not in os.environ and _SHARED.is_dir():
    os.environ["CRLAM_DATA"] = str(_SHARED)

settings.register_profile("crlam", deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("crlam")


@pytest.fixture(scope="session")
def data_dir() -> Path:
    from crlam.io.datasets import data_root

    root = data_root()
    if root is None:
        pytest.skip("real datasets not found: set CRLAM_DATA to the shared data folder (../shared/data)")
    return root


@pytest.fixture(scope="session")
def office_sick(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A short simulated office log: 150 scans of the SICK laser, seed 5 (``log.clf``,
    ``groundtruth.tum``, ``odometry.tum``); made once per test session. Read it, do not write into it."""
    from crlam.sim import SimulationConfig, simulate, write_simulation

    d = tmp_path_factory.mktemp("office_sick")
    write_simulation(simulate(SimulationConfig(world="office", n_scans=150, seed=5, sensor="sick")), d)
    return d
