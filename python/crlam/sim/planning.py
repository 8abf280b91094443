"""Global path planning for the simulated robot: A* on a coarse lattice with a clearance cost.

The lattice nodes are fine-grid cell centres spaced ``k`` cells apart (``k * resolution`` close to
the requested planning cell size). A node is traversable when its exact clearance (distance to
the nearest occupied cell square) exceeds ``radius + margin``. Stepping into a node costs the step
length times ``1 + w * ((d_pref - c) / (d_pref - r_safe))²`` when its clearance ``c`` is below the
preferred clearance ``d_pref``, which keeps paths in the middle of doors and away from walls.
The A* path is then shortened by string pulling, never letting a shortcut come closer to
obstacles than the A* path it replaces (capped at ``d_pref``).
"""

from __future__ import annotations

import heapq
import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from crlam.sim.grid_ops import ClearanceField, label_components
from crlam.sim.world import World

__all__ = ["PlanningError", "PlanningGrid"]

_SQRT2 = math.sqrt(2.0)


class PlanningError(RuntimeError):
    """No collision-free path was found between two points."""


@dataclass
class PlanningGrid:
    """Coarse planning lattice over a world.

    Attributes
    ----------
    world:
        The world planned in.
    step:
        Fine cells between lattice nodes.
    clearance:
        ``(cny, cnx)`` exact clearance (m) of the nodes, capped at the preferred clearance.
    cost:
        ``(cny, cnx)`` cost multiplier (>= 1), ``inf`` for blocked nodes.
    component:
        ``(cny, cnx)`` label of the 4-connected traversable component of each node (0 = blocked).
    field:
        Fine-resolution :class:`ClearanceField` for checking segments.
    safe:
        Minimum clearance (m) of traversable nodes: ``radius + margin``.
    preferred:
        Clearance (m) above which no extra cost applies.
    """

    world: World
    step: int
    clearance: NDArray[np.float64]
    cost: NDArray[np.float64]
    component: NDArray[np.int32]
    field: ClearanceField
    safe: float
    preferred: float

    @classmethod
    def build(
        cls,
        world: World,
        radius: float,
        margin: float,
        preferred: float,
        weight: float,
        cell: float = 0.25,
    ) -> PlanningGrid:
        """Compute the lattice; see the module docstring for the meaning of the parameters (m)."""
        step = max(1, round(cell / world.resolution))
        ny, nx = world.shape
        off = step // 2
        iy = np.arange(off, ny, step)
        ix = np.arange(off, nx, step)
        safe = radius + margin
        preferred = max(preferred, safe + world.resolution)
        fld = ClearanceField(world.occupied, world.resolution, world.origin, preferred + world.resolution)
        clr = np.minimum(fld.at_cells(iy[:, None], ix[None, :]), preferred)
        free = clr > safe
        deficit = np.clip((preferred - clr) / (preferred - safe), 0.0, 1.0)
        cost = np.where(free, 1.0 + weight * deficit**2, np.inf)
        comp, _ = label_components(free, connectivity=4)
        return cls(world, step, clr, cost, comp, fld, safe, preferred)

    # ------------------------------------------------------------------ coordinates
    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.cost.shape[0]), int(self.cost.shape[1]))

    def node_xy(self, i: NDArray[np.int64] | int, j: NDArray[np.int64] | int) -> NDArray[np.float64]:
        """World ``(x, y)`` of lattice nodes at row ``i``, column ``j``; shape ``(..., 2)``."""
        return self.world.cell_centers(np.asarray(j) * self.step + self.step // 2, np.asarray(i) * self.step + self.step // 2)

    def nearest_node(self, xy: NDArray[np.float64], label: int | None = None) -> tuple[int, int]:
        """Row and column of the traversable node nearest to ``xy`` (searching a small window).

        With ``label``, only nodes of that traversable component qualify (so a point next to a
        thin wall is not attached to the room behind it).
        """
        g = (np.asarray(xy, dtype=np.float64) - self.world.origin) / self.world.resolution - 0.5
        fi = (g[1] - self.step // 2) / self.step
        fj = (g[0] - self.step // 2) / self.step
        cny, cnx = self.shape
        best: tuple[float, int, int] | None = None
        for di in range(-2, 4):
            for dj in range(-2, 4):
                i, j = math.floor(fi) + di, math.floor(fj) + dj
                if not (0 <= i < cny and 0 <= j < cnx and math.isfinite(self.cost[i, j])):
                    continue
                if label is None or self.component[i, j] == label:
                    d = (i - fi) ** 2 + (j - fj) ** 2
                    if best is None or d < best[0]:
                        best = (d, i, j)
        if best is None:
            raise PlanningError(f"no traversable node near {tuple(np.round(xy, 2))}")
        return best[1], best[2]

    # ------------------------------------------------------------------ search
    def astar(self, start: tuple[int, int], goal: tuple[int, int], heuristic_weight: float = 1.5) -> list[int]:
        """Node path (flat indices ``i * cnx + j``) from ``start`` to ``goal``, 8-connected.

        Diagonal moves need both orthogonal neighbours traversable (no corner cutting). With
        ``heuristic_weight > 1`` this is weighted A*: faster, at most that factor above optimal.

        Raises
        ------
        PlanningError
            If the goal is blocked or unreachable from the start.
        """
        cny, cnx = self.shape
        if self.component[start] == 0 or self.component[start] != self.component[goal]:
            raise PlanningError(f"goal {goal} not reachable from {start}")
        # Pad with a blocked border so neighbour indices never leave the array.
        w = cnx + 2
        cost = np.full((cny + 2, w), math.inf)
        cost[1:-1, 1:-1] = self.cost
        c = cost.ravel().tolist()
        s = (start[0] + 1) * w + start[1] + 1
        g_node = (goal[0] + 1) * w + goal[1] + 1
        gy, gx = divmod(g_node, w)
        moves = [
            (1, 0, 1.0),
            (-1, 0, 1.0),
            (0, 1, 1.0),
            (0, -1, 1.0),
            (1, 1, _SQRT2),
            (1, -1, _SQRT2),
            (-1, 1, _SQRT2),
            (-1, -1, _SQRT2),
        ]
        offs = [(di * w + dj, di * w, dj, di, length) for di, dj, length in moves]
        inf = math.inf
        gscore = [inf] * len(c)
        parent = [-1] * len(c)
        closed = bytearray(len(c))
        gscore[s] = 0.0
        hw = heuristic_weight
        heap = [(0.0, s)]
        while heap:
            _, cur = heapq.heappop(heap)
            if closed[cur]:
                continue
            if cur == g_node:
                break
            closed[cur] = 1
            gc = gscore[cur]
            cc = c[cur]
            cy, cx = divmod(cur, w)
            for off, oi, oj, di, length in offs:
                n = cur + off
                cn = c[n]
                if cn == inf or closed[n]:
                    continue
                if oi and oj and (c[cur + oi] == inf or c[cur + oj] == inf):
                    continue
                ng = gc + 0.5 * length * (cc + cn)
                if ng < gscore[n]:
                    gscore[n] = ng
                    parent[n] = cur
                    dy = abs(cy + di - gy)
                    dx = abs(cx + oj - gx)
                    h = (dx + dy) + (_SQRT2 - 2.0) * (min(dy, dx))  # octile distance
                    heapq.heappush(heap, (ng + hw * h, n))
        if parent[g_node] < 0 and g_node != s:
            raise PlanningError(f"A* found no path from {start} to {goal}")
        path = [g_node]
        while path[-1] != s:
            path.append(parent[path[-1]])
        path.reverse()
        return [(p // w - 1) * cnx + (p % w - 1) for p in path]

    def segment_clearance(self, a: NDArray[np.float64], b: NDArray[np.float64]) -> float:
        """Lower bound of the clearance (m) along the segment ``a -> b`` (sampled every cell)."""
        length = float(np.hypot(*(b - a)))
        n = max(2, math.ceil(length / self.world.resolution) + 1)
        t = np.linspace(0.0, 1.0, n)[:, None]
        return float(self.field.at_points(a[None, :] * (1.0 - t) + b[None, :] * t).min())

    def plan(
        self,
        start_xy: NDArray[np.float64],
        goal_xy: NDArray[np.float64],
        min_clearance: float,
        heuristic_weight: float = 1.5,
    ) -> NDArray[np.float64]:
        """Smoothed collision-free polyline ``(k, 2)`` from ``start_xy`` to ``goal_xy`` (m).

        Every segment, including the first one from the exact start point, is checked to keep a
        clearance of at least ``min_clearance`` (m) (the robot radius plus a tolerance).

        Raises
        ------
        PlanningError
            If there is no path or the smoothed path fails the clearance check.
        """
        gi = self.nearest_node(goal_xy)
        si = self.nearest_node(start_xy, label=int(self.component[gi]))
        cnx = self.shape[1]
        nodes = self.astar(si, gi, heuristic_weight)
        rows, cols = np.divmod(np.asarray(nodes, dtype=np.int64), cnx)
        pts = self.node_xy(rows, cols)
        clr = self.clearance[rows, cols]
        pts = (
            np.vstack(
                [np.asarray(start_xy, dtype=np.float64)[None, :], pts[1:-1], np.asarray(goal_xy, dtype=np.float64)[None, :]]
            )
            if len(pts) > 1
            else np.vstack([np.asarray(start_xy, float)[None, :], np.asarray(goal_xy, float)[None, :]])
        )
        if len(clr) < len(pts):
            clr = np.concatenate([clr, clr[-1:]])
        # Running minimum of node clearance, to compare shortcuts with the sub-path they replace.
        out = [0]
        i = 0
        tol = self.world.resolution
        while i < len(pts) - 1:
            best = i + 1
            sub_min = min(clr[i], clr[i + 1])
            for j in range(i + 2, len(pts)):
                sub_min = min(sub_min, clr[j])
                need = max(min_clearance, min(sub_min, self.preferred) - tol)
                if self.segment_clearance(pts[i], pts[j]) >= need:
                    best = j
                else:
                    break
            out.append(best)
            i = best
        path = pts[out]
        for a, b in itertools.pairwise(path):
            if self.segment_clearance(a, b) < min_clearance:
                raise PlanningError("smoothed path comes too close to an obstacle")
        return path
