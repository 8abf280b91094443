"""Mapping that continues a saved run (``crlam slam LOG --continue DIR``).

A run folder of ``crlam slam`` holds the best particle's map and the run's final estimate with
its covariance in ``belief.npz`` (format version 2, :mod:`crlam.io.belief`), and its settings in
``config.toml``. :func:`load_slam_prior` reads them; a filter built with the prior
(:func:`crlam.slam.make_filter`) gives that map to every particle, draws the particles from
N(estimate, covariance) and weighs its first scan against the map, so the new log's first scan is
taken to follow the saved run's last one (the robot has not moved in between). The saved folder
is only read.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from crlam.errors import ConfigError, DataFormatError
from crlam.io.belief import load_belief
from crlam.io.run_folder import COMPLETE, INCOMPLETE, is_complete
from crlam.mapping import ConfidenceRichMap

__all__ = ["SlamPrior", "load_slam_prior", "pose_covariance"]


@dataclass(eq=False)
class SlamPrior:
    """What a continued run starts from.

    Attributes
    ----------
    map : ConfidenceRichMap
        The saved map, given to every particle.
    pose : ndarray, shape (3,)
        The saved run's final estimate (x m, y m, θ rad): the first scan's prior mean.
    cov : ndarray, shape (3, 3)
        Its covariance (m², m·rad, rad²).
    source : str
        The folder (or file) it was read from.
    """

    map: ConfidenceRichMap
    pose: NDArray[np.float64]
    cov: NDArray[np.float64]
    source: str

    def describe(self) -> dict[str, object]:
        """For ``metrics.json`` and ``config.toml``."""
        return {"path": self.source, "pose": self.pose.tolist(), "cov": self.cov.tolist()}


def pose_covariance(poses: NDArray[np.float64], weights: NDArray[np.float64], mean: NDArray[np.float64]) -> NDArray[np.float64]:
    """Weighted covariance (3, 3) of poses (n, 3) about ``mean``, headings differenced on the circle."""
    p = np.asarray(poses, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    w = w / w.sum()
    d = p - np.asarray(mean, dtype=np.float64)
    d[:, 2] = (d[:, 2] + np.pi) % (2 * np.pi) - np.pi
    cov = (d * w[:, None]).T @ d
    return np.asarray(0.5 * (cov + cov.T))


def check_complete_run(folder: Path, require_marker: bool = True) -> None:
    """Refuse a run folder that is not whole: one holding ``INCOMPLETE`` (a run still writing,
    stopped or crashed) or, with ``require_marker``, lacking the ``COMPLETE`` marker a run
    writes last."""
    if (folder / INCOMPLETE).exists():
        raise DataFormatError(
            "the run folder is marked INCOMPLETE (its run was interrupted or is still writing): --continue takes a "
            "complete crlam slam run folder",
            path=str(folder),
        )
    if require_marker and not is_complete(folder):
        raise DataFormatError(
            f"no {COMPLETE} marker: not a complete crlam slam run folder (a run writes the marker last)", path=str(folder)
        )


def load_slam_prior(path: str | os.PathLike[str]) -> SlamPrior:
    """The prior of a ``crlam slam`` run folder (or its ``belief.npz``).

    Raises
    ------
    DataFormatError
        When the run folder is not complete (:func:`check_complete_run`), when the archive
        carries no estimate (format version 1, written before runs saved one) or is invalid.
    """
    p = Path(path)
    folder_given = p.is_dir()
    if folder_given:
        p = p / "belief.npz"
    if not p.is_file():
        raise FileNotFoundError(f"no belief.npz to continue from: {p} (a crlam slam run folder holds one)")
    # A run folder must be whole; a belief.npz named alone may sit anywhere, but not in a
    # folder whose run did not finish.
    check_complete_run(p.parent, require_marker=folder_given)
    archive = load_belief(p)
    if archive.estimate is None or archive.estimate_cov is None:
        raise DataFormatError(
            "holds no final estimate (a belief.npz of format version 1, or of crlam map): --continue needs the "
            "belief.npz of a crlam slam run of format version 2 or later",
            path=str(p),
            field="estimate",
        )
    crm = ConfidenceRichMap.from_archive(archive)
    if crm.config.levels != "midpoints":
        raise ConfigError(f"{p}: the map has {crm.config.levels} levels; the SLAM filters map on midpoint levels")
    return SlamPrior(map=crm, pose=archive.estimate.copy(), cov=archive.estimate_cov.copy(), source=str(p.parent))
