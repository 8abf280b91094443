"""A straight corridor, 80 m x 2.5 m, closed at both ends, as a Nav2 map (PGM + YAML).

    python results/corridor/make_world.py OUT_DIR

Nothing along the corridor tells one stretch of it from another: with the simulator's 8 m lidar
the side walls fix the pose across the corridor and its heading, and only the odometry (and the
end walls, when within reach) fixes how far along it the robot is.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
from PIL import Image

RESOLUTION = 0.05  # m per pixel
LENGTH = 80.0  # m, inside
WIDTH = 2.5  # m, inside
WALL = 0.5  # m


def main(out: Path) -> None:
    out.mkdir(parents=True, exist_ok=True)
    wall = round(WALL / RESOLUTION)
    nx = round(LENGTH / RESOLUTION) + 2 * wall
    ny = round(WIDTH / RESOLUTION) + 2 * wall
    image = np.full((ny, nx), 254, dtype=np.uint8)
    image[:wall, :] = image[-wall:, :] = 0
    image[:, :wall] = image[:, -wall:] = 0
    Image.fromarray(image).save(out / "corridor.pgm")
    (out / "corridor.yaml").write_text(
        "image: corridor.pgm\n"
        f"resolution: {RESOLUTION}\n"
        "origin: [0.0, 0.0, 0.0]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n"
        "mode: trinary\n"
    )


if __name__ == "__main__":
    main(Path(sys.argv[1]))
