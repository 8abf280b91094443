"""Ground-truth worlds for simulation: a boolean occupancy grid with its geometry.

Grids are indexed ``[iy, ix]`` with ``iy = 0`` at the minimum y; ``origin`` is the world
``(x, y)`` of the lower-left corner of cell ``[0, 0]``; cell ``(ix, iy)`` covers
``[ox + ix*res, ox + (ix+1)*res) x [oy + iy*res, oy + (iy+1)*res)``.

Images (PGM, PNG, ...) are stored top row first, so image row 0 is the maximum y: loading flips
them. PGM (P2/P5) files are read and written with Pillow, the Nav2 ``map_server`` YAML with PyYAML
(:mod:`crlam.io.nav2`).
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import ConfigError, CrlamError, DataFormatError
from crlam.sim.grid_ops import ClearanceField, distance_map

__all__ = ["World", "read_pgm", "write_pgm"]

PathLike = str | os.PathLike[str]


@dataclass
class World:
    """A 2D world as an occupancy grid (true = obstacle).

    Attributes
    ----------
    occupied:
        bool ``(ny, nx)``, indexed ``[iy, ix]``, ``iy = 0`` at the minimum y.
    resolution:
        Cell edge length (m).
    origin:
        float64 ``(2,)``: world ``(x, y)`` (m) of the lower-left corner of cell ``[0, 0]``.
    name:
        Human-readable name (e.g. ``"museum"`` or the file stem).
    """

    occupied: NDArray[np.bool_]
    resolution: float
    origin: NDArray[np.float64] = field(default_factory=lambda: np.zeros(2))
    name: str = "world"

    def __post_init__(self) -> None:
        occ = np.asarray(self.occupied)
        if occ.ndim != 2 or occ.size == 0:
            raise ConfigError(f"World.occupied must be a non-empty 2D array, got shape {occ.shape}")
        self.occupied = occ.astype(bool, copy=False)
        self.resolution = float(self.resolution)
        if not (self.resolution > 0.0 and math.isfinite(self.resolution)):
            raise ConfigError(f"World.resolution must be positive and finite, got {self.resolution}")
        self.origin = np.asarray(self.origin, dtype=np.float64).reshape(2).copy()

    # ------------------------------------------------------------------ geometry
    @property
    def shape(self) -> tuple[int, int]:
        """Grid shape ``(ny, nx)``."""
        return (int(self.occupied.shape[0]), int(self.occupied.shape[1]))

    @property
    def width(self) -> float:
        """Extent along x (m)."""
        return self.occupied.shape[1] * self.resolution

    @property
    def height(self) -> float:
        """Extent along y (m)."""
        return self.occupied.shape[0] * self.resolution

    @property
    def extent(self) -> tuple[float, float, float, float]:
        """``(xmin, xmax, ymin, ymax)`` in metres (matplotlib ``imshow(origin="lower")`` order)."""
        ox, oy = float(self.origin[0]), float(self.origin[1])
        return (ox, ox + self.width, oy, oy + self.height)

    def world_to_cell(self, points: ArrayLike) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Cell indices ``(ix, iy)`` containing world points ``(..., 2)``; may be out of the grid."""
        p = np.asarray(points, dtype=np.float64)
        g = np.floor((p - self.origin) / self.resolution).astype(np.int64)
        return g[..., 0], g[..., 1]

    def cell_centers(self, ix: ArrayLike, iy: ArrayLike) -> NDArray[np.float64]:
        """World coordinates ``(..., 2)`` of the centres of cells ``(ix, iy)``."""
        x = self.origin[0] + (np.asarray(ix, dtype=np.float64) + 0.5) * self.resolution
        y = self.origin[1] + (np.asarray(iy, dtype=np.float64) + 0.5) * self.resolution
        return np.stack(np.broadcast_arrays(x, y), axis=-1)

    def in_bounds(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether world points ``(..., 2)`` fall inside the grid."""
        ix, iy = self.world_to_cell(points)
        ny, nx = self.shape
        return (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)

    def is_free(self, points: ArrayLike) -> NDArray[np.bool_]:
        """Whether world points ``(..., 2)`` lie in free cells; points outside the grid are not free."""
        ix, iy = self.world_to_cell(points)
        ny, nx = self.shape
        inside = (ix >= 0) & (ix < nx) & (iy >= 0) & (iy < ny)
        occ = self.occupied[np.clip(iy, 0, ny - 1), np.clip(ix, 0, nx - 1)]
        return inside & ~occ

    def clearance(self, points: ArrayLike, max_distance: float = 1.0) -> NDArray[np.float64]:
        """Exact distance (m) from world points ``(..., 2)`` to the nearest occupied cell square.

        Capped at ``max_distance``; 0 inside an occupied cell and for points outside the grid.
        Cost is ``O(n_points * (max_distance / resolution)²)``: meant for verification.
        """
        p = np.asarray(points, dtype=np.float64)
        flat = p.reshape(-1, 2)
        res = self.resolution
        k = math.ceil(max_distance / res) + 1
        ny, nx = self.shape
        ix, iy = self.world_to_cell(flat)
        offs = np.arange(-k, k + 1)
        out = np.full(len(flat), float(max_distance))
        for s in range(0, len(flat), 4096):
            cx = ix[s : s + 4096, None, None] + offs[None, None, :]
            cy = iy[s : s + 4096, None, None] + offs[None, :, None]
            valid = (cx >= 0) & (cx < nx) & (cy >= 0) & (cy < ny)
            occ = valid & self.occupied[np.clip(cy, 0, ny - 1), np.clip(cx, 0, nx - 1)]
            # Distance from the point to the square [x0, x0+res] x [y0, y0+res] of each cell.
            x0 = self.origin[0] + cx * res
            y0 = self.origin[1] + cy * res
            px = flat[s : s + 4096, 0, None, None]
            py = flat[s : s + 4096, 1, None, None]
            ex = np.maximum(np.maximum(x0 - px, px - (x0 + res)), 0.0)
            ey = np.maximum(np.maximum(y0 - py, py - (y0 + res)), 0.0)
            d = np.where(occ, np.hypot(ex, ey), np.inf).reshape(len(px), -1).min(axis=1)
            out[s : s + 4096] = np.minimum(d, max_distance)
        out[~self.in_bounds(flat)] = 0.0
        return out.reshape(p.shape[:-1])

    def clearance_field(self, max_distance: float) -> ClearanceField:
        """A :class:`ClearanceField` for fast repeated clearance queries."""
        return ClearanceField(self.occupied, self.resolution, self.origin, max_distance)

    def distance_map(self, max_distance: float) -> NDArray[np.float64]:
        """Clearance (m) of every cell centre, capped at ``max_distance``; shape ``(ny, nx)``."""
        return distance_map(self.occupied, self.resolution, max_distance)

    def inflated(self, radius: float) -> NDArray[np.bool_]:
        """Occupied cells plus the cells whose centre is within ``radius`` (m) of an occupied cell.

        A disc of radius ``radius`` centred on the centre of a cell that is false here touches
        no occupied cell. Shape ``(ny, nx)``.
        """
        if radius <= 0.0:
            return self.occupied.copy()
        return self.occupied | (distance_map(self.occupied, self.resolution, radius + self.resolution) <= radius)

    @property
    def free_fraction(self) -> float:
        """Fraction of the cells that are free."""
        return float(1.0 - self.occupied.mean())

    # ------------------------------------------------------------------ loading
    @classmethod
    def from_image(
        cls,
        path: PathLike,
        resolution: float,
        origin: ArrayLike = (0.0, 0.0),
        threshold: int = 128,
        name: str | None = None,
    ) -> World:
        """Load a grey-level image: pixel ``>= threshold`` is free, ``< threshold`` is an obstacle.

        Parameters
        ----------
        path:
            PGM (P2/P5) or any other image Pillow reads (PNG, ...). Colour images are
            converted to luminance; 16-bit PGMs are rescaled to 0..255.
        resolution:
            Metres per pixel (e.g. 0.2 for the Cave map).
        origin:
            World ``(x, y)`` (m) of the lower-left corner of the image.
        threshold:
            Grey level (0..255) separating obstacles from free space.
        """
        grey = _read_grey(Path(path))
        occupied = np.flipud(grey < threshold)  # image row 0 is the maximum y
        return cls(np.ascontiguousarray(occupied), resolution, np.asarray(origin, float), name or Path(path).stem)

    @classmethod
    def from_nav2_yaml(cls, path: PathLike, name: str | None = None) -> World:
        """Load a Nav2 ``map_server`` map (YAML + image); unknown cells become obstacles.

        Parsing follows Nav2 exactly (:func:`crlam.io.nav2.read_nav2_map`: keys ``image``,
        ``resolution``, ``origin``, ``negate``, ``occupied_thresh``, ``free_thresh``, ``mode``).
        A cell is free only when Nav2 classifies it as free (occupancy 0 in trinary and scale
        modes, below ``free_thresh`` in raw mode); occupied, unknown and intermediate cells all
        block the simulated robot and its laser. A rotated map (yaw != 0) is refused.
        """
        from crlam.io.nav2 import read_nav2_map

        m = read_nav2_map(path)
        if abs(float(m.origin[2])) > 1e-9:
            raise DataFormatError("rotated maps (yaw != 0) are not supported", path=str(path), field="origin")
        occ = np.asarray(m.occupancy, dtype=np.float64)
        if m.mode == "raw":
            free = np.isfinite(occ) & (occ < m.free_thresh)
        else:
            free = occ == 0.0
        return cls(np.ascontiguousarray(~free), float(m.resolution), m.origin[:2].copy(), name or Path(path).stem)

    # ------------------------------------------------------------------ saving
    def to_pgm(self, path: PathLike) -> None:
        """Write the grid as a binary PGM (map_server style: 0 obstacle, 254 free), top row = max y."""
        grey = np.where(np.flipud(self.occupied), 0, 254).astype(np.uint8)
        write_pgm(path, grey)

    def to_nav2_yaml(self, yaml_path: PathLike) -> Path:
        """Write a Nav2 trinary map: ``<stem>.pgm`` (0 obstacle, 254 free) and the YAML.

        Uses :func:`crlam.io.nav2.write_nav2_map`; the output bytes depend only on the world.
        Returns the YAML path.
        """
        from crlam.io.nav2 import write_nav2_map

        ypath = Path(yaml_path)
        return write_nav2_map(
            ypath.with_suffix(".pgm"), self.occupied.astype(np.float64), resolution=self.resolution, origin=self.origin
        )


# ---------------------------------------------------------------------- image helpers
def _read_grey(path: Path) -> NDArray[np.uint8]:
    """Read an image as uint8 grey levels ``(rows, cols)``, row 0 = top of the image."""
    if not path.exists():
        raise DataFormatError("file not found", path=str(path))
    with open(path, "rb") as fh:
        magic = fh.read(2)
    if magic in (b"P5", b"P2"):
        return read_pgm(path)
    from PIL import Image

    from crlam.io.nav2 import open_pil_image

    try:
        with open_pil_image(path) as img:
            if img.mode in ("RGBA", "LA", "PA") or (img.mode == "P" and "transparency" in img.info):
                img = img.convert("RGBA")
                background = Image.new("RGBA", img.size, (255, 255, 255, 255))
                img = Image.alpha_composite(background, img)
            if img.mode in ("I;16", "I;16B", "I"):
                arr = np.asarray(img, dtype=np.float64)
                top = arr.max() if arr.max() > 255 else 255.0
                return np.round(arr * 255.0 / top).astype(np.uint8)
            return np.asarray(img.convert("L"), dtype=np.uint8).copy()
    except CrlamError:
        raise
    except (OSError, ValueError, SyntaxError) as exc:
        raise DataFormatError(f"not an image: {exc}", path=str(path)) from exc


def read_pgm(path: PathLike) -> NDArray[np.uint8]:
    """Read a PGM file (P5 binary or P2 ASCII) as uint8 grey levels ``(rows, cols)``, row 0 = top.

    Reads through :func:`crlam.io.nav2.read_pgm` (Pillow); 16-bit images are rescaled to 0..255.
    """
    from crlam.io.nav2 import read_pgm as read_pgm_pillow

    values = read_pgm_pillow(path)
    if values.dtype == np.uint8:
        return values.astype(np.uint8)
    return np.round(values.astype(np.float64) * (255.0 / 65535.0)).astype(np.uint8)


def write_pgm(path: PathLike, grey: NDArray[np.uint8]) -> None:
    """Write uint8 grey levels ``(rows, cols)`` (row 0 = top) as a binary P5 PGM (Pillow)."""
    from crlam.io.nav2 import write_pgm as write_pgm_pillow

    write_pgm_pillow(path, np.ascontiguousarray(grey, dtype=np.uint8))
