"""Where the real datasets live, and what they are.

The datasets are never part of the repository. They are looked up in the folder named by the
environment variable ``CRLAM_DATA`` or, when it is unset, in ``../shared/data`` relative to the
repository root (the source checkout that holds ``python/crlam``), if that folder exists.
``CRLAM_DATA`` set to the empty string means "no data folder": nothing is looked up (the
continuous-integration run that proves the tests pass on a fresh clone uses it).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

from crlam.errors import CrlamError

__all__ = ["DATASETS", "ENV_VAR", "Dataset", "DatasetNotFoundError", "data_root", "dataset_path"]

ENV_VAR = "CRLAM_DATA"


class DatasetNotFoundError(CrlamError, FileNotFoundError):
    """A dataset (or the data folder itself) is not available on this machine."""


@dataclass(frozen=True)
class Dataset:
    """A known dataset.

    Attributes
    ----------
    name : str
        Registry key.
    relative_path : str
        Path inside the data folder.
    description : str
        What it is.
    flaser_max_range : float or None
        For CARMEN logs, the ``flaser_max_range`` (m) to give the reader: readings at or
        above it are no-returns in this log. ``None`` for other files.
    """

    name: str
    relative_path: str
    description: str
    flaser_max_range: float | None = None


def _registry(*items: Dataset) -> dict[str, Dataset]:
    return {d.name: d for d in items}


DATASETS: dict[str, Dataset] = _registry(
    Dataset(
        "intel",
        "intel/intel.clf.bz2",
        "Intel Research Lab (Seattle) raw CARMEN log: 13,631 FLASER (180 beams), 26,915 "
        "ODOM, not time sorted; no-return readings are 81.83 m",
        81.0,
    ),
    Dataset("intel-relations", "intel/intel.relations", "Kuemmerle et al. 2009 reference relations for Intel, 2,984 lines"),
    Dataset(
        "aces",
        "aces/aces.clf.bz2",
        "ACES building (Austin) raw CARMEN log: 7,374 FLASER (180 beams), 7,375 ODOM; no-return readings are 50.00 m",
        50.0,
    ),
    Dataset("aces-relations", "aces/aces.relations", "Kuemmerle et al. 2009 reference relations for ACES, 1,279 lines"),
    Dataset(
        "intel-corrected",
        "corrected/intel-corrected.log.gz",
        "GMapping-corrected Intel log (FLASER pose and odom hold the corrected pose)",
        81.0,
    ),
    Dataset(
        "aces-corrected",
        "corrected/aces-corrected.log.gz",
        "GMapping-corrected ACES log (FLASER pose and odom hold the corrected pose)",
        50.0,
    ),
    Dataset(
        "freiburg-101-corrected",
        "corrected/freiburg-101-corrected.log.gz",
        "GMapping-corrected Freiburg building 101 log, 360 beams, front laser offset -0.04 m",
        81.0,
    ),
    Dataset(
        "edmonton-corrected",
        "corrected/edmonton-corrected.log.gz",
        "GMapping-corrected Edmonton convention centre log; saturated readings are about 51.15 m",
        51.0,
    ),
    Dataset(
        "robotlaser1-sample",
        "robotlaser1-sample.clf.gz",
        "First 50 lines of a real log in the ROBOTLASER1 format (180/181 beams)",
    ),
    Dataset("cave-map", "maps/cave.pgm", "Player/Stage cave bitmap, 100 x 100 px at 0.2 m/px; pixel >= 128 free, < 128 obstacle"),
)


def _repo_root() -> Path:
    # python/crlam/io/datasets.py -> the checkout root three levels above the package dir.
    return Path(__file__).resolve().parents[3]


def data_root() -> Path | None:
    """The data folder, or ``None`` if it does not exist.

    ``$CRLAM_DATA`` when set (``None`` if it names no folder, or is empty: the empty string
    switches the lookup off), else ``<repo>/../shared/data``.
    """
    env = os.environ.get(ENV_VAR)
    if env is not None:
        if not env.strip():
            return None
        root = Path(env).expanduser()
    else:
        root = _repo_root().parent / "shared" / "data"
    return root if root.is_dir() else None


def dataset_path(relative: str) -> Path:
    """Absolute path of a dataset, by registry name (``"intel"``) or path inside the folder.

    Raises
    ------
    DatasetNotFoundError
        If the data folder or the file is missing; the message says where it was looked for.
    """
    rel = DATASETS[relative].relative_path if relative in DATASETS else relative
    root = data_root()
    if root is None:
        env = os.environ.get(ENV_VAR)
        default = _repo_root().parent / "shared" / "data"
        where = f"${ENV_VAR}={env!r}" if env is not None else f"{default} (set ${ENV_VAR} to override)"
        raise DatasetNotFoundError(f"dataset {relative!r}: no data folder at {where}")
    path = root / rel
    if not path.exists():
        raise DatasetNotFoundError(f"dataset {relative!r}: {path} does not exist")
    return path
