"""A small IIG comparison on a built-in world, for ``crlam demo``."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from crlam.errors import ConfigError
from crlam.experiments.iig import LABELS, claims
from crlam.info.prior import MapPrior, lattice_from_obstacles
from crlam.planner import IigSettings, IigTree, plan_iig
from crlam.sim.grid_ops import distance_map
from crlam.sim.worlds import office_world

__all__ = ["IigDemo", "office_prior", "run_iig_demo"]


def office_prior(seed: int = 0) -> tuple[MapPrior, tuple[float, float]]:
    """The procedural office world at 0.2 m as a planner prior, and a start with room to move
    (the free node nearest the lower-left corner with 1.2 m of clearance)."""
    world = office_world(seed, resolution=0.2)
    res = world.resolution
    node0 = (float(world.origin[0]) + 0.5 * res, float(world.origin[1]) + 0.5 * res)
    prior = lattice_from_obstacles(world.occupied, None, res, node0)
    clear = distance_map(world.occupied, res, 5.0)
    iy, ix = np.nonzero(clear >= 1.2)
    if iy.size == 0:
        raise ConfigError("the office world has no cell with 1.2 m of clearance")
    k = int(np.argmin(ix + iy))
    return prior, (node0[0] + ix[k] * res, node0[1] + iy[k] * res)


@dataclass(frozen=True)
class IigDemo:
    trees: dict[str, IigTree]
    rows: list[dict[str, Any]]
    claims: list[tuple[str, bool | None, str]]
    figure: Path


def run_iig_demo(
    out: Path, *, seed: int = 0, functions: Sequence[str] = ("ogmi", "crmi", "ucrmi", "gpvr", "ugpvr"), particles: int = 30
) -> IigDemo:
    """One IIG run per function on the office world (reference settings, OGMI by FSMI, UCRMI with
    ``particles`` particles); writes ``iig_trees.png`` into ``out``."""
    from crlam.experiments.iig import function_for
    from crlam.viz.iig import save_trees

    prior, start = office_prior(seed)
    settings = IigSettings(mode="reference", start=start, max_wall_seconds=120.0)
    trees: dict[str, IigTree] = {}
    rows: list[dict[str, Any]] = []
    for name in functions:
        f = function_for(name, mode="reference", particles=particles)
        t = plan_iig(f, prior, settings, seed=seed)
        trees[name] = t
        rows.append({**t.summary(), "function": name})
    fig = save_trees(out / "iig_trees.png", prior, trees, LABELS)
    return IigDemo(trees=trees, rows=rows, claims=claims(rows, list(functions)), figure=fig)
