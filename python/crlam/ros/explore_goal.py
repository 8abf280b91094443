"""One exploration decision on a live map: candidate goals and their scores (CRMI or UCRMI).

The rule of :func:`crlam.experiments.explore.explore` (the simulated exploration of the paper's
experiments) on the map a SLAM node has built so far: reachable cells within ``radius_m`` of
the robot and frontier cells (reachable cells next to unknown space), up to ``n_candidates``;
each is scored by the information function's gain divided by its path length to the power
``cost_weight``; the best is the goal. Exploration stops (no goal) when no candidate is left or
the best map gain is below ``threshold``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

__all__ = ["Decision", "choose_goal"]


@dataclass
class Decision:
    """A decision: candidate positions (n, 2) m, their scores (n,), the chosen index (-1: none) and why."""

    candidates: NDArray[np.float64]
    scores: NDArray[np.float64]
    best: int
    stop: str | None


def choose_goal(crm: Any, estimate: NDArray[np.float64], cfg: Any, seed: int, belief: Any = None) -> Decision:
    """The decision on ``crm`` (a :class:`crlam.mapping.ConfidenceRichMap`) from the robot's
    ``estimate`` (x, y, theta) with the settings ``cfg`` (:class:`crlam.experiments.explore.ExploreConfig`:
    function, radius_m, n_candidates, cost_weight, threshold, robot_radius, free_threshold,
    sensor_range, alpha, particles). ``belief`` (UCRMI) is the filter's weighed particle set."""
    from crlam.experiments.explore import geodesic
    from crlam.experiments.explore_candidates import pick_candidates
    from crlam.experiments.explore_window import decision_maps
    from crlam.info import make_function

    res = crm.config.resolution
    origin = crm.config.origin
    rect = crm.region()
    gx0, gy0, nx, ny = rect
    ox, oy = origin[0] + gx0 * res, origin[1] + gy0 * res
    here = (min(max(int((estimate[1] - oy) / res), 0), ny - 1), min(max(int((estimate[0] - ox) / res), 0), nx - 1))
    dm = decision_maps(crm.native, rect, here, resolution=res, free_threshold=cfg.free_threshold, robot_radius=cfg.robot_radius)
    dist, _ = geodesic(dm.traversable, (here[0] - dm.iy0, here[1] - dm.ix0), res)
    reach = np.isfinite(dist) & (dist >= 2 * res)
    frontier = reach & (dm.to_unknown < cfg.robot_radius + 1.5 * res)
    rng = np.random.default_rng(seed)
    idx, wy, wx, centres = pick_candidates(
        reach, frontier, (dm.iy0, dm.ix0), (ox, oy), res, estimate, cfg.radius_m, cfg.n_candidates, rng
    )
    if idx.size == 0:
        return Decision(np.zeros((0, 2)), np.zeros(0), -1, "no_candidates")
    cand = centres[idx]
    cost = dist[wy[idx], wx[idx]]
    poses3 = np.column_stack([cand, np.zeros(len(cand))])
    crmi = make_function("crmi", z_max=cfg.sensor_range, resolution=res)
    map_gains = np.asarray(crmi.gains(crm.native, poses3), dtype=np.float64)
    if cfg.function == "ucrmi" and belief is not None:
        fn = make_function("ucrmi", z_max=cfg.sensor_range, resolution=res, alpha=cfg.alpha, n_particles=cfg.particles)
        parents = np.tile(estimate[:2], (len(cand), 1))
        gains = np.asarray(fn.gains(crm.native, poses3, parents=parents, belief=belief, seed=seed), dtype=np.float64)
    else:
        gains = map_gains
    scores = gains / np.power(cost, cfg.cost_weight) if cfg.cost_weight > 0 else gains
    best = int(np.argmax(scores))
    if not math.isfinite(float(np.max(map_gains))) or float(np.max(map_gains)) < cfg.threshold:
        return Decision(cand, scores, -1, "threshold")
    return Decision(cand, scores, best, None)
