"""Type stubs of the Rust extension ``crlam._native`` (checked with ``mypy.stubtest``)."""

from typing import Any, final

import numpy as np
from numpy.typing import NDArray

__core_version__: str

__all__ = [
    "__core_version__",
    "_guarded_panic",
    "ClamFilter",
    "CrmMap",
    "GpVarianceMap",
    "InfoFunction",
    "InfoUpdate",
    "LocalMapMatcher",
    "LogOddsMap",
    "MclFilter",
    "OccupancyLattice",
    "OgmFilter",
    "ParticleBelief",
    "SensorModel",
    "candidate_seed",
    "loop_match",
    "mode_seeking_pose",
    "geodesic",
    "run_iig",
    "cast_ranges",
    "crm_update_ray",
    "run_benchmark",
    "set_limits",
    "simd_info",
    "simd_level",
    "traverse_ray",
]

_CellRect = tuple[int, int, int, int]

@final
class SensorModel:
    def __new__(
        cls,
        kind: str = "ijrr",
        z_max: float = 8.0,
        resolution: float = 0.2,
        *,
        cause_kernel: str = "midpoint",
        sigma_hit: float | None = None,
        w_hit: float | None = None,
        w_short: float | None = None,
        w_max: float | None = None,
        w_rand: float | None = None,
        lambda_short: float = 0.2,
        z_min: float = 0.0,
    ) -> SensorModel: ...
    @property
    def kind(self) -> str: ...
    @property
    def z_max(self) -> float: ...
    @property
    def cause_kernel(self) -> str: ...
    @property
    def z_min(self) -> float: ...
    @property
    def sigma_hit(self) -> float: ...
    @property
    def w_hit(self) -> float: ...
    @property
    def w_short(self) -> float: ...
    @property
    def w_max(self) -> float: ...
    @property
    def w_rand(self) -> float: ...
    @property
    def lambda_short(self) -> float: ...
    def on_ray(self, z: float, d: float) -> float: ...
    def infinity(self, z: float) -> float: ...

@final
class CrmMap:
    def __new__(
        cls,
        resolution: float,
        origin: tuple[float, float] = ...,
        *,
        n_levels: int = 10,
        levels: str = "midpoints",
        prior_mean: float | None = None,
        belief_floor: float = 1e-12,
        tile_size: int = 32,
        extent: _CellRect | None = None,
    ) -> CrmMap: ...
    @property
    def resolution(self) -> float: ...
    @property
    def origin(self) -> tuple[float, float]: ...
    @property
    def tile_size(self) -> int: ...
    @property
    def levels(self) -> NDArray[np.float64]: ...
    @property
    def placement(self) -> str: ...
    @property
    def prior(self) -> NDArray[np.float64]: ...
    @property
    def belief_floor(self) -> float: ...
    @property
    def extent(self) -> _CellRect | None: ...
    def bounds(self) -> _CellRect: ...
    def written_bounds(self) -> _CellRect | None: ...
    def cell_of(self, x: float, y: float) -> tuple[int, int]: ...
    def mean_at(self, ix: int, iy: int) -> float: ...
    def cell(self, ix: int, iy: int) -> NDArray[np.float32]: ...
    def update_scan(
        self,
        pose: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        model: SensorModel,
        *,
        mode: str = "batch",
        batch_kernel: str = "windowed",
        beam_stride: int = 1,
        zero_is_no_return: bool = False,
        hits_first: bool = False,
    ) -> dict[str, int]: ...
    def update_scans(
        self,
        poses: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        model: SensorModel,
        *,
        mode: str = "batch",
        batch_kernel: str = "windowed",
        beam_stride: int = 1,
        zero_is_no_return: bool = False,
        hits_first: bool = False,
    ) -> dict[str, int]: ...
    def scan_log_likelihood(
        self,
        pose: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        model: SensorModel,
        *,
        beam_stride: int = 1,
        zero_is_no_return: bool = False,
    ) -> tuple[float, int]: ...
    def beliefs(self, rect: _CellRect | None = None) -> NDArray[np.float32]: ...
    def set_beliefs(self, ix0: int, iy0: int, beliefs: NDArray[np.float64]) -> None: ...
    def derived_maps(
        self, rect: _CellRect | None = None
    ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]: ...
    def copy(self) -> CrmMap: ...
    def tile_stats(self) -> dict[str, int]: ...

@final
class LogOddsMap:
    def __new__(
        cls,
        resolution: float,
        origin: tuple[float, float] = ...,
        *,
        z_max: float = 8.0,
        l_occ: float = 1.0,
        l_free: float = ...,
        l_min: float = ...,
        l_max: float = 100.0,
        base: float = 2.0,
        clear_no_return: bool = True,
        tile_size: int = 32,
        extent: _CellRect | None = None,
    ) -> LogOddsMap: ...
    @property
    def resolution(self) -> float: ...
    @property
    def origin(self) -> tuple[float, float]: ...
    @property
    def base(self) -> float: ...
    def bounds(self) -> _CellRect: ...
    def written_bounds(self) -> _CellRect | None: ...
    def update_scan(
        self, pose: NDArray[np.float64], angles: NDArray[np.float64], ranges: NDArray[np.float64]
    ) -> tuple[int, int]: ...
    def update_scans(
        self, poses: NDArray[np.float64], angles: NDArray[np.float64], ranges: NDArray[np.float64]
    ) -> tuple[int, int]: ...
    def log_odds(self, rect: _CellRect | None = None) -> NDArray[np.float64]: ...
    def copy(self) -> LogOddsMap: ...
    def tile_stats(self) -> dict[str, int]: ...

@final
class ClamFilter:
    def __new__(
        cls,
        initial_pose: NDArray[np.float64],
        mapping_model: SensorModel,
        weight_model: SensorModel,
        *,
        n_particles: int = 100,
        resolution: float = 0.2,
        origin: tuple[float, float] = ...,
        n_levels: int = 10,
        levels: str = "midpoints",
        belief_floor: float = 1e-12,
        tile_size: int = 32,
        extent: _CellRect | None = None,
        scan_update: str = "batch",
        batch_kernel: str = "windowed",
        hits_first: bool = False,
        weight_stride: int = 1,
        map_stride: int = 1,
        tempering: float = 1.0,
        tempering_beams: float | None = None,
        resample_threshold: float = 0.5,
        init_sigma: tuple[float, float, float] = ...,
        motion: str = "gaussian",
        motion_params: list[float] | None = None,
        linear_update: float = 0.0,
        angular_update: float = 0.0,
        proposal: str = "odometry",
        proposal_pose: str = "sample",
        match_stride: int = 3,
        lattice_step: tuple[float, float] = ...,  # (0.05, 0.025)
        motion_outlier: float = 0.0,
        scan_match_weight: str = "crm",
        match_range: str | float = ...,  # "z_max"
        hit_means: bool = ...,  # False
        front_end: tuple[float, float] | None = None,
        match_min_score: float = 0.0,
        match_climb: str = "score",
        degeneracy: str = "off",
        seed: int = 0,
        prior_map: CrmMap | None = None,
        initial_cov: NDArray[np.float64] | None = None,
    ) -> ClamFilter: ...
    def process(
        self,
        odom: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> tuple[bool, tuple[float, float, float], float, bool]: ...
    def process_many(
        self,
        odoms: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> dict[str, NDArray[Any]]: ...
    def estimate(self) -> tuple[float, float, float]: ...
    def particle_poses(self) -> NDArray[np.float64]: ...
    def best_path(self) -> NDArray[np.float64]: ...
    def best_path_means(self) -> NDArray[np.float64] | None: ...
    def weighed_set(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...
    def ancestor_means(self, max_lag: int | None = None, proposal_means: bool = False) -> NDArray[np.float64] | None: ...
    def log_weights(self) -> NDArray[np.float64]: ...
    def weights(self) -> NDArray[np.float64]: ...
    @property
    def best_index(self) -> int: ...
    @property
    def n_resamples(self) -> int: ...
    @property
    def n_processed(self) -> int: ...
    @property
    def n_particles(self) -> int: ...
    def best_map(self) -> CrmMap: ...
    def front_end_counts(self) -> tuple[int, int]: ...
    def degenerate_scans(self) -> int: ...
    def map_memory(self) -> tuple[int, int, int]: ...
    def release_maps(self) -> None: ...
    @property
    def maps_released(self) -> bool: ...
    def empty_map(self) -> CrmMap: ...
    def map_scan(
        self,
        map: CrmMap,
        pose: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> None: ...
    def reanchor(self, map: CrmMap, correction: NDArray[np.float64]) -> None: ...

@final
class MclFilter:
    def __new__(
        cls,
        crm: CrmMap,
        rect: _CellRect,
        model: SensorModel,
        *,
        initial_pose: NDArray[np.float64] | None = None,
        initial_cov: NDArray[np.float64] | None = None,
        free_threshold: float = 0.25,
        margin: int = 0,
        n_min: int = 100,
        n_max: int = 5000,
        kld_err: float = 0.01,
        kld_z: float = ...,  # 2.3263478740408408
        bin_xy: float = 0.5,
        bin_theta: float = ...,  # 10 deg
        alpha_slow: float = 0.001,
        alpha_fast: float = 0.1,
        tempering: float = 1.0,
        min_neff: float = 0.0,
        sigma_max: float = 0.0,
        anneal: float = 0.5,
        beam_stride: int = 1,
        max_beams: int = 0,
        motion: str = "gmapping",
        motion_params: list[float] | None = None,
        linear_update: float = 0.0,
        angular_update: float = 0.0,
        spread_update: tuple[float, float] = ...,  # (0.0, 0.0): pyo3 cannot render a tuple default
        spread_limit: float = 0.5,
        resample_threshold: float = 0.5,
        min_cluster: int = 0,
        keep_ratio: float = 1e-3,
        min_bin: int = 0,
        place_xy: float = 0.0,
        place_theta: float = ...,  # 90 deg
        spread_max: int = 0,
        spread_climb: bool = False,
        tail_tolerance: float = 1e-06,
        skip_no_returns: bool = False,
        measurement: str = "crm",
        measurement_params: list[tuple[str, float]] | None = None,
        seed: int = 0,
    ) -> MclFilter: ...
    def process(
        self,
        odom: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> dict[str, Any]: ...
    def reset_pose(self, pose: NDArray[np.float64], cov: NDArray[np.float64]) -> None: ...
    def reset_global(self) -> None: ...
    def estimate(self) -> tuple[float, float, float]: ...
    def particle_poses(self) -> NDArray[np.float64]: ...
    def weights(self) -> NDArray[np.float64]: ...
    def clusters(self) -> list[dict[str, Any]]: ...
    @property
    def averages(self) -> tuple[float, float] | None: ...
    @property
    def n_particles(self) -> int: ...
    @property
    def n_processed(self) -> int: ...
    @property
    def n_free(self) -> int: ...
    def scan_fit(
        self,
        pose: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> tuple[float, float, int]: ...
    def occupied_distance(self, occupied: float) -> NDArray[np.float64]: ...

@final
class OgmFilter:
    def __new__(
        cls,
        initial_pose: NDArray[np.float64],
        *,
        n_particles: int = 30,
        resolution: float = 0.05,
        usable_range: float = 30.0,
        motion: str = "thrun",
        motion_params: list[float] | None = None,
        linear_update: float = 0.0,
        angular_update: float = 0.0,
        resample_threshold: float = 0.5,
        init_sigma: tuple[float, float, float] = ...,
        proposal_pose: str = "sample",
        map_model: str = "log_odds",
        motion_draws: str = "per_update",
        weight_smoothing: float = 3.0,
        seed: int = 0,
    ) -> OgmFilter: ...
    def process(
        self,
        odom: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> tuple[bool, tuple[float, float, float], float, bool]: ...
    def process_many(
        self,
        odoms: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> dict[str, NDArray[Any]]: ...
    def estimate(self) -> tuple[float, float, float]: ...
    def particle_poses(self) -> NDArray[np.float64]: ...
    def best_path(self) -> NDArray[np.float64]: ...
    def best_path_means(self) -> NDArray[np.float64] | None: ...
    def weighed_set(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]: ...
    def ancestor_means(self, max_lag: int | None = None, proposal_means: bool = False) -> NDArray[np.float64] | None: ...
    def log_weights(self) -> NDArray[np.float64]: ...
    def weights(self) -> NDArray[np.float64]: ...
    @property
    def best_index(self) -> int: ...
    @property
    def n_resamples(self) -> int: ...
    @property
    def n_processed(self) -> int: ...
    @property
    def n_particles(self) -> int: ...
    def best_map(self) -> LogOddsMap: ...
    def map_memory(self) -> tuple[int, int, int]: ...
    def release_maps(self) -> None: ...
    @property
    def maps_released(self) -> bool: ...

@final
class LocalMapMatcher:
    def __new__(
        cls,
        *,
        resolution: float = 0.05,
        usable_range: float = 8.0,
        score_sigma: float = 0.05,
        lstep: float = 0.05,
        astep: float = 0.05,
        iterations: int = 5,
        kernel_size: int = 1,
        beam_stride: int = 1,
    ) -> LocalMapMatcher: ...
    def match_scan(
        self,
        start: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> tuple[tuple[float, float, float], float, int, int]: ...
    def insert(
        self,
        pose: NDArray[np.float64],
        angles: NDArray[np.float64],
        ranges: NDArray[np.float64],
        laser_offset: NDArray[np.float64],
    ) -> None: ...
    def clear(self) -> None: ...
    @property
    def n_inserted(self) -> int: ...
    def map(self) -> LogOddsMap: ...

def loop_match(
    world_points: NDArray[np.float64],
    endpoints: NDArray[np.float64],
    guess: NDArray[np.float64],
    *,
    resolution: float,
    linear_window: float,
    angular_window: float,
    penalty: float = 0.0,
    exclude: tuple[tuple[float, float], float] | None = None,
) -> tuple[tuple[float, float, float], float, float, int]: ...
def mode_seeking_pose(
    poses: NDArray[np.float64], weights: NDArray[np.float64], bandwidth: tuple[float, float]
) -> tuple[float, float, float]: ...
def traverse_ray(
    origin_x: float,
    origin_y: float,
    angle: float,
    length: float,
    resolution: float,
    grid_origin: tuple[float, float] = ...,
) -> tuple[NDArray[np.int64], NDArray[np.float64], NDArray[np.float64]]: ...
def cast_ranges(
    occupied: NDArray[np.uint8],
    origin_x: float,
    origin_y: float,
    resolution: float,
    poses: NDArray[np.float64],
    angles: NDArray[np.float64],
    max_range: float,
) -> NDArray[np.float64]: ...
def crm_update_ray(
    beliefs: NDArray[np.float64],
    levels: NDArray[np.float64],
    like: NDArray[np.float64],
    like_inf: float,
    belief_floor: float = 0.0,
) -> tuple[NDArray[np.float64], float]: ...
def run_benchmark(name: str, size: int) -> dict[str, Any]: ...
def simd_level() -> str: ...
def simd_info() -> dict[str, Any]: ...
def _guarded_panic(message: str) -> None: ...
def set_limits(*, map_cells: int | None = None, particles: int | None = None) -> tuple[int, int]: ...

@final
class OccupancyLattice:
    def __new__(
        cls, probabilities: NDArray[np.float64], resolution: float, origin: tuple[float, float] = ...
    ) -> OccupancyLattice: ...
    @property
    def shape(self) -> tuple[int, int]: ...
    @property
    def resolution(self) -> float: ...
    @property
    def origin(self) -> tuple[float, float]: ...
    def probabilities(self) -> NDArray[np.float64]: ...
    def copy(self) -> OccupancyLattice: ...
    def to_crm(self, n_levels: int = 10) -> CrmMap: ...

@final
class GpVarianceMap:
    def __new__(cls, lattice: OccupancyLattice, prior_variance: float = 1.0) -> GpVarianceMap: ...
    def variances(self) -> NDArray[np.float64]: ...
    def copy(self) -> GpVarianceMap: ...

@final
class ParticleBelief:
    @staticmethod
    def from_particles(
        particles: NDArray[np.float64], log_weights: NDArray[np.float64], entropy_nats: float
    ) -> ParticleBelief: ...
    @property
    def particles(self) -> NDArray[np.float64]: ...
    @property
    def weights(self) -> NDArray[np.float64]: ...
    @property
    def entropy_nats(self) -> float: ...
    @property
    def map_gain_bits(self) -> float: ...
    @property
    def pose_gain_bits(self) -> float: ...
    @property
    def resampled(self) -> bool: ...
    def mean_pose(self) -> tuple[float, float, float]: ...
    def position_covariance(self) -> list[list[float]]: ...

@final
class InfoUpdate:
    @property
    def kind(self) -> str: ...
    def summary(self) -> tuple[int, list[float]]: ...

_State = CrmMap | OccupancyLattice | GpVarianceMap

@final
class InfoFunction:
    @staticmethod
    def crmi(
        model: SensorModel,
        *,
        n_beams: int = 10,
        beam_angles: str = "distinct",
        lambda_z: float = 0.1,
        quadrature: str = "cdf",
        dedupe_cells: str = "sum",
        units: str = "bits",
        hit_threshold: float = 0.5,
        variant: str = "exact",
        resolution: float = 0.2,
    ) -> InfoFunction: ...
    @staticmethod
    def ucrmi(
        model: SensorModel,
        weight_model: SensorModel,
        *,
        alpha: float = 0.5,
        n_particles: int = 100,
        n_beams: int = 10,
        beam_angles: str = "distinct",
        lambda_z: float = 0.1,
        quadrature: str = "cdf",
        dedupe_cells: str = "sum",
        hit_threshold: float = 0.5,
        edge_noise: tuple[float, float] = ...,
        root_cov_diag: tuple[float, float, float] = ...,
        resample_threshold: float = 0.5,
    ) -> InfoFunction: ...
    @staticmethod
    def fsmi(
        *,
        variant: str = "full",
        width_sigmas: float = 3.0,
        points_per_cell: int = 16,
        delta_occ: float = 1.5,
        delta_emp: float = ...,
        sigma: float = 0.05,
        z_max: float = 5.0,
        n_beams: int = 10,
        beam_angles: str = "distinct",
        p_occ: float = 0.65,
    ) -> InfoFunction: ...
    @staticmethod
    def iig_mi(
        *,
        upper_bound: bool = False,
        n_beams: int = 10,
        beam_angles: str = "reference",
        z_max: float = 5.0,
        p_occ: float = 0.65,
        int_res: float = 0.5,
    ) -> InfoFunction: ...
    @staticmethod
    def gpvr(*, mode: str = "reference") -> InfoFunction: ...
    @staticmethod
    def ugpvr(*, mode: str = "reference") -> InfoFunction: ...
    @property
    def name(self) -> str: ...
    @property
    def units(self) -> str: ...
    @property
    def state_kind(self) -> str: ...
    @property
    def belief_kind(self) -> str: ...
    def root_belief(self, pose: NDArray[np.float64], seed: int = 0) -> Any: ...
    def evaluate(
        self,
        state: _State,
        pose: NDArray[np.float64],
        *,
        parent: tuple[float, float] | None = None,
        belief: Any = None,
        seed: int = 0,
    ) -> tuple[float, Any, InfoUpdate]: ...
    def commit(self, state: _State, update: InfoUpdate) -> None: ...
    def gains(
        self,
        state: _State,
        poses: NDArray[np.float64],
        *,
        parents: NDArray[np.float64] | None = None,
        belief: Any = None,
        seed: int = 0,
    ) -> NDArray[np.float64]: ...

def candidate_seed(seed: int, index: int) -> int: ...
def run_iig(
    function: InfoFunction,
    state: _State,
    lattice: OccupancyLattice,
    obstacle_points: NDArray[np.float64],
    *,
    mode: str = "reference",
    options: dict[str, Any] | None = None,
    seed: int = 0,
    belief: Any = None,
) -> dict[str, Any]: ...
def geodesic(
    traversable: NDArray[np.bool_] | NDArray[np.uint8],
    start: tuple[int, int],
    res: float,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]: ...
