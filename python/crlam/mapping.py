"""Confidence-rich maps and log-odds maps: the typed Python face of the Rust core.

Grids follow the project convention: layers are ``(ny, nx)`` arrays indexed ``[iy, ix]`` with
``iy = 0`` at the minimum y, and ``origin`` is the world position (m) of the lower-left corner of
cell ``[0, 0]``. Poses are ``(x, y, theta)`` of the *sensor* (m, rad); beam ``b`` points along
``theta + angles[b]`` and read ``ranges[b]`` (m; ``inf``/``nan``/``>= max_range`` = no return).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam import _native
from crlam.errors import ConfigError
from crlam.io.belief import BeliefArchive

__all__ = [
    "MapLayer",
    "MappingConfig",
    "ScanUpdateStats",
    "ConfidenceRichMap",
    "LogOddsOccupancyMap",
    "SENSOR_MODELS",
    "LEVEL_PLACEMENTS",
    "SCAN_UPDATE_MODES",
    "BATCH_KERNELS",
    "CAUSE_KERNELS",
]

SENSOR_MODELS = ("ijrr", "mixture", "authors_code")
LEVEL_PLACEMENTS = ("midpoints", "endpoints", "r1_right")
SCAN_UPDATE_MODES = ("batch", "sequential")
BATCH_KERNELS = ("windowed", "full_ray")
CAUSE_KERNELS = ("midpoint", "chord")

CellRect = tuple[int, int, int, int]


def _f64(a: ArrayLike) -> NDArray[np.float64]:
    return np.ascontiguousarray(a, dtype=np.float64)


@dataclass(frozen=True)
class MapLayer:
    """One scalar value per cell.

    Attributes
    ----------
    values : ndarray, shape (ny, nx)
        Cell values, ``[iy, ix]``, ``iy = 0`` at the minimum y.
    origin : tuple of float
        World ``(x, y)`` (m) of the lower-left corner of ``values[0, 0]``.
    resolution : float
        Cell size (m).
    name : str
        What the values are (e.g. ``"expected occupancy"``).
    """

    values: NDArray[np.float64]
    origin: tuple[float, float]
    resolution: float
    name: str = ""

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.values.shape[0]), int(self.values.shape[1]))

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` in metres (matplotlib's ``extent`` order)."""
        ny, nx = self.shape
        x0, y0 = self.origin
        return (x0, x0 + nx * self.resolution, y0, y0 + ny * self.resolution)

    def cell_of(self, points: ArrayLike) -> NDArray[np.int64]:
        """Indices ``(iy, ix)`` of world points ``(..., 2)``; may lie outside the layer."""
        p = np.asarray(points, dtype=np.float64)
        ix = np.floor((p[..., 0] - self.origin[0]) / self.resolution).astype(np.int64)
        iy = np.floor((p[..., 1] - self.origin[1]) / self.resolution).astype(np.int64)
        return np.stack([iy, ix], axis=-1)

    def sample(self, points: ArrayLike, fill: float = np.nan) -> NDArray[np.float64]:
        """Values at world points ``(..., 2)``; ``fill`` outside the layer."""
        idx = self.cell_of(points)
        iy, ix = idx[..., 0], idx[..., 1]
        ny, nx = self.shape
        inside = (iy >= 0) & (iy < ny) & (ix >= 0) & (ix < nx)
        out = np.full(iy.shape, fill, dtype=np.float64)
        out[inside] = self.values[iy[inside], ix[inside]]
        return out


@dataclass(frozen=True)
class MappingConfig:
    """Settings of a confidence-rich map (crm-spec section 9).

    Attributes
    ----------
    resolution : float
        Cell size Δ (m).
    max_range : float
        z_max (m): readings at or beyond it are no-returns; rays stop there.
    min_range : float
        z_min (m): shorter readings are dropped.
    model : str
        ``"ijrr"`` (default for mapping), ``"mixture"`` or ``"authors_code"``.
    n_levels : int
        K occupancy levels.
    levels : str
        ``"midpoints"`` (default), ``"endpoints"`` (K+1 levels) or ``"r1_right"``.
    prior_mean : float or None
        ``None`` for the uniform prior, else the tilted prior with this mean.
    belief_floor : float
        ε_b floor of every pmf entry after an update (0 disables).
    scan_update : str
        ``"batch"`` (default) or ``"sequential"``.
    batch_kernel : str
        How a batch update computes each beam: ``"windowed"`` (default: likelihoods only near
        the reading, the cells before it counted as passes; ``ijrr`` with midpoint causes, other
        models take the full sweep) or ``"full_ray"`` (every cell's likelihood and factor: the
        reference). The two agree to f32 storage precision.
    hits_first : bool
        Batch updates only: a cell that a beam of the scan makes more occupied (α > 1e-9, above
        rounding) drops the passes of the scan's beams, those whose readings lie so far beyond it
        that causes beyond it explain them to a millionth (factor (1 − μ)/(1 − m̂)); every other
        factor is applied as without it (default ``False``: every factor, as crm-spec 3.3). Where a beam meets a wall
        at a slant it crosses the wall's cells before the point it hits, so without this a scan
        thins a slanted wall into a dotted line, differently from each viewpoint (Cartographer
        likewise lets a scan's hits take precedence over its misses).
    cause_kernel : str
        ``"midpoint"`` (the spec: a cause sits at its chord midpoint) or ``"chord"`` (spread
        uniformly along the chord; sharper walls under grazing incidence, see BENCHMARKS.md).
    sigma_range : float
        Range noise σ_r (m); σ_hit = sqrt(σ_r² + Δ²/12) for the midpoint kernel (σ_r for the
        chord kernel, which models the quantisation itself) unless ``sigma_hit`` is given.
    sigma_hit : float or None
        Explicit hit standard deviation (m).
    w_hit, w_short, w_max, w_rand, lambda_short : float
        Beam-mixture weights and short-reading rate (1/m) for ``mixture``/``authors_code``.
    beam_stride : int
        Use every n-th beam.
    tile_size : int
        Tile side in cells (power of two).
    extent : tuple of float or None
        Fixed world extent ``(xmin, ymin, xmax, ymax)``; ``None`` grows with the data.
    origin : tuple of float
        Grid origin (m): cell boundaries fall on ``origin + k·Δ``.
    """

    resolution: float = 0.2
    max_range: float = 8.0
    min_range: float = 0.0
    model: str = "ijrr"
    n_levels: int = 10
    levels: str = "midpoints"
    prior_mean: float | None = None
    belief_floor: float = 1e-12
    scan_update: str = "batch"
    batch_kernel: str = "windowed"
    hits_first: bool = False
    cause_kernel: str = "midpoint"
    sigma_range: float = 0.01
    sigma_hit: float | None = None
    w_hit: float = 0.7
    w_short: float = 0.1
    w_max: float = 0.1
    w_rand: float = 0.1
    lambda_short: float = 0.2
    beam_stride: int = 1
    tile_size: int = 32
    extent: tuple[float, float, float, float] | None = None
    origin: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        # Lists (from JSON/TOML or a user's literal) become the tuples the native map takes.
        for name, size in (("origin", 2), ("extent", 4)):
            value = getattr(self, name)
            if value is None:
                continue
            try:
                items = tuple(float(v) for v in value)
            except (TypeError, ValueError):
                raise ConfigError(f"MappingConfig.{name}: must be {size} numbers (got {value!r})") from None
            if len(items) != size:
                raise ConfigError(f"MappingConfig.{name}: must be {size} numbers (got {value!r})")
            object.__setattr__(self, name, items)
        self.validate()

    def validate(self) -> None:
        """Raise :class:`ConfigError` naming the first invalid field."""

        def bad(name: str, why: str) -> ConfigError:
            return ConfigError(f"MappingConfig.{name}: {why} (got {getattr(self, name)!r})")

        if not all(math.isfinite(v) for v in self.origin):
            raise bad("origin", "must be two finite numbers (x, y)")

        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise bad("resolution", "must be a finite number > 0")
        if not (math.isfinite(self.max_range) and self.max_range > 0):
            raise bad("max_range", "must be a finite number > 0")
        if not (math.isfinite(self.min_range) and 0 <= self.min_range < self.max_range):
            raise bad("min_range", "must be in [0, max_range)")
        if self.model not in SENSOR_MODELS:
            raise bad("model", f"must be one of {SENSOR_MODELS}")
        if self.levels not in LEVEL_PLACEMENTS:
            raise bad("levels", f"must be one of {LEVEL_PLACEMENTS}")
        if self.scan_update not in SCAN_UPDATE_MODES:
            raise bad("scan_update", f"must be one of {SCAN_UPDATE_MODES}")
        if self.batch_kernel not in BATCH_KERNELS:
            raise bad("batch_kernel", f"must be one of {BATCH_KERNELS}")
        if self.cause_kernel not in CAUSE_KERNELS:
            raise bad("cause_kernel", f"must be one of {CAUSE_KERNELS}")
        if not isinstance(self.hits_first, bool):
            raise bad("hits_first", "must be True or False")
        if self.hits_first and self.scan_update != "batch":
            raise bad("hits_first", "needs scan_update = 'batch' (a sequential update applies each beam before the next)")
        if not (isinstance(self.n_levels, int) and 2 <= self.n_levels <= 64):
            raise bad("n_levels", "must be an integer in 2..64")
        if not (isinstance(self.beam_stride, int) and self.beam_stride >= 1):
            raise bad("beam_stride", "must be an integer >= 1")
        if not (math.isfinite(self.sigma_range) and self.sigma_range >= 0):
            raise bad("sigma_range", "must be finite and >= 0")
        if self.sigma_hit is not None and not (math.isfinite(self.sigma_hit) and self.sigma_hit > 0):
            raise bad("sigma_hit", "must be finite and > 0")
        if self.extent is not None:
            x0, y0, x1, y1 = self.extent
            if not all(math.isfinite(v) for v in self.extent) or x1 <= x0 or y1 <= y0:
                raise bad("extent", "must be finite (xmin, ymin, xmax, ymax) with xmax > xmin, ymax > ymin")

    @property
    def hit_sigma(self) -> float:
        """σ_hit actually used (m)."""
        if self.sigma_hit is not None:
            return self.sigma_hit
        if self.model == "authors_code":
            return 0.1 * self.resolution
        if self.cause_kernel == "chord":
            return max(self.sigma_range, 1e-4)
        return math.hypot(self.sigma_range, self.resolution / math.sqrt(12.0))

    def sensor_model(self, model: str | None = None) -> _native.SensorModel:
        """The native likelihood model (``model`` overrides ``self.model``)."""
        kind = model or self.model
        mix = {} if kind == "ijrr" else {"w_hit": self.w_hit, "w_short": self.w_short, "w_max": self.w_max, "w_rand": self.w_rand}
        try:
            return _native.SensorModel(
                kind,
                self.max_range,
                self.resolution,
                cause_kernel=self.cause_kernel,
                sigma_hit=self.hit_sigma,
                lambda_short=self.lambda_short,
                z_min=self.min_range,
                **mix,
            )
        except ValueError as e:
            raise ConfigError(f"MappingConfig: {e}") from e

    def cell_extent(self) -> CellRect | None:
        """The fixed extent in cells, or ``None``."""
        if self.extent is None:
            return None
        return _cells_of_box(self.extent, self.resolution, self.origin)

    def to_dict(self) -> dict[str, Any]:
        """Every setting, plus the resolved σ_hit."""
        d = asdict(self)
        d["sigma_hit_resolved"] = self.hit_sigma
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> MappingConfig:
        """Inverse of :meth:`to_dict` (unknown keys are an error)."""
        names = {f.name for f in fields(cls)}
        unknown = set(d) - names - {"sigma_hit_resolved"}
        if unknown:
            raise ConfigError(f"MappingConfig: unknown settings {sorted(unknown)}")
        kw = {k: v for k, v in d.items() if k in names}
        for k in ("extent", "origin"):
            if kw.get(k) is not None:
                kw[k] = tuple(kw[k])
        return cls(**kw)


@dataclass
class ScanUpdateStats:
    """Counters of CRM scan updates (summed over scans with ``+=``)."""

    n_beams: int = 0
    n_used: int = 0
    n_no_return: int = 0
    n_dropped_short: int = 0
    n_skipped_eta: int = 0
    n_empty_ray: int = 0
    n_cell_updates: int = 0
    n_frozen: int = 0

    def __iadd__(self, other: ScanUpdateStats | dict[str, int]) -> ScanUpdateStats:
        o = other if isinstance(other, dict) else asdict(other)
        for f in fields(self):
            setattr(self, f.name, getattr(self, f.name) + int(o[f.name]))
        return self

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


def _box(bounds: object) -> tuple[float, float, float, float]:
    """A world box ``(xmin, ymin, xmax, ymax)`` from input: four finite numbers, max > min."""
    try:
        box = tuple(float(v) for v in bounds)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise ConfigError(f"bounds must be (xmin, ymin, xmax, ymax), got {bounds!r}") from None
    if len(box) != 4 or not all(math.isfinite(v) for v in box) or box[2] <= box[0] or box[3] <= box[1]:
        raise ConfigError(f"bounds must be 4 finite numbers (xmin, ymin, xmax, ymax) with max > min, got {bounds!r}")
    return box  # type: ignore[return-value]


def _cells_of_box(bounds: tuple[float, float, float, float], resolution: float, origin: tuple[float, float]) -> CellRect:
    """Cell rectangle ``(ix0, iy0, nx, ny)`` covering the world box ``(xmin, ymin, xmax, ymax)``."""
    ix0 = math.floor((bounds[0] - origin[0]) / resolution)
    iy0 = math.floor((bounds[1] - origin[1]) / resolution)
    nx = max(1, math.ceil((bounds[2] - origin[0]) / resolution) - ix0)
    ny = max(1, math.ceil((bounds[3] - origin[1]) / resolution) - iy0)
    return (ix0, iy0, nx, ny)


def _check_scan(pose: ArrayLike, angles: ArrayLike, ranges: ArrayLike) -> tuple[NDArray[np.float64], ...]:
    p, a, r = _f64(pose).reshape(-1), _f64(angles).reshape(-1), _f64(ranges).reshape(-1)
    if p.shape != (3,):
        raise ConfigError(f"pose must have 3 values (x, y, theta), got shape {np.shape(pose)}")
    if a.shape != r.shape:
        raise ConfigError(f"scan has {a.size} beam angles but {r.size} ranges")
    return p, a, r


@dataclass
class ConfidenceRichMap:
    """A confidence-rich map: a pmf over occupancy levels in every cell (crm-spec 1–3).

    Cheap to copy (:meth:`copy` shares storage tiles copy-on-write). Cells never touched read
    the prior, so the map is unbounded unless ``config.extent`` fixes it.
    """

    config: MappingConfig = field(default_factory=MappingConfig)
    native: _native.CrmMap = field(init=False, repr=False)
    stats: ScanUpdateStats = field(default_factory=ScanUpdateStats, repr=False)

    def __post_init__(self) -> None:
        c = self.config
        try:
            self.native = _native.CrmMap(
                c.resolution,
                c.origin,
                n_levels=c.n_levels,
                levels=c.levels,
                prior_mean=c.prior_mean,
                belief_floor=c.belief_floor,
                tile_size=c.tile_size,
                extent=c.cell_extent(),
            )
        except ValueError as e:
            raise ConfigError(f"MappingConfig: {e}") from e
        self._model = c.sensor_model()

    @property
    def levels(self) -> NDArray[np.float64]:
        """Level values μ_k, shape (K,) (K+1 for endpoint levels)."""
        return self.native.levels

    @property
    def sensor_model(self) -> _native.SensorModel:
        return self._model

    def update(self, pose: ArrayLike, angles: ArrayLike, ranges: ArrayLike) -> ScanUpdateStats:
        """Integrates one scan from the sensor pose; returns this scan's counters."""
        p, a, r = _check_scan(pose, angles, ranges)
        d = self.native.update_scan(
            p,
            a,
            r,
            self._model,
            mode=self.config.scan_update,
            batch_kernel=self.config.batch_kernel,
            hits_first=self.config.hits_first,
            beam_stride=self.config.beam_stride,
        )
        s = ScanUpdateStats(**d)
        self.stats += s
        return s

    def update_many(self, poses: ArrayLike, angles: ArrayLike, ranges: ArrayLike) -> ScanUpdateStats:
        """Integrates n scans: poses (n, 3), shared angles (m,), ranges (n, m)."""
        d = self.native.update_scans(
            _f64(poses),
            _f64(angles),
            _f64(ranges),
            self._model,
            mode=self.config.scan_update,
            batch_kernel=self.config.batch_kernel,
            hits_first=self.config.hits_first,
            beam_stride=self.config.beam_stride,
        )
        s = ScanUpdateStats(**d)
        self.stats += s
        return s

    def log_likelihood(self, pose: ArrayLike, angles: ArrayLike, ranges: ArrayLike, model: str | None = None) -> float:
        """Σ_beams log η of a scan under the current beliefs (crm-spec 4.1); map unchanged."""
        p, a, r = _check_scan(pose, angles, ranges)
        m = self._model if model is None else self.config.sensor_model(model)
        ll, _ = self.native.scan_log_likelihood(p, a, r, m, beam_stride=self.config.beam_stride)
        return ll

    def region(self, bounds: tuple[float, float, float, float] | None = None) -> CellRect:
        """Cell rectangle of a world box ``(xmin, ymin, xmax, ymax)``; default: the written area
        (or the fixed extent)."""
        if bounds is None:
            r = self.native.extent or self.native.written_bounds()
            return r if r is not None else (0, 0, 1, 1)
        return _cells_of_box(_box(bounds), self.config.resolution, self.config.origin)

    def _layer(self, values: NDArray[np.float64], rect: CellRect, name: str) -> MapLayer:
        res, (ox, oy) = self.config.resolution, self.config.origin
        return MapLayer(values, (ox + rect[0] * res, oy + rect[1] * res), res, name)

    def layers(self, bounds: tuple[float, float, float, float] | None = None) -> tuple[MapLayer, MapLayer, MapLayer]:
        """(expected occupancy m̂, variance, entropy in bits) over a region."""
        rect = self.region(bounds)
        m, v, h = self.native.derived_maps(rect)
        return (
            self._layer(m, rect, "expected occupancy"),
            self._layer(v, rect, "variance"),
            self._layer(h, rect, "entropy (bits)"),
        )

    def expected_occupancy(self, bounds: tuple[float, float, float, float] | None = None) -> MapLayer:
        return self.layers(bounds)[0]

    def variance(self, bounds: tuple[float, float, float, float] | None = None) -> MapLayer:
        return self.layers(bounds)[1]

    def entropy(self, bounds: tuple[float, float, float, float] | None = None) -> MapLayer:
        return self.layers(bounds)[2]

    def copy(self) -> ConfidenceRichMap:
        """A copy sharing storage copy-on-write."""
        new = object.__new__(ConfidenceRichMap)
        new.config = self.config
        new.native = self.native.copy()
        new.stats = ScanUpdateStats(**self.stats.as_dict())
        new._model = self._model
        return new

    def to_archive(self, bounds: tuple[float, float, float, float] | None = None) -> BeliefArchive:
        """Lossless snapshot of the beliefs over a region, with the full configuration.

        It holds the region's pmfs in memory, ``ny x nx x K`` float32;
        :func:`crlam.experiments.map_outputs.write_belief_archive` writes the same file band by band."""
        rect = self.region(bounds)
        origin, meta = self.archive_header(rect)
        return BeliefArchive(
            beliefs=self.native.beliefs(rect),
            levels=self.levels.copy(),
            origin=origin,
            resolution=self.config.resolution,
            metadata=meta,
        )

    def archive_header(self, rect: CellRect) -> tuple[NDArray[np.float64], dict[str, str | int | float]]:
        """The ``origin`` (2,) and ``metadata`` of the archive of cell rectangle ``rect``
        (``(ix0, iy0, nx, ny)``, as :meth:`region` gives)."""
        meta: dict[str, str | int | float] = {
            k: (v if isinstance(v, (str, int, float)) else repr(v)) for k, v in self.config.to_dict().items() if v is not None
        }
        meta["cell_ix0"], meta["cell_iy0"] = rect[0], rect[1]
        meta["config_json"] = _json(self.config.to_dict())
        res, (ox, oy) = self.config.resolution, self.config.origin
        return np.array([ox + rect[0] * res, oy + rect[1] * res]), meta

    @classmethod
    def from_archive(cls, archive: BeliefArchive, config: MappingConfig | None = None) -> ConfidenceRichMap:
        """Rebuilds a map from :meth:`to_archive` output (config from the archive if absent)."""
        if config is None:
            raw = archive.metadata.get("config_json")
            if isinstance(raw, str):
                config = MappingConfig.from_dict(json.loads(raw))
            else:
                k = archive.levels.size
                config = MappingConfig(
                    resolution=archive.resolution, n_levels=k, origin=(float(archive.origin[0]), float(archive.origin[1]))
                )
        res, (ox, oy) = config.resolution, config.origin
        # The archive's own fields describe its grid: a configuration (given, or stored in the
        # metadata) on another grid would silently place the beliefs on cells of another size.
        if not math.isclose(archive.resolution, res, rel_tol=1e-9, abs_tol=0.0):
            raise ConfigError(
                f"the archive's cells are {archive.resolution} m but its configuration (metadata config_json or the "
                f"config given) says resolution {res} m"
            )
        fx, fy = ((archive.origin[0] - ox) / res, (archive.origin[1] - oy) / res)
        ix0, iy0 = round(fx), round(fy)
        if abs(fx - ix0) > 1e-6 or abs(fy - iy0) > 1e-6:
            raise ConfigError(
                f"the archive's origin {archive.origin.tolist()} is not on the configuration's grid (origin {config.origin}, "
                f"cells {res} m)"
            )
        m = cls(config)
        if archive.levels.shape != m.levels.shape or not np.allclose(archive.levels, m.levels):
            raise ConfigError("archive levels do not match the configuration's levels")
        m.native.set_beliefs(ix0, iy0, np.ascontiguousarray(archive.beliefs, dtype=np.float64))
        return m


def _json(d: dict[str, Any]) -> str:
    return json.dumps(d, sort_keys=True)


@dataclass(frozen=True)
class LogOddsConfig:
    """Inverse sensor model of the log-odds baseline (crm-spec 9: R1's +1, −0.5, ±100, base 2)."""

    resolution: float = 0.2
    max_range: float = 8.0
    l_occ: float = 1.0
    l_free: float = -0.5
    l_min: float = -100.0
    l_max: float = 100.0
    base: float = 2.0
    clear_no_return: bool = True
    tile_size: int = 32
    origin: tuple[float, float] = (0.0, 0.0)


@dataclass
class LogOddsOccupancyMap:
    """Baseline occupancy grid in log-odds, on the same grid and traversal as the CRM."""

    config: LogOddsConfig = field(default_factory=LogOddsConfig)
    native: _native.LogOddsMap = field(init=False, repr=False)

    def __post_init__(self) -> None:
        c = self.config
        try:
            self.native = _native.LogOddsMap(
                c.resolution,
                c.origin,
                z_max=c.max_range,
                l_occ=c.l_occ,
                l_free=c.l_free,
                l_min=c.l_min,
                l_max=c.l_max,
                base=c.base,
                clear_no_return=c.clear_no_return,
                tile_size=c.tile_size,
            )
        except ValueError as e:
            raise ConfigError(f"LogOddsConfig: {e}") from e

    def update(self, pose: ArrayLike, angles: ArrayLike, ranges: ArrayLike) -> tuple[int, int]:
        """Integrates one scan; returns (beams used, beams dropped)."""
        p, a, r = _check_scan(pose, angles, ranges)
        return self.native.update_scan(p, a, r)

    def update_many(self, poses: ArrayLike, angles: ArrayLike, ranges: ArrayLike) -> tuple[int, int]:
        return self.native.update_scans(_f64(poses), _f64(angles), _f64(ranges))

    def region(self, bounds: tuple[float, float, float, float] | None = None) -> CellRect:
        if bounds is None:
            r = self.native.written_bounds()
            return r if r is not None else (0, 0, 1, 1)
        return _cells_of_box(_box(bounds), self.config.resolution, self.config.origin)

    def probability(self, bounds: tuple[float, float, float, float] | None = None) -> MapLayer:
        """Occupancy probability ``base^l / (1 + base^l)`` over a region."""
        rect = self.region(bounds)
        lo = self.native.log_odds(rect)
        # The logistic as tanh: no overflow for the large values of counting (hit-rate) cells.
        p = 0.5 * (1.0 + np.tanh(0.5 * math.log(self.config.base) * lo))
        res, (ox, oy) = self.config.resolution, self.config.origin
        return MapLayer(p, (ox + rect[0] * res, oy + rect[1] * res), res, "occupancy probability")
