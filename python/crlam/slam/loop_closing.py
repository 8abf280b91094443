"""Loop closing beside RBPF-CLAM: a pose graph over the processed scans, closed by wide-window
matches against scans mapped long ago, and the particles re-anchored on the corrected map.

A particle filter closes a loop only if one of its particles happens to come back along the
right path; on a long loop (100-300 m) none does, and the map keeps both copies of the corridor.
This module does what graph SLAM does, beside the filter and without changing what the filter
is (every particle keeps a CRM and its CRM-likelihood weight):

1. **Nodes.** Every processed scan is a node of a pose graph, at the filter's online estimate;
   consecutive nodes are joined by the estimate's relative motion.
2. **Search.** Every :attr:`LoopClosingSettings.search_every` processed scans, when old nodes
   (at least :attr:`~LoopClosingSettings.min_travel` metres of path back) lie near the current
   pose, the scan's endpoints are searched against those nodes' endpoints over a window as wide
   as the drift the path between them allows (:func:`search_window`), by branch and bound
   (:func:`crlam._native.loop_match`), first on a coarse grid, then refined. Nothing of the
   particles' maps is read: the place is found even when no particle's map is right there.
3. **Verification.** A match counts when it explains :attr:`~LoopClosingSettings.min_explained`
   of the scan, when no pose of the window a metre or more away explains nearly as much (a
   corridor's walls fit anywhere along it), when the graph does not already put the scan there
   (the loop is closed: the match adds nothing), and when a second match, from a later scan, implies the same correction
   (:attr:`~LoopClosingSettings.agree_xy`, :attr:`~LoopClosingSettings.agree_theta`): a corridor's
   look-alike or a door seen twice rarely agrees with itself twice. Verified matches become
   edges of the graph, with a Cauchy loss so that a wrong one that slips through is outvoted.
4. **Consistency.** The solved graph is kept only if it makes the map agree with itself where
   the robot has been twice: more scan endpoints must fall in cells that are hit from at least
   :attr:`~LoopClosingSettings.min_travel` metres of path apart (:func:`revisited_endpoints`)
   than before the new edges. A right closure lays the second pass's walls onto the first;
   a wrong one (a corridor passed in opposite directions, a match a few decimetres off) pulls
   walls that already lay on each other apart. Otherwise the new edges are dropped and the
   graph stays as it was.
5. **Correction.** The graph is solved by Gauss-Newton over its sparse normal equations
   (:func:`optimize_pose_graph`). When the current node moves by more than 0.4 m or 2 deg,
   the map is rebuilt from every processed scan at its corrected pose, with the filter's own
   mapping model, and every particle takes that map and moves by the current node's correction
   (``ClamFilter.reanchor``): their spread and weights stay.

Once the graph has re-anchored the filter, the run's trajectory is the graph's (every processed
scan's corrected pose); the online estimates stay in :attr:`crlam.slam.SlamRun.particle_sets`.
Until then the graph has found nothing beyond the filter's own reach, and the trajectory stays
the filter's.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import scipy.sparse
import scipy.sparse.linalg
from numpy.typing import NDArray

from crlam import _native
from crlam.pose import compose, inverse, transform_points, wrap_angle
from crlam.process_memory import return_freed_memory

Array = NDArray[np.float64]


@dataclass(frozen=True)
class LoopClosingSettings:
    """The rule of loop closing; the values are not tuned per log (docs/method/loop-closing.md)."""

    #: Most endpoints a node keeps for the search (every k-th return).
    node_endpoints: int = 240
    #: Metres of path between an old node and the current one before the old one may close a loop
    #: (closer nodes are in the particles' maps anyway).
    min_travel: float = 15.0
    #: Processed scans between two searches.
    search_every: int = 2
    #: Farthest endpoint (m) a node keeps: beyond, walls are too sparse to match on.
    max_reach: float = 15.0
    #: Drift the search window allows per metre of path between the old node and the current one
    #: (x and y each), and its least and largest half-width (m).
    drift_per_metre: float = 0.03
    min_linear_window: float = 1.0
    max_linear_window: float = 6.0
    #: The same for heading (rad per metre of path; least and largest half-width, rad).
    heading_drift_per_metre: float = 0.002
    min_angular_window: float = 0.15
    max_angular_window: float = 0.45
    #: Cell of the coarse search (m); the refinement searches +-``refine_linear`` m and
    #: +-``refine_angular`` rad on the filter's own grid.
    coarse_resolution: float = 0.2
    refine_linear: float = 0.3
    refine_angular: float = 0.06
    #: Share of the scan's endpoints a match must explain (mean likelihood-field value, the field
    #: one cell wide) on the coarse and the fine grid.
    min_explained: float = 0.55
    min_explained_fine: float = 0.45
    #: The ambiguity test: the best pose farther than ``exclusion_radius`` m from the match may
    #: explain at most ``max_second_share`` of what the match explains.
    exclusion_radius: float = 1.0
    max_second_share: float = 0.8
    #: A match whose guess already explains this share of what the match explains finds the
    #: loop closed (the particles closed it): it adds no edge.
    closed_share: float = 0.85
    #: Fewest endpoints of a scan worth a search.
    min_endpoints: int = 40
    #: Two matches agree when the corrections they imply move the current pose within these.
    agree_xy: float = 0.3
    agree_theta: float = 0.05
    #: Old nodes read per search (the nearest ones to the guess).
    max_search_nodes: int = 120
    #: Standard deviations of a loop edge (m, rad) and of the odometry-like chain between nodes:
    #: ``chain_xy + chain_xy_per_metre * d`` and ``chain_theta + chain_theta_per_rad * |dtheta|``.
    loop_sigma_xy: float = 0.05
    loop_sigma_theta: float = 0.01
    chain_xy: float = 0.01
    chain_xy_per_metre: float = 0.02
    chain_theta: float = 0.002
    chain_theta_per_rad: float = 0.02
    #: The Cauchy loss's scale on a loop edge's whitened residual.
    cauchy_scale: float = 2.0
    #: A correction of the current node beyond these (m, rad) rebuilds the map and re-anchors
    #: the particles: beyond the reach of the filter's own pose search (the correlative front
    #: end's +-0.4 m; 2 deg moves an endpoint 8 m away by 0.3 m). Smaller errors the particles'
    #: scan match corrects itself, and their maps keep their diversity.
    reanchor_xy: float = 0.4
    reanchor_theta: float = math.radians(2.0)


def search_window(travel: float, settings: LoopClosingSettings) -> tuple[float, float]:
    """Half-widths (m, rad) of the loop search after ``travel`` metres of path: the drift the
    estimate may have gathered along it, within the settings' bounds."""
    s = settings
    lin = min(max(s.drift_per_metre * travel, s.min_linear_window), s.max_linear_window)
    ang = min(max(s.heading_drift_per_metre * travel, s.min_angular_window), s.max_angular_window)
    return lin, ang


def scan_endpoints(angles: Array, ranges: Array, laser_offset: Array, *, max_reach: float, most: int) -> NDArray[np.float64]:
    """Endpoints (k, 2; robot frame, m) of the scan's returns within ``max_reach`` m, thinned to
    at most ``most`` by taking every j-th in beam order."""
    ok = np.isfinite(ranges) & (ranges > 0.0) & (ranges <= max_reach)
    a, r = angles[ok], ranges[ok]
    if a.size > most:
        keep = np.linspace(0, a.size - 1, most).round().astype(np.intp)
        a, r = a[keep], r[keep]
    return transform_points(laser_offset, np.stack([r * np.cos(a), r * np.sin(a)], axis=-1).reshape(-1, 2))


def _edge_residuals(x: Array, i: NDArray[np.intp], j: NDArray[np.intp], z: Array) -> tuple[Array, Array, Array]:
    """Residuals (m, 3) of the edges i -> j with measurements z (m, 3) at poses x (n, 3), and the
    Jacobians (m, 3, 3) with respect to x_i and x_j."""
    xi, xj = x[i], x[j]
    ci, si = np.cos(xi[:, 2]), np.sin(xi[:, 2])
    cz, sz = np.cos(z[:, 2]), np.sin(z[:, 2])
    dx, dy = xj[:, 0] - xi[:, 0], xj[:, 1] - xi[:, 1]
    # x_i^-1 x_j, then z^-1 of it.
    lx, ly = ci * dx + si * dy, -si * dx + ci * dy
    ex, ey = lx - z[:, 0], ly - z[:, 1]
    r = np.empty((len(i), 3))
    r[:, 0] = cz * ex + sz * ey
    r[:, 1] = -sz * ex + cz * ey
    r[:, 2] = wrap_angle(xj[:, 2] - xi[:, 2] - z[:, 2])
    m = len(i)
    # d(lx, ly)/d(x_i) and d/d(x_j); then rotated by z^-1.
    dli = np.zeros((m, 2, 3))
    dli[:, 0, 0], dli[:, 0, 1], dli[:, 0, 2] = -ci, -si, ly
    dli[:, 1, 0], dli[:, 1, 1], dli[:, 1, 2] = si, -ci, -lx
    dlj = np.zeros((m, 2, 3))
    dlj[:, 0, 0], dlj[:, 0, 1] = ci, si
    dlj[:, 1, 0], dlj[:, 1, 1] = -si, ci
    rz = np.empty((m, 2, 2))
    rz[:, 0, 0], rz[:, 0, 1], rz[:, 1, 0], rz[:, 1, 1] = cz, sz, -sz, cz
    ji = np.zeros((m, 3, 3))
    jj = np.zeros((m, 3, 3))
    ji[:, :2, :] = np.einsum("mab,mbc->mac", rz, dli)
    jj[:, :2, :] = np.einsum("mab,mbc->mac", rz, dlj)
    ji[:, 2, 2], jj[:, 2, 2] = -1.0, 1.0
    return r, ji, jj


def optimize_pose_graph(
    poses: Array,
    edges_i: NDArray[np.intp],
    edges_j: NDArray[np.intp],
    measurements: Array,
    sigmas: Array,
    robust: NDArray[np.bool_],
    *,
    cauchy_scale: float = 2.0,
    iterations: int = 20,
    tolerance: float = 1e-6,
) -> Array:
    """Least-squares poses of a 2-D pose graph, node 0 held fixed.

    Parameters
    ----------
    poses : (n, 3) array
        Initial node poses (x, y m; theta rad).
    edges_i, edges_j : (m,) int arrays
        Each edge's nodes; its measurement is the pose of node j in node i's frame.
    measurements : (m, 3) array
        The relative poses x_i^-1 x_j measured.
    sigmas : (m, 3) or (m, 3, 3) array
        Standard deviations of each edge's residual (m, m, rad), or each edge's square-root
        information S (S^T S the inverse covariance of the residual, which is in node j's frame
        for the translation).
    robust : (m,) bool array
        Edges under a Cauchy loss of scale ``cauchy_scale`` (on the whitened residual's norm),
        by iteratively reweighted least squares; the others are plain squares.

    Returns
    -------
    (n, 3) array
        The optimised poses (Gauss-Newton on the sparse normal equations, solved by SuperLU).
    """
    x = np.array(poses, dtype=np.float64)
    n = len(x)
    if n < 2 or len(edges_i) == 0:
        return x
    i = np.asarray(edges_i, dtype=np.intp)
    j = np.asarray(edges_j, dtype=np.intp)
    z = np.asarray(measurements, dtype=np.float64)
    sig = np.asarray(sigmas, dtype=np.float64)
    sqrt_info = sig if sig.ndim == 3 else np.einsum("mi,ij->mij", 1.0 / sig, np.eye(3))
    m = len(i)
    rows = np.repeat(np.arange(3 * m).reshape(m, 3), 3, axis=1).reshape(m, 3, 3)
    cols_i = (3 * i)[:, None, None] + np.arange(3)[None, None, :]
    cols_j = (3 * j)[:, None, None] + np.arange(3)[None, None, :]
    cols_i = np.broadcast_to(cols_i, (m, 3, 3))
    cols_j = np.broadcast_to(cols_j, (m, 3, 3))
    # Plain least squares first, then the Cauchy loss from there: started at the drifted poses,
    # the loss would take the loop edges themselves (whose residuals are the whole drift) for
    # outliers; at the plain solution a right edge fits and a wrong one stands out.
    for phase in (False, True) if robust.any() else (False,):
        for _ in range(iterations):
            r, ji, jj = _edge_residuals(x, i, j, z)
            scale = np.ones(m)
            rw = np.einsum("mij,mj->mi", sqrt_info, r)
            if phase:
                norm2 = np.sum(rw[robust] ** 2, axis=1)
                # IRLS weight of the Cauchy loss rho(s) = c^2 log(1 + s / c^2): rho'(s).
                scale[robust] = 1.0 / (1.0 + norm2 / cauchy_scale**2)
            ws = sqrt_info * np.sqrt(scale)[:, None, None]
            rw = rw * np.sqrt(scale)[:, None]
            data = np.concatenate([np.einsum("mij,mjk->mik", ws, ji).ravel(), np.einsum("mij,mjk->mik", ws, jj).ravel()])
            jac = scipy.sparse.csr_matrix(
                (data, (np.concatenate([rows.ravel(), rows.ravel()]), np.concatenate([cols_i.ravel(), cols_j.ravel()]))),
                shape=(3 * m, 3 * n),
            )[:, 3:]  # node 0 fixed: its columns dropped
            h = (jac.T @ jac).tocsc() + scipy.sparse.identity(3 * (n - 1), format="csc") * 1e-9
            step = -scipy.sparse.linalg.spsolve(h, jac.T @ rw.ravel()).reshape(-1, 3)
            x[1:] += step
            x[1:, 2] = wrap_angle(x[1:, 2])
            if float(np.max(np.abs(step))) < tolerance:
                break
    return x


@dataclass
class _Match:
    node: int  # the current node when searched
    old_node: int  # the old node nearest the match
    pose: Array  # the matched pose of `node`, in the graph's frame
    guess: Array  # the graph's pose of `node` when searched
    explained: float
    sqrt_information: Array  # (3, 3): the edge's square-root information


@dataclass
class LoopCloser:
    """The pose graph and loop search beside one RBPF-CLAM filter (see the module documentation).

    Feed it every processed scan with :meth:`add_node`; it returns the correction it applied to
    the filter (or ``None``).
    """

    resolution: float
    settings: LoopClosingSettings = field(default_factory=LoopClosingSettings)
    #: The map a continued run started from (:mod:`crlam.slam.prior`): a rebuilt map starts
    #: from a copy of it, since its scans are not in the graph.
    base_map: _native.CrmMap | None = None
    #: Graph poses (n, 3) of the processed scans, in order.
    _poses: list[Array] = field(default_factory=list)
    _travel: list[float] = field(default_factory=list)
    _endpoints: list[NDArray[np.float64]] = field(default_factory=list)
    _scans: list[tuple[Array, NDArray[np.float32], Array]] = field(default_factory=list)
    _edges: list[tuple[int, int, Array, Array, bool]] = field(default_factory=list)
    _last_online: Array | None = None
    _pending: list[_Match] = field(default_factory=list)
    #: What happened, for metrics.json.
    searches: int = 0
    ambiguous: int = 0
    already_closed: int = 0
    matches: int = 0
    loops_closed: int = 0
    reanchors: int = 0
    inconsistent: int = 0
    #: Each solved closure: the node, how far it moved the current pose, the revisited endpoints
    #: before and after, and whether the graph kept it.
    closures: list[dict[str, Any]] = field(default_factory=list)
    largest_correction_m: float = 0.0
    #: Each re-anchoring: the node (processed scan, from 0) and how far its pose moved.
    reanchorings: list[dict[str, float]] = field(default_factory=list)
    _optimised_since_rebuild: bool = False

    @property
    def n_nodes(self) -> int:
        return len(self._poses)

    def poses(self) -> Array:
        """Graph poses (n, 3) of the processed scans."""
        return np.array(self._poses).reshape(-1, 3)

    def add_node(
        self,
        filt: _native.ClamFilter,
        online: Array,
        angles: Array,
        ranges: Array,
        laser_offset: Array,
    ) -> Array | None:
        """Adds the processed scan with the filter's online estimate ``online``; searches, closes
        and re-anchors the filter when the rule says so. Returns the correction applied (the
        rigid transform new = correction ∘ old) or ``None``."""
        s = self.settings
        online = np.asarray(online, dtype=np.float64)
        if self._last_online is None:
            pose = online.copy()
            travel = 0.0
        else:
            rel = compose(inverse(self._last_online), online)
            pose = compose(self._poses[-1], rel)
            d = float(math.hypot(rel[0], rel[1]))
            travel = self._travel[-1] + d
            sig = np.array(
                [
                    s.chain_xy + s.chain_xy_per_metre * d,
                    s.chain_xy + s.chain_xy_per_metre * d,
                    s.chain_theta + s.chain_theta_per_rad * abs(float(rel[2])) + 0.2 * s.chain_xy_per_metre * d,
                ]
            )
            self._edges.append((self.n_nodes - 1, self.n_nodes, rel, np.diag(1.0 / sig), False))
        self._last_online = online.copy()
        self._poses.append(np.asarray(pose, dtype=np.float64))
        self._travel.append(travel)
        self._endpoints.append(scan_endpoints(angles, ranges, laser_offset, max_reach=s.max_reach, most=s.node_endpoints))
        same = bool(self._scans) and self._scans[-1][0].shape == angles.shape and np.array_equal(self._scans[-1][0], angles)
        self._scans.append(
            (self._scans[-1][0] if same else np.array(angles), np.asarray(ranges, dtype=np.float32), np.array(laser_offset))
        )
        if (self.n_nodes - 1) % s.search_every != 0:
            return None
        match = self._search(self.n_nodes - 1)
        if match is None:
            return None
        self.matches += 1
        agreeing = [m for m in self._pending if self._agree(m, match)]
        self._pending = [m for m in self._pending if self.n_nodes - 1 - m.node <= 20 * s.search_every] + [match]
        if not agreeing:
            return None
        # The graph moves (or not): matches still pending were measured in its old frame.
        self._pending = []
        if not self._close([*agreeing, match]):
            return None
        return self._maybe_reanchor(filt, online)

    def _close(self, matches: list[_Match]) -> bool:
        """Adds the matches' loop edges and solves the graph; keeps the solution only if it makes
        the map agree better with itself where the robot has been twice (the module's step 4).
        Returns whether it was kept."""
        before = self.poses()
        n_edges, optimised = len(self._edges), self._optimised_since_rebuild
        revisited_before = self._revisited(before)
        for m in matches:
            z = compose(inverse(self._poses[m.old_node]), m.pose)
            self._edges.append((m.old_node, m.node, z, m.sqrt_information, True))
        self._optimise()
        revisited_after = self._revisited(self.poses())
        kept = revisited_after > revisited_before
        self.closures.append(
            {
                "node": self.n_nodes - 1,
                "moved_m": float(math.hypot(*(self._poses[-1][:2] - before[-1][:2]))),
                "revisited_endpoints_before": revisited_before,
                "revisited_endpoints_after": revisited_after,
                "kept": kept,
            }
        )
        if not kept:
            # The closure pulls apart what the passes agreed on: the graph goes back.
            self._poses = list(before)
            del self._edges[n_edges:]
            self._optimised_since_rebuild = optimised
            self.inconsistent += 1
            return False
        self.loops_closed += 1
        return True

    def _revisited(self, poses: Array) -> int:
        return revisited_endpoints(poses, self._endpoints, np.array(self._travel), self.resolution, self.settings.min_travel)

    def _agree(self, a: _Match, b: _Match) -> bool:
        """Whether two matches imply the same correction of the graph at b's pose."""
        s = self.settings
        ca = compose(a.pose, inverse(a.guess))
        cb = compose(b.pose, inverse(b.guess))
        pa, pb = compose(ca, b.guess), compose(cb, b.guess)
        return bool(
            math.hypot(pa[0] - pb[0], pa[1] - pb[1]) <= s.agree_xy and abs(float(wrap_angle(pa[2] - pb[2]))) <= s.agree_theta
        )

    def _search(self, c: int) -> _Match | None:
        s = self.settings
        ends = self._endpoints[c]
        if len(ends) < s.min_endpoints:
            return None
        travel = np.array(self._travel)
        old = np.flatnonzero(travel <= travel[c] - s.min_travel)
        if old.size == 0:
            return None
        poses = self.poses()
        guess = poses[c]
        dist = np.hypot(poses[old, 0] - guess[0], poses[old, 1] - guess[1])
        lin_max, _ = search_window(float(travel[c] - travel[old].min()), s)
        near = old[dist <= s.max_reach + lin_max]
        near = _earlier_visit(near, int(old.max()))
        if near.size == 0:
            return None
        near = near[np.argsort(np.hypot(poses[near, 0] - guess[0], poses[near, 1] - guess[1]))[: s.max_search_nodes]]
        lin, ang = search_window(float(travel[c] - travel[near].max()), s)
        points = np.vstack([transform_points(poses[k], self._endpoints[k]) for k in near])
        if len(points) < s.min_endpoints:
            return None
        self.searches += 1
        pose, explained, explained_at_guess, _ = _native.loop_match(
            np.ascontiguousarray(points),
            np.ascontiguousarray(ends),
            np.ascontiguousarray(guess),
            resolution=max(s.coarse_resolution, self.resolution),
            linear_window=lin,
            angular_window=ang,
        )
        if explained < s.min_explained:
            return None
        if explained_at_guess >= s.closed_share * explained:
            # The graph already puts the scan where the old scans saw it: this loop is closed
            # (by the particles or by an earlier correction), and the match adds nothing.
            self.already_closed += 1
            return None
        fine, explained_fine, _, _ = _native.loop_match(
            np.ascontiguousarray(points),
            np.ascontiguousarray(ends),
            np.array(pose, dtype=np.float64),
            resolution=self.resolution,
            linear_window=s.refine_linear,
            angular_window=s.refine_angular,
        )
        if explained_fine < s.min_explained_fine:
            return None
        # The ambiguity test: the best pose elsewhere in the window (beyond the exclusion radius)
        # must explain clearly less, or the match is one of a corridor's look-alikes.
        _, explained_elsewhere, _, _ = _native.loop_match(
            np.ascontiguousarray(points),
            np.ascontiguousarray(ends),
            np.ascontiguousarray(guess),
            resolution=max(s.coarse_resolution, self.resolution),
            linear_window=lin,
            angular_window=ang,
            exclude=((float(fine[0]), float(fine[1])), s.exclusion_radius),
        )
        if explained_elsewhere > s.max_second_share * explained:
            self.ambiguous += 1
            return None
        matched = np.array(fine, dtype=np.float64)
        nearest = int(near[np.argmin(np.hypot(poses[near, 0] - matched[0], poses[near, 1] - matched[1]))])
        return _Match(
            node=c,
            old_node=nearest,
            pose=matched,
            guess=guess.copy(),
            explained=float(explained_fine),
            sqrt_information=np.diag(1.0 / np.array([s.loop_sigma_xy, s.loop_sigma_xy, s.loop_sigma_theta])),
        )

    def _optimise(self) -> None:
        i = np.array([e[0] for e in self._edges], dtype=np.intp)
        j = np.array([e[1] for e in self._edges], dtype=np.intp)
        z = np.array([e[2] for e in self._edges])
        sig = np.array([e[3] for e in self._edges]).reshape(-1, 3, 3)
        robust = np.array([e[4] for e in self._edges], dtype=bool)
        x = optimize_pose_graph(self.poses(), i, j, z, sig, robust, cauchy_scale=self.settings.cauchy_scale)
        self._poses = list(x)
        self._optimised_since_rebuild = True

    def _maybe_reanchor(self, filt: _native.ClamFilter, online: Array) -> Array | None:
        s = self.settings
        new = self._poses[-1]
        moved = math.hypot(new[0] - online[0], new[1] - online[1])
        turned = abs(float(wrap_angle(new[2] - online[2])))
        self.largest_correction_m = max(self.largest_correction_m, moved)
        if moved <= s.reanchor_xy and turned <= s.reanchor_theta:
            return None
        correction = compose(new, inverse(online))
        filt.reanchor(self.rebuild_map(filt), np.ascontiguousarray(correction))
        # The particles' old maps were allocated on the filter's worker threads and are freed
        # now, while the rebuilt map was allocated on this thread: without handing the freed
        # memory back, each re-anchoring leaves a map's worth of resident memory behind.
        return_freed_memory()
        self.reanchorings.append({"node": self.n_nodes - 1, "moved_m": moved, "turned_deg": math.degrees(turned)})
        self._last_online = compose(correction, self._last_online) if self._last_online is not None else None
        self.reanchors += 1
        self._optimised_since_rebuild = False
        return correction

    def rebuild_map(self, filt: _native.ClamFilter) -> _native.CrmMap:
        """A CRM of every processed scan at its graph pose, mapped as the filter maps a particle's."""
        m = filt.empty_map() if self.base_map is None else self.base_map.copy()
        for pose, (angles, ranges, offset) in zip(self._poses, self._scans, strict=True):
            filt.map_scan(
                m,
                np.ascontiguousarray(pose),
                np.ascontiguousarray(angles, dtype=np.float64),
                np.ascontiguousarray(ranges, dtype=np.float64),
                np.ascontiguousarray(offset, dtype=np.float64),
            )
        return m

    @property
    def changed_since_rebuild(self) -> bool:
        """Whether the graph moved poses since the particles last took a rebuilt map."""
        return self._optimised_since_rebuild

    def record(self) -> dict[str, Any]:
        """What ``metrics.json`` reports under ``loop_closing``."""
        return {
            "nodes": self.n_nodes,
            "searches": self.searches,
            "ambiguous": self.ambiguous,
            "already_closed": self.already_closed,
            "matches": self.matches,
            "loops_closed": self.loops_closed,
            "reanchors": self.reanchors,
            "largest_correction_m": self.largest_correction_m,
            "loop_edges": [
                {"old_node": int(e[0]), "node": int(e[1]), "relative_pose": [float(v) for v in e[2]]} for e in self._edges if e[4]
            ],
            "reanchorings": self.reanchorings,
            "inconsistent": self.inconsistent,
            "closures": self.closures,
        }


def revisited_endpoints(
    poses: Array, endpoints: list[NDArray[np.float64]], travel: Array, resolution: float, min_travel: float
) -> int:
    """How many endpoints fall in cells that scans hit from at least ``min_travel`` metres of path
    apart: the map's agreement with itself where the robot has been twice.

    Parameters
    ----------
    poses : (n, 3) float64
        Each node's pose (x, y in m; theta in rad).
    endpoints : list of (k_i, 2) float64
        Each node's scan endpoints in its own frame (m).
    travel : (n,) float64
        Each node's path length from the start (m).
    resolution : float
        Cell size (m).
    min_travel : float
        Path (m) between two hits of a cell for the cell to count as seen twice.
    """
    if not endpoints:
        return 0
    points = np.vstack([transform_points(p, e) for p, e in zip(poses, endpoints, strict=True)])
    along = np.repeat(np.asarray(travel, dtype=np.float64), [len(e) for e in endpoints])
    cells = np.floor(points / resolution).astype(np.int64)
    key = cells[:, 0] * (1 << 32) + cells[:, 1]  # unique while each cell index is below 2^31 in size
    order = np.argsort(key, kind="stable")
    key, along = key[order], along[order]
    starts = np.flatnonzero(np.r_[True, key[1:] != key[:-1]])
    spread = np.maximum.reduceat(along, starts) - np.minimum.reduceat(along, starts)
    hits = np.diff(np.r_[starts, key.size])
    return int(hits[spread >= min_travel].sum())


def _earlier_visit(near: NDArray[np.intp], newest_old: int) -> NDArray[np.intp]:
    """Of the old nodes near the current pose (sorted indices), those of the nearest earlier
    visit: the run of consecutive nodes that leads up to the newest old node is the robot's own
    recent path (the particles' maps hold it, and its drift against the current pose is small),
    so it is left out; of the other runs, the latest one (the others are older visits still)."""
    if near.size == 0:
        return near
    breaks = np.flatnonzero(np.diff(near) > 1) + 1
    runs = np.split(near, breaks)
    if runs[-1][-1] == newest_old:
        runs = runs[:-1]
    return runs[-1] if runs else near[:0]
