"""Loop closing (crlam.slam.loop_closing): the pose graph, the wide search, the particles' re-anchoring,
and a simulated long loop whose odometry drifts metres that closes only with it."""

from __future__ import annotations

import math

import numpy as np
import pytest

from crlam import _native
from crlam.errors import ConfigError
from crlam.pose import between, compose
from crlam.slam import SlamConfig, SlamRun
from crlam.slam.loop_closing import (
    LoopCloser,
    LoopClosingSettings,
    _Match,
    optimize_pose_graph,
    revisited_endpoints,
    scan_endpoints,
    search_window,
)


def _chain(truth: np.ndarray) -> np.ndarray:
    return np.array([between(truth[k], truth[k + 1]) for k in range(len(truth) - 1)])


def _square(n_side: int = 10, side: float = 10.0) -> np.ndarray:
    """Poses around a square, counter-clockwise, back to the start."""
    poses = []
    for leg in range(4):
        th = leg * math.pi / 2
        x0, y0 = [(0, 0), (side, 0), (side, side), (0, side)][leg]
        for k in range(n_side):
            t = side * k / n_side
            poses.append([x0 + t * math.cos(th), y0 + t * math.sin(th), th])
    poses.append([0.0, 0.0, 0.0])
    return np.array(poses)


def _drifted(truth: np.ndarray, heading_bias: float) -> tuple[np.ndarray, np.ndarray]:
    """Relative motions with a heading bias per step, and the poses they chain to."""
    rel = _chain(truth)
    rel[:, 2] += heading_bias
    poses = [truth[0]]
    for r in rel:
        poses.append(compose(poses[-1], r))
    return rel, np.array(poses)


def test_a_loop_edge_pulls_a_drifted_square_back() -> None:
    truth = _square()
    rel, drifted = _drifted(truth, 0.01)
    n = len(truth)
    i = np.arange(n - 1)
    sig = np.tile([0.02, 0.02, 0.005], (n - 1, 1))
    # Without the loop edge the chain is already its own optimum: nothing moves.
    alone = optimize_pose_graph(drifted, i, i + 1, rel, sig, np.zeros(n - 1, bool))
    assert np.hypot(*(alone[-1, :2] - truth[-1, :2])) > 2.0
    # The loop edge: the last pose is the first one.
    ii, jj = np.append(i, 0), np.append(i + 1, n - 1)
    z = np.vstack([rel, [0.0, 0.0, 0.0]])
    s = np.vstack([sig, [0.01, 0.01, 0.002]])
    closed = optimize_pose_graph(drifted, ii, jj, z, s, np.append(np.zeros(n - 1, bool), True))
    assert np.hypot(*(closed[-1, :2] - truth[-1, :2])) < 0.1
    # The whole square is within a fraction of its drift of the truth (the bias spread back).
    assert np.max(np.hypot(*(closed[:, :2] - truth[:, :2]).T)) < 0.6
    assert closed[0] == pytest.approx(drifted[0])


def test_a_wrong_loop_edge_is_outvoted_by_the_cauchy_loss() -> None:
    truth = _square()
    rel = _chain(truth)
    n = len(truth)
    i = np.arange(n - 1)
    sig = np.tile([0.02, 0.02, 0.005], (n - 1, 1))
    # Right edges: the last pose is the first; a wrong one claims pose 25 is pose 5 moved 3 m.
    ii = np.concatenate([i, [0, 0, 5]])
    jj = np.concatenate([i + 1, [n - 1, 1, 25]])
    z = np.vstack([rel, [0.0, 0.0, 0.0], rel[0], [3.0, 0.0, 0.0]])
    s = np.vstack([sig, np.tile([0.05, 0.05, 0.01], (3, 1))])
    robust = np.append(np.zeros(n - 1, bool), [True, True, True])
    out = optimize_pose_graph(truth, ii, jj, z, s, robust)
    assert np.max(np.hypot(*(out[:, :2] - truth[:, :2]).T)) < 0.15
    plain = optimize_pose_graph(truth, ii, jj, z, s, np.zeros(len(ii), bool))
    assert np.max(np.hypot(*(plain[:, :2] - truth[:, :2]).T)) > 0.3


def test_the_search_window_grows_with_the_path_within_its_bounds() -> None:
    s = LoopClosingSettings()
    assert search_window(0.0, s) == (s.min_linear_window, s.min_angular_window)
    lin, ang = search_window(100.0, s)
    assert lin == pytest.approx(100.0 * s.drift_per_metre)
    assert ang == pytest.approx(100.0 * s.heading_drift_per_metre)
    assert search_window(1e6, s) == (s.max_linear_window, s.max_angular_window)


def test_endpoints_are_thinned_and_put_in_the_robot_frame() -> None:
    angles = np.linspace(-math.pi / 2, math.pi / 2, 181)
    ranges = np.full(181, 2.0)
    ranges[:10] = np.inf
    ranges[10:20] = 30.0
    pts = scan_endpoints(angles, ranges, np.array([0.5, 0.0, math.pi]), max_reach=15.0, most=50)
    assert len(pts) == 50
    # Mounted backwards 0.5 m ahead: every endpoint lies 2 m from (0.5, 0), behind it.
    assert np.hypot(pts[:, 0] - 0.5, pts[:, 1]) == pytest.approx(np.full(50, 2.0))
    assert np.all(pts[:, 0] <= 0.5 + 1e-9)


def test_loop_closing_needs_rbpf_clam() -> None:
    with pytest.raises(ConfigError, match="loop_closing"):
        SlamConfig(method="ogm", loop_closing="graph")
    with pytest.raises(ConfigError, match="loop_closing"):
        SlamConfig(loop_closing="always")


def _mapped_filter(resolution: float = 0.1) -> _native.ClamFilter:
    config = SlamConfig(particles=4, resolution=resolution, init_sigma=(0.1, 0.1, 0.05), seed=3)
    run = SlamRun(config)
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    run.step(np.zeros(3), angles, np.full(360, 3.0), np.zeros(3), 0.0)
    assert run.filter is not None and isinstance(run.filter, _native.ClamFilter)
    return run.filter


def test_reanchoring_moves_every_particle_and_gives_each_the_map() -> None:
    filt = _mapped_filter()
    before = np.asarray(filt.particle_poses())
    weights = np.asarray(filt.log_weights())
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    rebuilt = filt.empty_map()
    filt.map_scan(rebuilt, np.array([5.0, 0.0, 0.0]), angles, np.full(360, 1.0), np.zeros(3))
    correction = np.array([1.0, -2.0, 0.3])
    filt.reanchor(rebuilt, correction)
    after = np.asarray(filt.particle_poses())
    for b, a in zip(before, after, strict=True):
        assert a == pytest.approx(compose(correction, b))
    assert np.asarray(filt.log_weights()) == pytest.approx(weights)
    # The best map is now the rebuilt one: its occupied ring is around (5, 0), not the origin.
    best = filt.best_map()
    assert best.mean_at(*best.cell_of(6.05, 0.05)) > 0.5
    assert best.mean_at(*best.cell_of(3.05, 0.05)) == pytest.approx(0.5)  # the old ring is gone: unknown
    assert filt.estimate() == pytest.approx(tuple(compose(correction, before.mean(axis=0))), abs=0.2)


def test_a_map_of_another_grid_is_refused() -> None:
    filt = _mapped_filter()
    other = _mapped_filter(resolution=0.2).empty_map()
    with pytest.raises(ConfigError):
        filt.reanchor(other, np.zeros(3))


# --- A long loop: a 44 m x 26 m ring corridor with alcoves, driven once around and 20 m on.

_RES = 0.05


def _ring_world() -> tuple[np.ndarray, tuple[float, float]]:
    """Occupancy (uint8, rows y) of a ring corridor 3 m wide, with alcoves and pillars placed at
    random (fixed seed) along its walls so that each stretch looks different."""
    w, h = 50.0, 32.0
    nx, ny = int(w / _RES), int(h / _RES)
    occ = np.ones((ny, nx), np.uint8)
    x = (np.arange(nx) + 0.5) * _RES
    y = (np.arange(ny) + 0.5) * _RES
    xx, yy = np.meshgrid(x, y)

    def box(x0: float, y0: float, x1: float, y1: float, v: int) -> None:
        occ[(xx >= x0) & (xx <= x1) & (yy >= y0) & (yy <= y1)] = v

    box(1.5, 1.5, 48.5, 30.5, 0)
    box(4.5, 4.5, 45.5, 27.5, 1)
    rng = np.random.default_rng(7)
    # Along both walls of every leg, every 1.5-4 m: an alcove into the wall or a cabinet out of it,
    # 0.5-2 m long and 0.3-0.9 m deep, so that no stretch of corridor looks like another.
    for x0, y0, x1, y1, horizontal in (
        (1.5, 1.5, 48.5, 4.5, True),
        (1.5, 27.5, 48.5, 30.5, True),
        (1.5, 1.5, 4.5, 30.5, False),
        (45.5, 1.5, 48.5, 30.5, False),
    ):
        lo, hi = (x0, x1) if horizontal else (y0, y1)
        for wall in (0, 1):
            t = lo + 2.0 + rng.uniform(0.0, 2.0)
            while t < hi - 4.0:
                length, depth = rng.uniform(0.5, 2.0), rng.uniform(0.3, 0.9)
                inward = rng.random() < 0.5  # a cabinet into the corridor, else an alcove
                # The wall's line and the side of it the corridor is on.
                if horizontal:
                    line, into = (y0, 1.0) if wall == 0 else (y1, -1.0)
                else:
                    line, into = (x0, 1.0) if wall == 0 else (x1, -1.0)
                a_, b_ = (line, line + into * depth) if inward else (line - into * depth, line)
                lo2, hi2 = min(a_, b_), max(a_, b_)
                if horizontal:
                    box(t, lo2, t + length, hi2, 1 if inward else 0)
                else:
                    box(lo2, t, hi2, t + length, 1 if inward else 0)
                t += length + rng.uniform(1.5, 4.0)
    box(0.0, 0.0, 50.0, 0.5, 1)
    box(0.0, 31.5, 50.0, 32.0, 1)
    box(0.0, 0.0, 0.5, 32.0, 1)
    box(49.5, 0.0, 50.0, 32.0, 1)
    return occ, (0.0, 0.0)


def _ring_path(step: float = 0.25) -> np.ndarray:
    """Poses along the corridor's centre line (3 m in from the outer wall), counter-clockwise
    from (6, 3), once around and 20 m on; turns in place at the corners."""
    corners = [(3.0, 3.0), (47.0, 3.0), (47.0, 29.0), (3.0, 29.0)]
    pts = []
    start = np.array([6.0, 3.0])
    legs = (
        [(start, np.array(corners[1]))]
        + [(np.array(corners[k]), np.array(corners[(k + 1) % 4])) for k in range(1, 4)]
        + [(np.array(corners[0]), np.array(corners[1]))]
    )
    travelled = 0.0
    total = 2 * (44 + 26) + 20.0
    for a, b in legs:
        d = b - a
        length = float(np.hypot(*d))
        th = math.atan2(d[1], d[0])
        if pts and abs((th - pts[-1][2] + math.pi) % (2 * math.pi) - math.pi) > 1e-9:
            for t in np.linspace(pts[-1][2], pts[-1][2] + ((th - pts[-1][2] + math.pi) % (2 * math.pi) - math.pi), 7)[1:]:
                pts.append([a[0], a[1], t])
        for k in range(int(length / step)):
            if travelled >= total:
                break
            p = a + d * (k * step / length)
            pts.append([p[0], p[1], th])
            travelled += step
    return np.array(pts)


def _run_ring(loop_closing: str, heading_bias_deg: float = 0.02) -> tuple[float, float, SlamRun]:
    occ, origin = _ring_world()
    truth = _ring_path()
    angles = np.linspace(-math.pi / 2, math.pi / 2, 181)
    ranges = np.asarray(_native.cast_ranges(occ, origin[0], origin[1], _RES, truth, angles, 10.0))
    ranges = np.where(ranges >= 10.0, np.inf, ranges)
    rng = np.random.default_rng(1)
    ranges = ranges + rng.normal(0.0, 0.01, ranges.shape)
    # Odometry: a heading bias per 0.25 m step (0.02 deg: 0.08 deg/m; after the 160 m it has
    # turned 13 deg and strayed metres).
    rel, _ = _drifted(truth, math.radians(heading_bias_deg))
    odom = [truth[0]]
    for r in rel:
        odom.append(compose(odom[-1], r))
    config = SlamConfig(
        particles=3,
        resolution=0.1,
        max_range=10.0,
        proposal="odometry",
        motion="gaussian",
        motion_params=[0.005, 0.005, 0.001],
        linear_update=0.5,
        angular_update=0.25,
        loop_closing=loop_closing,
        seed=0,
    )
    run = SlamRun(config)
    for k in range(len(truth)):
        run.step(odom[k], angles, ranges[k], np.zeros(3), 0.1 * k)
    _, poses = run.trajectory()
    err = np.hypot(*(poses[:, :2] - truth[:, :2]).T)
    return float(err[-1]), float(err.max()), run


def test_a_long_loop_with_drifting_odometry_closes_only_with_loop_closing() -> None:
    open_end, open_max, _ = _run_ring("off")
    closed_end, closed_max, run = _run_ring("graph")
    # The particles follow the drift: the loop stays open by metres.
    assert open_end > 1.5 and open_max > 3.0
    assert run.loops is not None and run.loops.loops_closed >= 1 and run.loops.reanchors >= 1
    assert closed_end < 0.3
    # The whole trajectory is corrected, not only its end.
    assert closed_max < 0.5


def test_a_drift_beyond_the_search_window_is_left_alone() -> None:
    # 0.24 deg/m: the heading is 30 deg off when the loop comes round, beyond the window's
    # 0.002 rad/m rule; no match may close the loop at a wrong place.
    open_end, open_max, _ = _run_ring("off", heading_bias_deg=0.06)
    end, worst, run = _run_ring("graph", heading_bias_deg=0.06)
    assert run.loops is not None
    assert end <= open_end + 0.3 and worst <= open_max + 0.3


def _landmarks() -> np.ndarray:
    """Points (m) scattered over a 30 m x 12 m strip around a 20 m corridor's centre line."""
    return np.random.default_rng(3).uniform((-5.0, -6.0), (25.0, 6.0), (600, 2))


def _seen_from(pose: np.ndarray, world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The bearings and ranges of the points within 8 m of ``pose``, in its frame."""
    d = world - pose[:2]
    c, s = math.cos(pose[2]), math.sin(pose[2])
    local = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1]], axis=1)
    r = np.hypot(local[:, 0], local[:, 1])
    keep = r < 8.0
    return np.arctan2(local[keep, 1], local[keep, 0]), r[keep]


def _out_and_back() -> np.ndarray:
    """Poses (m, rad) 20 m out along x and back, one per metre: the return pass sees the same
    points again after 2-40 m of path."""
    out = [(float(k), 0.0, 0.0) for k in range(21)]
    back = [(float(k), 0.0, math.pi) for k in range(20, -1, -1)]
    return np.array(out + back)


def test_revisited_endpoints_count_only_walls_seen_again_in_place() -> None:
    world = _landmarks()
    truth = _out_and_back()
    ends = []
    for p in truth:
        a, r = _seen_from(p, world)
        ends.append(np.stack([r * np.cos(a), r * np.sin(a)], axis=1))
    travel = np.arange(len(truth), dtype=np.float64)
    aligned = revisited_endpoints(truth, ends, travel, 0.1, 15.0)
    assert aligned > 0.3 * sum(len(e) for e in ends)
    # The return pass 0.4 m to the side: its points fall beside the first pass's.
    shifted = truth.copy()
    shifted[21:, 1] += 0.4
    assert revisited_endpoints(shifted, ends, travel, 0.1, 15.0) < 0.2 * aligned
    # Seen again after less path than min_travel: a cell hit by the same pass does not count.
    assert revisited_endpoints(truth, ends, travel, 0.1, 100.0) == 0


def _closer_along(poses: np.ndarray) -> LoopCloser:
    """A loop closer fed the out-and-back scans at ``poses`` (the filter's online estimates); its
    own search never runs."""
    world = _landmarks()
    # A search at node 0 only, which has no old node to search.
    closer = LoopCloser(resolution=0.1, settings=LoopClosingSettings(search_every=10**6))
    for p, t in zip(poses, _out_and_back(), strict=True):
        a, r = _seen_from(t, world)  # the scan is taken at the true pose
        assert closer.add_node(None, p, a, r, np.zeros(3)) is None  # type: ignore[arg-type]
    return closer


def _match(closer: LoopCloser, node: int, old: int, pose: np.ndarray) -> _Match:
    s = closer.settings
    info = np.diag(1.0 / np.array([s.loop_sigma_xy, s.loop_sigma_xy, s.loop_sigma_theta]))
    return _Match(node=node, old_node=old, pose=pose, guess=closer.poses()[node], explained=0.9, sqrt_information=info)


def test_a_closure_that_pulls_agreeing_passes_apart_is_dropped() -> None:
    truth = _out_and_back()
    closer = _closer_along(truth)  # the loop is closed: both passes lie on each other
    before = closer.poses()
    wrong = [_match(closer, k, 41 - k, truth[k] + np.array([0.0, 0.5, 0.0])) for k in (39, 41)]
    assert not closer._close(wrong)
    assert closer.inconsistent == 1 and closer.loops_closed == 0
    np.testing.assert_array_equal(closer.poses(), before)
    assert not any(e[4] for e in closer._edges) and not closer.changed_since_rebuild
    c = closer.record()["closures"][0]
    assert c["revisited_endpoints_after"] < c["revisited_endpoints_before"] and not c["kept"]


def test_a_closure_that_lays_the_passes_onto_each_other_is_kept() -> None:
    truth = _out_and_back()
    drifted = truth.copy()
    drifted[21:, 1] += 0.05 * np.arange(21)  # the return pass drifts 1 m to the side
    closer = _closer_along(drifted)
    right = [_match(closer, k, 41 - k, truth[k]) for k in (39, 41)]
    assert closer._close(right)
    assert closer.loops_closed == 1 and closer.inconsistent == 0
    end = closer.poses()[-1]
    assert math.hypot(end[0] - truth[-1][0], end[1] - truth[-1][1]) < 0.1
