"""Figures of results/bags/README.md: a crlam slam run folder's confidence-rich map (expected
occupancy and confidence, with the trajectory) and a Nav2 floor map, at the same scale.

    python results/bags/figures.py RUN_DIR OUT.png [--floor-map MAP.yaml FLOOR.png [--overlay OVERLAY.png]] [--title TEXT]
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from crlam.experiments.known_poses import unknown_mask
from crlam.io.belief import load_belief
from crlam.io.nav2 import read_nav2_map, read_pgm
from crlam.io.tum import read_tum
from crlam.mapping import ConfidenceRichMap
from crlam.slam.grid_alignment import frame_from_record, from_map_frame
from crlam.viz.maps import metric_axes, save_crm_figure, save_figure


def crm_figure(run: Path, out: Path, title: str) -> list[float]:
    """The run's CRM figure; returns its extent (x0, x1, y0, y1) in metres."""
    crm = ConfidenceRichMap.from_archive(load_belief(run / "belief.npz"))
    mean, var, ent = crm.layers()
    poses = read_tum(run / "trajectory.tum").poses
    save_crm_figure(out, mean, var, unknown=unknown_mask(crm, ent), title=title, trajectory=poses)
    return [float(v) for v in mean.extent]


def floor_figure(map_yaml: Path, out: Path, title: str, window: list[float] | None = None) -> None:
    """The floor map's image as its owners drew it (grey 205 = not seen), in metres; ``window``
    (x0, x1, y0, y1) crops it to the region of a run's map."""
    m = read_nav2_map(map_yaml)
    image = read_pgm(m.image_path)  # first row = largest y
    ny, nx = image.shape
    x0, y0, res = float(m.origin[0]), float(m.origin[1]), m.resolution
    extent = [x0, x0 + nx * res, y0, y0 + ny * res]
    if window is not None:
        c0, c1 = (max(0, min(nx, round((v - x0) / res))) for v in window[:2])
        r0, r1 = (max(0, min(ny, round((extent[3] - v) / res))) for v in (window[3], window[2]))
        image = image[r0:r1, c0:c1]
        extent = [x0 + c0 * res, x0 + c1 * res, extent[3] - r1 * res, extent[3] - r0 * res]
    w, h = extent[1] - extent[0], extent[3] - extent[2]
    fig, ax = plt.subplots(figsize=(6.5, 6.5 * h / w + 0.6), constrained_layout=True)
    ax.imshow(image, cmap="gray", vmin=0, vmax=255, extent=extent, interpolation="nearest")
    metric_axes(ax, extent)
    ax.set_title(title)
    save_figure(fig, out, 150)


def overlay_figure(run: Path, map_yaml: Path, out: Path, window: list[float]) -> None:
    """The run's cells of expected occupancy above 0.6 (red) drawn on the floor map's image, the
    run's turned back from its map's frame into its odometry frame (``map_frame`` of its
    metrics.json), the two frames not aligned: how far apart they put the walls."""
    crm = ConfidenceRichMap.from_archive(load_belief(run / "belief.npz"))
    mean, _, _ = crm.layers()
    m = read_nav2_map(map_yaml)
    image = read_pgm(m.image_path)
    ny, nx = image.shape
    x0, y0, res = float(m.origin[0]), float(m.origin[1]), m.resolution
    w, h = window[1] - window[0], window[3] - window[2]
    fig, ax = plt.subplots(figsize=(6.5, 6.5 * h / w + 0.6), constrained_layout=True)
    ax.imshow(image, cmap="gray", vmin=0, vmax=255, extent=[x0, x0 + nx * res, y0, y0 + ny * res], interpolation="nearest")
    iy, ix = (mean.values > 0.6).nonzero()
    ex = mean.extent
    cells = np.stack([ex[0] + (ix + 0.5) * mean.resolution, ex[2] + (iy + 0.5) * mean.resolution, np.zeros(ix.size)], 1)
    frame = frame_from_record(json.loads((run / "metrics.json").read_text()).get("map_frame"))
    cells = from_map_frame(frame, cells)
    ax.plot(cells[:, 0], cells[:, 1], "r.", ms=2, label="run: m > 0.6")
    ax.set_xlim(window[0], window[1])
    ax.set_ylim(window[2], window[3])
    ax.grid(True, linewidth=0.3)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_title("run's occupied cells on the floor map (frames not aligned)")
    save_figure(fig, out, 150)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("run", type=Path)
    p.add_argument("out", type=Path)
    p.add_argument("--floor-map", nargs=2, type=Path, metavar=("MAP_YAML", "OUT_PNG"))
    p.add_argument("--overlay", type=Path, metavar="OUT_PNG", help="with --floor-map: the run's walls drawn on the floor map")
    p.add_argument("--title", default="")
    a = p.parse_args()
    window = crm_figure(a.run, a.out, a.title)
    if a.floor_map:
        floor_figure(a.floor_map[0], a.floor_map[1], f"floor map {a.floor_map[0].name}, the same window", window)
        if a.overlay:
            overlay_figure(a.run, a.floor_map[0], a.overlay, window)


if __name__ == "__main__":
    main()
