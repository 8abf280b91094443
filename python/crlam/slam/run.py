"""SLAM with Rao-Blackwellized particle filters: RBPF-CLAM (and the RBPF-OGM baseline).

:class:`SlamConfig` holds every setting with the paper's defaults (defined in
:mod:`crlam.slam.config`); :func:`make_filter` builds the native filter;
:class:`SlamRun` feeds it a stream of scans and keeps one pose per scan.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam import _native
from crlam.errors import ConfigError, CrlamError
from crlam.mapping import ConfidenceRichMap, LogOddsConfig, LogOddsOccupancyMap
from crlam.pose import number_pair
from crlam.slam.config import SlamConfig
from crlam.slam.fill import fill_skipped
from crlam.slam.grid_alignment import WallDirection, from_map_frame, into_map_frame, map_frame, map_turn, walls_found
from crlam.slam.loop_closing import LoopCloser
from crlam.slam.prior import SlamPrior

# The package (crlam.slam) re-exports these with SlamConfig and its constants (crlam.slam.config);
# the users of the library import them from there.
__all__ = [
    "SlamStep",
    "SlamRun",
    "ParticleSetRecord",
    "particle_spread",
    "mode_seeking_pose",
    "make_filter",
]

NativeFilter = _native.ClamFilter | _native.OgmFilter


def make_filter(config: SlamConfig, initial_pose: ArrayLike, prior: SlamPrior | None = None) -> NativeFilter:
    """The native filter for ``config``, with particles at ``initial_pose``.

    RBPF-OGM takes the same particle count, seed, triggers, motion model and grid; its map range
    is ``max_range`` and its scan matcher has GMapping's settings. With a ``prior`` (a saved run,
    :mod:`crlam.slam.prior`; RBPF-CLAM only) every particle starts with its map, at a draw
    from N(prior.pose, prior.cov), and ``initial_pose`` is not used.
    """
    if not isinstance(config, SlamConfig):
        raise TypeError(f"config must be a SlamConfig, got {type(config).__name__}")
    pose = np.ascontiguousarray(initial_pose if prior is None else prior.pose, dtype=np.float64)
    params = list(config.motion_params) if config.motion_params is not None else None
    if prior is not None:
        if config.method != "clam":
            raise ConfigError("SlamConfig.method: continuing a saved run needs RBPF-CLAM (the saved map is a CRM)")
        if prior.map.config.resolution != config.resolution:
            raise ConfigError(
                f"SlamConfig.resolution: {config.resolution} m, but the saved map ({prior.source}) has "
                f"{prior.map.config.resolution} m cells"
            )
    if config.method == "ogm":
        try:
            return _native.OgmFilter(
                pose,
                n_particles=config.particles,
                resolution=config.resolution,
                usable_range=config.max_range,
                motion=config.motion,
                motion_params=params,
                linear_update=config.linear_update,
                angular_update=config.angular_update,
                resample_threshold=config.resample_threshold,
                init_sigma=config.init_sigma,
                proposal_pose=config.proposal_pose,
                map_model=config.ogm_map,
                motion_draws=config.ogm_motion_draws,
                weight_smoothing=config.ogm_weight_smoothing,
                seed=config.seed,
            )
        except ValueError as e:
            raise ConfigError(f"SlamConfig: {e}") from e
    mc = config.mapping_config()
    mapping = mc.sensor_model(config.mapping_model)
    weight = mc.sensor_model(config.weight_model)
    try:
        return _native.ClamFilter(
            pose,
            mapping,
            weight,
            n_particles=config.particles,
            resolution=config.resolution,
            scan_update=config.scan_update,
            batch_kernel=config.batch_kernel,
            hits_first=bool(config.hits_first),
            weight_stride=config.weight_stride,
            map_stride=config.map_stride,
            tempering=config.tempering,
            tempering_beams=None if config.tempering_beams is None else float(config.tempering_beams),
            resample_threshold=config.resample_threshold,
            init_sigma=config.init_sigma,
            motion=config.motion,
            motion_params=params,
            linear_update=config.linear_update,
            angular_update=config.angular_update,
            proposal=config.proposal,
            proposal_pose=config.proposal_pose,
            match_stride=config.match_stride,
            lattice_step=(float(config.lattice_step[0]), float(config.lattice_step[1])),
            motion_outlier=float(config.motion_outlier),
            scan_match_weight=config.scan_match_weight,
            match_range=config.match_range if isinstance(config.match_range, str) else float(config.match_range),
            hit_means=bool(config.hit_means),
            match_min_score=float(config.match_min_score),
            match_climb=config.match_climb,
            degeneracy=config.degeneracy,
            front_end=None
            if config.front_end == "none"
            else (float(config.front_end_window[0]), float(config.front_end_window[1])),
            seed=config.seed,
            prior_map=None if prior is None else prior.map.native,
            initial_cov=None if prior is None else np.ascontiguousarray(prior.cov, dtype=np.float64),
        )
    except ValueError as e:
        raise ConfigError(f"SlamConfig: {e}") from e


def _front_end_window(config: SlamConfig) -> tuple[float, float] | None:
    """The correlative front end's half-widths (m, rad) for the native filter; None when it is off."""
    if config.front_end == "none":
        return None
    return (float(config.front_end_window[0]), float(config.front_end_window[1]))


@dataclass(frozen=True)
class SlamStep:
    """What the filter did with one scan."""

    processed: bool
    estimate: NDArray[np.float64]
    neff: float
    resampled: bool


@dataclass(frozen=True)
class ParticleSetRecord:
    """The particle set after one processed scan, summarised.

    Attributes
    ----------
    scan_index : int
        Index of the scan (file order, from 0).
    neff : float
        Effective sample size of the weights the estimate was taken from (before resampling).
    resampled : bool
        Whether the step resampled.
    estimate : ndarray, shape (3,)
        Weighted-mean pose (x m, y m, θ rad; circular mean heading).
    max_weight : ndarray, shape (3,)
        Pose of the highest-weight particle (after resampling: its first child).
    mode : ndarray, shape (3,)
        Mode-seeking pose (:func:`mode_seeking_pose`) of the set before resampling, with the
        run's ``mode_bandwidth``.
    spread_xy : float
        Weighted RMS distance (m) of the particle positions from their weighted mean, over the
        set the step left (uniform weights after a resampling).
    spread_theta : float
        Circular spread of the headings (rad): sqrt(-2 ln R) with R the weighted mean resultant
        length, which is the standard deviation for a wrapped normal.
    """

    scan_index: int
    neff: float
    resampled: bool
    estimate: NDArray[np.float64]
    max_weight: NDArray[np.float64]
    mode: NDArray[np.float64]
    spread_xy: float
    spread_theta: float


def particle_spread(poses: NDArray[np.float64], log_weights: NDArray[np.float64]) -> tuple[float, float]:
    """Weighted spread of a particle set: (RMS distance from the weighted mean position (m),
    circular heading spread sqrt(-2 ln R) (rad)).

    Parameters
    ----------
    poses : ndarray, shape (n, 3)
        Particle poses (x m, y m, θ rad).
    log_weights : ndarray, shape (n,)
        Unnormalised log-weights.
    """
    lw = np.asarray(log_weights, dtype=np.float64)
    w = np.exp(lw - np.max(lw))
    w /= w.sum()
    xy = poses[:, :2]
    mu = w @ xy
    spread_xy = float(np.sqrt(w @ np.sum((xy - mu) ** 2, axis=1)))
    r = float(np.hypot(w @ np.cos(poses[:, 2]), w @ np.sin(poses[:, 2])))
    spread_theta = float(np.sqrt(max(0.0, -2.0 * np.log(min(max(r, 1e-300), 1.0)))))
    return spread_xy, spread_theta


def mode_seeking_pose(
    poses: ArrayLike, weights: ArrayLike, bandwidth: tuple[float, float] = (0.05, 0.025)
) -> NDArray[np.float64]:
    """The mode of a weighted particle set's kernel density that holds its densest particle.

    Starts at the particle with the highest weighted Gaussian kernel density and climbs by mean
    shift (positions averaged, headings by circular mean, within the kernel). On a compact set
    this is the weighted mean up to the kernel's tails; when the set splits into groups (lineages
    whose maps disagree), it is the weighted mean of the group with the most weight near its
    centre instead of a point between the groups. ``bandwidth = (inf, inf)`` gives the weighted
    mean exactly; a bandwidth far below the particle spacing gives the highest-weight particle.
    O(n²) kernel evaluations.

    Parameters
    ----------
    poses : array_like, shape (n, 3)
        Particle poses (x m, y m, θ rad).
    weights : array_like, shape (n,)
        Weights ≥ 0, not all zero (need not be normalised).
    bandwidth : tuple of float
        Gaussian kernel bandwidths (m, rad), > 0.

    Returns
    -------
    ndarray, shape (3,)

    Raises
    ------
    CrlamError
        Shape mismatch, an empty set, non-finite values, negative or all-zero weights, a
        bandwidth ≤ 0 (a ValueError subclass).
    """
    p = np.ascontiguousarray(poses, dtype=np.float64)
    if p.ndim != 2:
        raise ConfigError(f"mode_seeking_pose: poses must have shape (n, 3), got {p.shape}")
    w = np.ascontiguousarray(weights, dtype=np.float64)
    return np.array(_native.mode_seeking_pose(p, w, number_pair(bandwidth, "bandwidth", finite=False)))


@dataclass
class SlamRun:
    """Feeds scans to a filter and keeps one pose estimate per scan (file order)."""

    config: SlamConfig
    filter: NativeFilter | None = None
    #: A saved run to continue (:mod:`crlam.slam.prior`): its map and final estimate.
    prior: SlamPrior | None = None
    estimates: list[NDArray[np.float64]] = field(default_factory=list)
    stamps: list[float] = field(default_factory=list)
    processed: list[bool] = field(default_factory=list)
    odometry: list[NDArray[np.float64]] = field(default_factory=list)
    particle_sets: list[ParticleSetRecord] = field(default_factory=list)
    # Fixed-lag smoother output (config.smoothing_lag = L): the pose of processed scan k, taken
    # at processed scan k + L; proposal means where the filter records them.
    _lagged: list[NDArray[np.float64]] = field(default_factory=list, repr=False)
    _lagged_means: list[NDArray[np.float64]] = field(default_factory=list, repr=False)
    #: The map's frame in the odometry frame's terms (``config.grid_alignment``; set at the first
    #: scan): ``compose(map_frame, q)`` is odometry pose q in the map's frame. Every pose the run
    #: records, :attr:`odometry` included, is in the map's frame.
    map_frame: NDArray[np.float64] | None = None
    #: The point (x, y m, odometry frame) the map's frame is turned about: the first pose's.
    map_pivot: NDArray[np.float64] | None = None
    #: The first scan's wall direction the turn was taken from (``grid_alignment="walls"``).
    map_walls: WallDirection | None = None
    #: The pose graph and loop search (``config.loop_closing="graph"``; set at the first scan).
    loops: LoopCloser | None = None
    #: The settings the filter runs with (set at the first scan): :attr:`config` with the
    #: sub-cell geometry where ``config.sub_cell`` asks for it (:meth:`SlamConfig.filter_settings`).
    filter_config: SlamConfig | None = None

    @property
    def map_turn(self) -> float:
        """The map frame's turn (rad) against the odometry frame, about the first pose (0: none)."""
        return 0.0 if self.map_frame is None else float(self.map_frame[2])

    @property
    def sub_cell(self) -> bool:
        """Whether the filter runs with the sub-cell geometry (chord causes and hit means,
        ``SlamConfig.sub_cell``); False before the first scan."""
        fc = self.filter_config
        return fc is not None and fc.method == "clam" and fc.cause_kernel == "chord" and fc.hit_means

    def to_odometry_frame(self, poses: ArrayLike) -> NDArray[np.float64]:
        """Poses (..., 3) of this run's map frame in the odometry's frame, e.g. to compare them
        with a reference that starts where the odometry starts."""
        p = np.array(poses, dtype=np.float64)
        return p if self.map_frame is None else from_map_frame(self.map_frame, p)

    def map_frame_record(self) -> dict[str, Any]:
        """What ``metrics.json`` records about the map's frame (``map_frame``)."""
        walls = self.map_walls
        return {
            "grid_alignment": self.config.grid_alignment,
            "turn_deg": math.degrees(self.map_turn),
            "sub_cell": self.sub_cell,
            "pivot": None if self.map_pivot is None else [float(v) for v in self.map_pivot],
            "first_scan_walls": None
            if walls is None
            else {
                "angle_deg": math.degrees(walls.angle),
                "concentration": walls.concentration,
                "wall_length_m": walls.wall_length,
            },
        }

    def _to_map_frame(self, odom: NDArray[np.float64]) -> NDArray[np.float64]:
        return odom if self.map_frame is None else np.ascontiguousarray(into_map_frame(self.map_frame, odom))

    def step(self, odom: ArrayLike, angles: ArrayLike, ranges: ArrayLike, laser_offset: ArrayLike, stamp: float) -> SlamStep:
        """Feeds one scan (odometry pose of the robot, beam bearings, ranges, laser offset).

        The odometry pose is in the odometry's frame; the step's estimate, like every pose the
        run records, is in the map's frame (:attr:`map_frame`)."""
        odom = np.ascontiguousarray(odom, dtype=np.float64)
        if self.filter is None:
            turn = 0.0
            if self.config.grid_alignment == "walls" and self.prior is None:
                turn, self.map_walls = map_turn(angles, ranges, laser_offset, float(odom[2]), max_range=self.config.max_range)
            self.map_pivot = odom[:2].copy()
            self.map_frame = map_frame(turn, self.map_pivot)
            self.filter_config = self.config.filter_settings(self.map_walls is not None and walls_found(self.map_walls))
        odom = self._to_map_frame(odom)
        if self.filter is None:
            self.filter = make_filter(self.filter_config or self.config, odom, self.prior)
            if self.config.loop_closing == "graph":
                base = None if self.prior is None else self.prior.map.native.copy()
                self.loops = LoopCloser(resolution=self.config.resolution, base_map=base)
        angles = np.ascontiguousarray(angles, dtype=np.float64)
        ranges = np.ascontiguousarray(ranges, dtype=np.float64)
        laser_offset = np.ascontiguousarray(laser_offset, dtype=np.float64)
        p, e, n, r = self.filter.process(odom, angles, ranges, laser_offset)
        est = np.array(e)
        if p and self.loops is not None and isinstance(self.filter, _native.ClamFilter):
            self.loops.add_node(self.filter, est, angles, ranges, laser_offset)
        self.odometry.append(odom)
        self.estimates.append(est)
        self.stamps.append(stamp)
        self.processed.append(p)
        if p:
            poses = np.asarray(self.filter.particle_poses(), dtype=np.float64)
            # The weights the filter itself uses: RBPF-OGM's stored log-weights are before
            # GMapping's weight smoothing, which flattens them by ogain · n.
            with np.errstate(divide="ignore"):
                log_w = np.log(np.asarray(self.filter.weights(), dtype=np.float64))
            spread_xy, spread_theta = particle_spread(poses, log_w)
            lag = self.config.smoothing_lag
            if lag is not None:
                for out, use_means in ((self._lagged, False), (self._lagged_means, True)):
                    back = self.filter.ancestor_means(lag, use_means)
                    if back is not None and len(back) > lag:
                        out.append(np.array(back[lag]))
            weighed_poses, weighed_w = self.filter.weighed_set()
            mode = mode_seeking_pose(weighed_poses, weighed_w, self.config.mode_bandwidth)
            self.particle_sets.append(
                ParticleSetRecord(
                    scan_index=len(self.estimates) - 1,
                    neff=float(n),
                    resampled=bool(r),
                    estimate=est,
                    max_weight=poses[self.filter.best_index].copy(),
                    mode=mode,
                    spread_xy=spread_xy,
                    spread_theta=spread_theta,
                )
            )
        return SlamStep(p, est, n, r)

    @property
    def neff(self) -> list[float]:
        """N_eff of every processed scan (before its resampling), in order."""
        return [r.neff for r in self.particle_sets]

    @property
    def n_scans(self) -> int:
        return len(self.estimates)

    def trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(stamps (n,), poses (n, 3)), one per scan in file order: the weighted-mean estimate at
        each processed scan, the others by the ``fill`` rule (:mod:`crlam.slam.fill`).

        :attr:`estimates` keeps the estimates as they stood online (skipped scans: the odometry
        fill).
        """
        if not self.particle_sets or not self.processed[0]:
            return np.array(self.stamps), np.array(self.estimates).reshape(-1, 3)
        if self.loops is not None and self.loops.reanchors > 0:
            return self._fill_path(self.loops.poses(), "pose graph")
        return self.online_trajectory()

    def online_trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """As :meth:`trajectory`, with the weighted-mean estimates as they stood online even when
        loop closing has corrected them since."""
        if not self.particle_sets or not self.processed[0]:
            return np.array(self.stamps), np.array(self.estimates).reshape(-1, 3)
        return self._fill_path(np.array([r.estimate for r in self.particle_sets]), "weighted-mean estimates")

    def best_path_trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(stamps (n,), poses (n, 3)) from the final best particle's path, one per scan in file order.

        At a processed scan the pose is that particle's ancestor's pose there (GMapping's
        trajectory: one lineage, consistent with the map it built); in between, the same fill
        rule as :meth:`trajectory`.
        """
        if self.filter is None:
            raise ConfigError("no scan has been processed yet")
        return self._fill_path(np.asarray(self.filter.best_path(), dtype=np.float64), "best path")

    def best_path_means_trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """As :meth:`best_path_trajectory`, with each processed pose replaced by the mean of the proposal it was drawn from.

        The same lineage without the proposal's draw jitter. ``None`` unless the filter draws its
        poses from a fitted proposal (``proposal="likelihood_mode"`` for RBPF-CLAM, any RBPF-OGM
        run with ``proposal_pose="sample"``).
        """
        if self.filter is None:
            raise ConfigError("no scan has been processed yet")
        means = self.filter.best_path_means()
        if means is None:
            return None
        return self._fill_path(np.asarray(means, dtype=np.float64), "best path means")

    def max_weight_trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(stamps (n,), poses (n, 3)) from the highest-weight particle at each processed scan.

        The online choice of one particle, unlike :meth:`best_path_trajectory`, which follows
        the final best particle's lineage back; in between processed scans, the fill rule of
        :meth:`trajectory`.
        """
        if not self.particle_sets:
            raise ConfigError("no scan has been processed yet")
        return self._fill_path(np.array([r.max_weight for r in self.particle_sets]), "max-weight poses")

    def mode_trajectory(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(stamps (n,), poses (n, 3)) from the mode-seeking estimate at each processed scan
        (:func:`mode_seeking_pose`); in between processed scans, the fill rule of :meth:`trajectory`."""
        if not self.particle_sets:
            raise ConfigError("no scan has been processed yet")
        return self._fill_path(np.array([r.mode for r in self.particle_sets]), "mode poses")

    def smoothed_trajectory(self, proposal_means: bool = False) -> tuple[NDArray[np.float64], NDArray[np.float64]] | None:
        """(stamps (n,), poses (n, 3)) from the lineage smoother, one per scan in file order.

        At processed scan k the pose is the weighted mean of the particles' ancestors at k, weighed
        with the final weights (``smoothing_lag=None``: E[x_k | all scans] under the particle
        approximation; lineages that died carry no weight, and where every lineage has coalesced
        it is the surviving one) or with the weights L processed scans later (``smoothing_lag=L``;
        the last L scans from the final set). Lag 0 is the weighted mean. In between processed
        scans, the fill rule of :meth:`trajectory`. ``proposal_means`` averages the ancestors'
        proposal means instead of their drawn poses; ``None`` then unless the filter records them
        (see :meth:`best_path_means_trajectory`).
        """
        if self.filter is None:
            raise ConfigError("no scan has been processed yet")
        lag = self.config.smoothing_lag
        full = self.filter.ancestor_means(None if lag is None else max(lag - 1, 0), proposal_means)
        if full is None:
            return None
        tail = np.asarray(full, dtype=np.float64)[::-1]
        if lag is not None:
            done = np.array(self._lagged_means if proposal_means else self._lagged).reshape(-1, 3)
            tail = tail[len(tail) - (int(sum(self.processed)) - len(done)) :] if lag > 0 else tail[:0]
            tail = np.vstack([done, tail])
        return self._fill_path(tail, "smoothed poses")

    def _fill_path(self, path: NDArray[np.float64], what: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """One pose per processed scan -> one per scan (the fill rule of :meth:`trajectory`)."""
        processed = np.array(self.processed, dtype=bool)
        if path.shape[0] != int(processed.sum()):
            raise CrlamError(f"{what} has {path.shape[0]} poses for {int(processed.sum())} processed scans")
        poses = fill_skipped(
            path,
            processed,
            np.array(self.odometry).reshape(-1, 3),
            np.array(self.stamps, dtype=np.float64),
            self.config.fill,
            self.config.linear_update,
            self.config.angular_update,
        )
        return np.array(self.stamps), poses

    def release_maps(self) -> None:
        """Frees the particles' maps (a finished run whose map files are written).

        The trajectories, weights and metrics stay readable; :meth:`best_map` and :meth:`step`
        raise :class:`~crlam.errors.ConfigError` afterwards. The freed memory goes back to the
        system (:func:`crlam.process_memory.return_freed_memory`), so what the run's
        figures allocate next does not add to the filter's high-water mark.
        """
        if self.filter is None:
            return
        self.filter.release_maps()
        from crlam.process_memory import return_freed_memory

        return_freed_memory()

    def best_map(self) -> ConfidenceRichMap | LogOddsOccupancyMap:
        """The highest-weight particle's map (crm-spec B7), wrapped for the Python API."""
        if self.filter is None:
            raise ConfigError("no scan has been processed yet")
        if self.filter.maps_released:
            raise ConfigError("the particles' maps were released once the run's map files were written (release_maps)")
        if isinstance(self.filter, _native.OgmFilter):
            lo = LogOddsOccupancyMap(LogOddsConfig(resolution=self.config.resolution, max_range=self.config.max_range))
            lo.native = self.filter.best_map()
            return lo
        m = ConfidenceRichMap((self.filter_config or self.config).mapping_config())
        if self.loops is not None and self.loops.changed_since_rebuild:
            # The graph moved poses since the particles took their map: the map of its poses.
            m.native = self.loops.rebuild_map(self.filter)
        else:
            m.native = self.filter.best_map()
        return m
