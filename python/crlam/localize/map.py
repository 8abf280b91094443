"""The fixed map a localizer runs on: a saved CRM (a run folder or ``belief.npz``) or a Nav2 map
turned into a CRM prior.

A Nav2 map (``map.yaml`` + image, e.g. built by another SLAM) says, per cell, occupied, free or
unknown; a CRM needs a belief over occupancy levels. :func:`crm_from_nav2` gives every class the
maximum-entropy pmf (the tilted prior, crm-spec 1.3) with a stated mean, on the endpoint levels
0, 0.1, ..., 1 (which, unlike the midpoint levels, allow a mean near 0: with the midpoint
levels a free cell keeps m̂ ≥ 0.05, so the reach through 100 free cells of a 3 cm map would be
at most 0.006, and every beam longer than a few metres would carry no information). The
confidence of each class is then the standard deviation of its pmf, written to the run's
``metrics.json``.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam import _native
from crlam.errors import ConfigError, DataFormatError
from crlam.io.belief import BeliefArchive, load_belief
from crlam.io.nav2 import Nav2Map, read_nav2_map
from crlam.mapping import ConfidenceRichMap, MapLayer, MappingConfig

__all__ = ["LocalizationMap", "Nav2Prior", "crm_from_nav2", "load_localization_map"]

CellRect = tuple[int, int, int, int]


@dataclass(frozen=True)
class Nav2Prior:
    """How a Nav2 map's classes become CRM beliefs: the mean m̂ of each class's pmf.

    Attributes
    ----------
    occupied_mean : float
        m̂ of an occupied cell: the probability that a beam entering it is returned there.
    free_mean : float
        m̂ of a free cell (what may stand in a free cell of the map: people, moved furniture).
    unknown_mean : float
        m̂ of an unknown cell (0.5: the uniform pmf).
    n_levels : int
        K: the pmfs live on the K + 1 endpoint levels 0, 1/K, ..., 1.
    free_thresh : float or None
        Classify the image with this ``free_thresh`` instead of the YAML's (None). A YAML with
        ``free_thresh: 0.25`` makes map_saver's unknown grey (205, occupancy 0.196) free, as Nav2
        reads it; 0.196 (map_saver's own) keeps it unknown.
    """

    occupied_mean: float = 0.9
    free_mean: float = 0.01
    unknown_mean: float = 0.5
    n_levels: int = 10
    free_thresh: float | None = None

    def __post_init__(self) -> None:
        for name in ("occupied_mean", "free_mean", "unknown_mean"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and 0.0 < v < 1.0):
                raise ConfigError(f"Nav2Prior.{name}: must be in (0, 1) (got {v!r})")
        if not self.free_mean < self.occupied_mean:
            raise ConfigError(f"Nav2Prior: free_mean ({self.free_mean}) must be below occupied_mean ({self.occupied_mean})")
        if self.free_thresh is not None and not 0.0 <= self.free_thresh <= 1.0:
            raise ConfigError(f"Nav2Prior.free_thresh: must be in [0, 1] (got {self.free_thresh!r})")
        if not (isinstance(self.n_levels, int) and 2 <= self.n_levels <= 63):
            raise ConfigError(f"Nav2Prior.n_levels: must be an integer in 2..63 (got {self.n_levels!r})")

    def pmf(self, mean: float) -> NDArray[np.float64]:
        """The maximum-entropy pmf over the endpoint levels with this mean, shape (K + 1,)."""
        probe = _native.CrmMap(1.0, n_levels=self.n_levels, levels="endpoints", prior_mean=float(mean))
        return np.asarray(probe.prior, dtype=np.float64)

    def levels(self) -> NDArray[np.float64]:
        return np.linspace(0.0, 1.0, self.n_levels + 1)

    def confidence(self) -> dict[str, dict[str, float]]:
        """Mean and standard deviation of each class's pmf (the confidence the prior states)."""
        mu = self.levels()
        out = {}
        for name, m in (("occupied", self.occupied_mean), ("free", self.free_mean), ("unknown", self.unknown_mean)):
            p = self.pmf(m)
            mean = float(p @ mu)
            var = float(p @ mu**2) - mean**2
            out[name] = {"mean": mean, "std": math.sqrt(max(0.0, var))}
        return out


@dataclass(eq=False)
class LocalizationMap:
    """A CRM to localize in, with where it came from.

    Attributes
    ----------
    crm : ConfidenceRichMap
        The map; only its expected occupancy enters the likelihood.
    rect : tuple of int
        The cells ``(ix0, iy0, nx, ny)`` the map covers; cells outside read the prior (m̂ 0.5).
    source : str
        Path of the file read.
    kind : str
        ``"belief"`` (a saved CRM) or ``"nav2"`` (a Nav2 map turned into a prior).
    description : dict
        What ``metrics.json`` records about the map (for a Nav2 map: the prior's classes and
        their stated confidence, the class counts).
    """

    crm: ConfidenceRichMap
    rect: CellRect
    source: str
    kind: str
    description: dict[str, Any] = field(default_factory=dict)

    @property
    def resolution(self) -> float:
        return self.crm.config.resolution

    def expected_occupancy(self) -> MapLayer:
        """m̂ over the map's cells."""
        ix0, iy0, nx, ny = self.rect
        m, _, _ = self.crm.native.derived_maps(self.rect)
        res, (ox, oy) = self.crm.config.resolution, self.crm.config.origin
        return MapLayer(m, (ox + ix0 * res, oy + iy0 * res), res, "expected occupancy")


def crm_from_nav2(nav: Nav2Map, prior: Nav2Prior | None = None, *, max_range: float = 8.0) -> tuple[ConfidenceRichMap, CellRect]:
    """A CRM on the Nav2 map's grid whose cells hold the class pmfs of ``prior``.

    Trinary maps give three classes; a scale-mode value q in (0, 1) gets the pmf with mean
    free_mean + q (occupied_mean − free_mean). Returns the map and the cells it covers.
    """
    prior = prior or Nav2Prior()
    if abs(float(nav.origin[2])) > 1e-12:
        raise ConfigError(f"{nav.image_path}: a rotated map origin (yaw {float(nav.origin[2])}) is not supported")
    cfg = MappingConfig(
        resolution=nav.resolution,
        max_range=max_range,
        levels="endpoints",
        n_levels=prior.n_levels,
        origin=(float(nav.origin[0]), float(nav.origin[1])),
    )
    crm = ConfidenceRichMap(cfg)
    occ = nav.occupancy
    ny, nx = occ.shape
    known = ~np.isnan(occ)
    values = np.unique(occ[known])
    table = {float(v): prior.pmf(prior.free_mean + float(v) * (prior.occupied_mean - prior.free_mean)) for v in values}
    k = prior.n_levels + 1
    pmfs = np.empty((ny, nx, k), dtype=np.float64)
    pmfs[~known] = prior.pmf(prior.unknown_mean)
    for v, p in table.items():
        pmfs[known & (occ == v)] = p
    crm.native.set_beliefs(0, 0, pmfs)
    return crm, (0, 0, nx, ny)


def _rect_of_archive(archive: BeliefArchive, crm: ConfidenceRichMap) -> CellRect:
    res, (ox, oy) = crm.config.resolution, crm.config.origin
    ix0 = round((float(archive.origin[0]) - ox) / res)
    iy0 = round((float(archive.origin[1]) - oy) / res)
    ny, nx = archive.shape
    return (ix0, iy0, nx, ny)


def load_localization_map(
    path: str | os.PathLike[str], *, nav2_prior: Nav2Prior | None = None, max_range: float = 8.0
) -> LocalizationMap:
    """The map at ``path``: a run folder of ``crlam map`` / ``crlam slam`` (its ``belief.npz``),
    a ``belief.npz`` or a Nav2 ``.yaml``. ``max_range`` is the z_max a Nav2 prior's config records
    (a saved CRM keeps its own)."""
    p = Path(path)
    if not p.exists():
        raise FileNotFoundError(f"map not found: {p}")
    if p.is_dir():
        if (p / "belief.npz").is_file():
            p = p / "belief.npz"
        elif (p / "map.yaml").is_file():
            p = p / "map.yaml"
        else:
            raise DataFormatError("a map folder needs belief.npz (a crlam map or slam run) or map.yaml (Nav2)", path=str(p))
    suffix = p.suffix.lower()
    if suffix == ".npz":
        archive = load_belief(p)
        crm = ConfidenceRichMap.from_archive(archive)
        return LocalizationMap(
            crm=crm,
            rect=_rect_of_archive(archive, crm),
            source=str(p),
            kind="belief",
            description={"path": str(p), "kind": "belief", "levels": crm.config.levels, "resolution": crm.config.resolution},
        )
    if suffix in (".yaml", ".yml"):
        prior = nav2_prior or Nav2Prior()
        nav = read_nav2_map(p, free_thresh=prior.free_thresh)
        crm, rect = crm_from_nav2(nav, prior, max_range=max_range)
        occ = nav.occupancy
        return LocalizationMap(
            crm=crm,
            rect=rect,
            source=str(p),
            kind="nav2",
            description={
                "path": str(p),
                "kind": "nav2",
                "resolution": nav.resolution,
                "levels": "endpoints",
                "n_levels": prior.n_levels + 1,
                "prior": {"occupied_mean": prior.occupied_mean, "free_mean": prior.free_mean, "unknown_mean": prior.unknown_mean},
                "free_thresh": nav.free_thresh,
                "confidence": prior.confidence(),
                "cells": {
                    "occupied": int(np.sum(occ == 1.0)),
                    "free": int(np.sum(occ == 0.0)),
                    "unknown": int(np.sum(np.isnan(occ))),
                    "other": int(np.sum(~np.isnan(occ) & (occ != 0.0) & (occ != 1.0))),
                },
            },
        )
    raise DataFormatError("expected a run folder, a belief.npz or a Nav2 .yaml map", path=str(p))
