"""Nav2 ``map_server`` maps (image + YAML) and PGM images.

Array convention (the whole project): a grid is indexed ``[iy, ix]`` with ``iy = 0`` at the
*minimum* y, and ``origin`` is the world position of the lower-left corner of cell ``[0, 0]``.
An image stores its top row (maximum y) first, so rows are flipped on the way in and out.

Nav2's trinary rule, applied by :func:`read_nav2_map` exactly as ``map_server`` does: with
``shade`` the pixel brightness in [0, 1], ``occ = shade`` if ``negate`` else ``1 - shade``; the
cell is occupied if ``occ > occupied_thresh``, free if ``occ < free_thresh``, unknown otherwise.
:func:`write_nav2_map` classifies occupancy probabilities with the same strict inequalities and
writes 0 (occupied), 254 (free) and 205 (unknown) like ``map_saver`` (mirrored when
``negate=1``), so that a written map reads back to the same classes.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from crlam.errors import ConfigError, DataFormatError, ResourceLimitError
from crlam.io.lines import read_small_text
from crlam.io.structured import load_yaml_text
from crlam.limits import check_limit

__all__ = ["Nav2Map", "nav2_pixels", "read_image", "read_nav2_map", "read_pgm", "write_nav2_image", "write_nav2_map", "write_pgm"]

FloatArray = NDArray[np.float64]

_OCCUPIED, _FREE, _UNKNOWN = 1, 0, -1


@dataclass(eq=False)
class Nav2Map:
    """An occupancy map loaded from a Nav2 YAML file.

    Attributes
    ----------
    occupancy : ndarray, shape (ny, nx), float64
        ``[iy, ix]`` with ``iy = 0`` at the minimum y. Trinary mode: 1.0 occupied, 0.0 free,
        NaN unknown. Scale mode: values in between are ``(occ - free) / (occ_t - free)`` rounded
        to percent, as Nav2 does. Raw mode: pixel value / 100, NaN above 100.
    resolution : float
        Cell size (m).
    origin : ndarray, shape (3,)
        ``(x, y, yaw)`` of the lower-left corner of cell ``[0, 0]`` (m, m, rad).
    image_path : Path
        The image the occupancy came from.
    mode, negate, occupied_thresh, free_thresh
        The YAML parameters used.
    """

    occupancy: FloatArray
    resolution: float
    origin: FloatArray
    image_path: Path
    mode: str = "trinary"
    negate: int = 0
    occupied_thresh: float = 0.65
    free_thresh: float = 0.196


# ---------------------------------------------------------------- PGM


def _pgm_error(path: str | os.PathLike[str], message: str, field: str) -> DataFormatError:
    return DataFormatError(message, path=str(path), field=field)


def check_image_size(path: str | os.PathLike[str], width: int, height: int) -> None:
    """Refuses an image of more pixels than the ``image_pixels`` limit, before it is decoded."""
    check_limit("image_pixels", float(width) * float(height), f"image {path} ({width} x {height} pixels)")


def open_pil_image(path: str | os.PathLike[str], field: str = "image"):  # type: ignore[no-untyped-def]
    """A Pillow image, opened (header read, nothing decoded) and checked against the
    ``image_pixels`` limit (ResourceLimitError naming its size). A file Pillow cannot read raises
    DataFormatError naming ``field``."""
    from PIL import Image, UnidentifiedImageError

    p = Path(path)
    if not p.is_file():
        if not p.exists():
            raise FileNotFoundError(f"{p}: no such image file")
        raise DataFormatError("not a regular file", path=str(p), field="image")
    # Pillow's own decompression-bomb guard is off while the header is read: crlam's limit is
    # checked right after, on the size the header declares, before anything is decoded.
    saved = Image.MAX_IMAGE_PIXELS
    Image.MAX_IMAGE_PIXELS = None
    try:
        img = Image.open(p)
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        raise DataFormatError(f"cannot read image ({exc})", path=str(p), field=field) from exc
    finally:
        Image.MAX_IMAGE_PIXELS = saved
    try:
        check_image_size(p, *img.size)
    except ResourceLimitError:
        img.close()
        raise
    return img


def read_pgm(path: str | os.PathLike[str]) -> NDArray[np.uint8] | NDArray[np.uint16]:
    """Read a binary (P5) or ASCII (P2) PGM image with Pillow, comments allowed.

    Returns
    -------
    ndarray, shape (height, width)
        Pixel values, row 0 = top of the image, scaled to the full range of the type as Pillow
        does: ``uint8`` (0..255) when maxval <= 255, ``uint16`` (0..65535) otherwise. A file with
        maxval 15 holding 15 reads as 255.

    Raises
    ------
    DataFormatError
        Naming the file and the field: ``magic`` (not a PGM), ``header`` (bad size or maxval)
        or ``raster`` (truncated or out-of-range pixel data).
    """
    p = Path(path)
    if p.is_file():  # anything else (missing, a FIFO, /dev/zero) is refused by open_pil_image
        with open(p, "rb") as fh:
            magic = fh.read(2)
        if magic not in (b"P5", b"P2"):
            raise _pgm_error(path, f"not a PGM file (magic {magic!r}, want P5 or P2)", "magic")
    img = open_pil_image(p, field="header")
    with img:
        try:
            img.load()
        except (ValueError, OSError) as exc:
            raise _pgm_error(path, f"bad PGM raster ({exc})", "raster") from exc
        if img.mode == "L":
            return np.asarray(img, dtype=np.uint8).copy()
        return np.asarray(img, dtype=np.int64).astype(np.uint16)


def write_pgm(path: str | os.PathLike[str], image: ArrayLike) -> None:
    """Write a binary (P5) PGM with Pillow, row 0 = top of the image.

    Parameters
    ----------
    image : array_like, shape (height, width), integer
        ``uint8`` (maxval 255) or wider integers up to 65535 (maxval 65535, 16-bit big endian).
    """
    from PIL import Image

    a = np.asarray(image)
    if a.ndim != 2 or a.size == 0:
        raise DataFormatError(f"image must be a non-empty 2-D array, got shape {a.shape}", path=str(path), field="image")
    if a.dtype == np.bool_ or not np.issubdtype(a.dtype, np.integer):
        raise DataFormatError(f"image must hold integers, got {a.dtype}", path=str(path), field="image")
    if int(a.min()) < 0 or int(a.max()) > 65535:
        raise DataFormatError("pixel values must lie in 0..65535", path=str(path), field="image")
    wide = a.dtype == np.uint16 or (a.dtype.itemsize > 1 and int(a.max()) > 255)
    img = Image.fromarray(np.ascontiguousarray(a, dtype=np.uint16 if wide else np.uint8))
    img.save(path, format="PPM")


def _image_planes(path: Path) -> tuple[FloatArray, FloatArray | None]:
    """Brightness (mean of the colour channels) and opacity, both in [0, 1], row 0 = top."""
    with open(path, "rb") as fh:
        magic = fh.read(2)
    if magic in (b"P5", b"P2"):
        values = read_pgm(path)
        return values.astype(np.float64) / (255.0 if values.dtype == np.uint8 else 65535.0), None
    img = open_pil_image(path)
    try:
        img.load()
    except (OSError, ValueError, SyntaxError) as exc:
        raise DataFormatError(f"cannot read image ({exc})", path=str(path), field="image") from exc
    if img.mode == "P":
        img = img.convert("RGBA" if "transparency" in img.info else "RGB")
    elif img.mode == "1":
        img = img.convert("L")
    if img.mode in ("I;16", "I;16B", "I;16L", "I"):
        arr = np.asarray(img, dtype=np.float64)
        return arr / (65535.0 if arr.max(initial=0) > 255 or "16" in img.mode else 255.0), None
    if img.mode not in ("L", "LA", "RGB", "RGBA"):
        img = img.convert("RGBA" if "A" in img.mode else "RGB")
    arr = np.asarray(img, dtype=np.float64) / 255.0
    if img.mode == "L":
        return arr, None
    if img.mode == "LA":
        return arr[..., 0], arr[..., 1]
    rgb = arr[..., :3].mean(axis=-1)
    return rgb, (arr[..., 3] if img.mode == "RGBA" else None)


def read_image(path: str | os.PathLike[str]) -> FloatArray:
    """Brightness of a PGM/PNG/... image in [0, 1] (mean of the colour channels, alpha
    ignored), shape (height, width), row 0 = top of the image."""
    return _image_planes(Path(path))[0]


# ---------------------------------------------------------------- Nav2


def _classify(occ: FloatArray, occupied_thresh: float, free_thresh: float) -> NDArray[np.int8]:
    out = np.full(occ.shape, _UNKNOWN, dtype=np.int8)
    out[occ > occupied_thresh] = _OCCUPIED
    out[occ < free_thresh] = _FREE  # NaN compares False in both tests, so it stays unknown
    return out


def _class_pixels(occupied_thresh: float, free_thresh: float, negate: int) -> dict[int, int]:
    """8-bit pixel value per class that Nav2 decodes back to that class.

    The ``map_saver`` values (254 free, 0 occupied, 205 unknown; mirrored with ``negate``) are
    kept when the thresholds allow, otherwise the closest value that decodes correctly.
    """
    pixels = np.arange(256, dtype=np.float64)
    shade = pixels / 255.0
    decoded = _classify(shade if negate else 1.0 - shade, occupied_thresh, free_thresh)
    preferred = {_FREE: 254, _OCCUPIED: 0, _UNKNOWN: 205}
    out: dict[int, int] = {}
    for cls, px in preferred.items():
        px = 255 - px if negate else px
        ok = np.flatnonzero(decoded == cls)
        if ok.size == 0:
            raise ConfigError(
                f"thresholds occupied={occupied_thresh} free={free_thresh} leave no 8-bit pixel value for class {cls}"
            )
        out[cls] = int(ok[np.argmin(np.abs(ok - px))])
    return out


def write_nav2_map(
    pgm_path: str | os.PathLike[str],
    occupancy: ArrayLike,
    *,
    resolution: float,
    origin: ArrayLike,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
    negate: int = 0,
) -> Path:
    """Write an occupancy grid as a Nav2 trinary map: a P5 PGM plus a YAML file beside it.

    Parameters
    ----------
    pgm_path : str or PathLike
        Image path; the YAML goes to the same path with suffix ``.yaml``.
    occupancy : array_like, shape (ny, nx)
        Occupancy probability in [0, 1], NaN for unknown, ``[iy, ix]`` with ``iy = 0`` at the
        minimum y (written as the *last* image row).
    resolution : float
        Cell size (m), > 0.
    origin : array_like, shape (2,) or (3,)
        ``(x, y[, yaw])`` of the lower-left corner of cell ``[0, 0]`` (m, m, rad).
    occupied_thresh, free_thresh : float
        Nav2 thresholds, ``0 <= free_thresh < occupied_thresh <= 1``.
    negate : int
        0 (white = free) or 1 (white = occupied).

    Returns
    -------
    Path
        The YAML path.
    """
    pgm = Path(pgm_path)
    occ = np.asarray(occupancy, dtype=np.float64)
    if occ.ndim != 2 or occ.size == 0:
        raise DataFormatError(f"occupancy must be a non-empty 2-D array, got shape {occ.shape}", path=str(pgm), field="occupancy")
    image = nav2_pixels(occ, occupied_thresh=occupied_thresh, free_thresh=free_thresh, negate=negate, path=pgm)
    return write_nav2_image(
        pgm, image, resolution=resolution, origin=origin, occupied_thresh=occupied_thresh, free_thresh=free_thresh, negate=negate
    )


def _check_thresholds(occupied_thresh: float, free_thresh: float, negate: int) -> None:
    if not 0.0 <= free_thresh < occupied_thresh <= 1.0:
        raise ConfigError(f"need 0 <= free_thresh < occupied_thresh <= 1, got {free_thresh}, {occupied_thresh}")
    if negate not in (0, 1):
        raise ConfigError(f"negate must be 0 or 1, got {negate!r}")


def nav2_pixels(
    occupancy: ArrayLike,
    *,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
    negate: int = 0,
    path: str | os.PathLike[str] | None = None,
) -> NDArray[np.uint8]:
    """The 8-bit pixels of a Nav2 trinary map for occupancy probabilities, row for row.

    ``occupancy`` (h, nx) in [0, 1], NaN unknown, may be any band of rows of a map: the pixels
    of a whole map are the pixels of its bands stacked, so a large map is classified band by band
    and written with :func:`write_nav2_image`. ``path`` names the map in errors.

    Returns
    -------
    ndarray, shape (h, nx), uint8
        0 occupied, 254 free, 205 unknown (``map_saver``'s values; mirrored with ``negate``),
        rows in the array's order (not flipped).
    """
    where = None if path is None else str(path)
    occ = np.asarray(occupancy, dtype=np.float64)
    if occ.ndim != 2:
        raise DataFormatError(f"occupancy must be a 2-D array, got shape {occ.shape}", path=where, field="occupancy")
    finite = occ[np.isfinite(occ)]
    if np.isinf(occ).any() or (finite.size and (finite.min() < 0.0 or finite.max() > 1.0)):
        raise DataFormatError("occupancy must lie in [0, 1] or be NaN", path=where, field="occupancy")
    _check_thresholds(occupied_thresh, free_thresh, negate)
    lut = _class_pixels(occupied_thresh, free_thresh, int(negate))
    classes = _classify(occ, occupied_thresh, free_thresh)
    image = np.empty(occ.shape, dtype=np.uint8)
    for cls, px in lut.items():
        image[classes == cls] = px
    return image


def write_nav2_image(
    pgm_path: str | os.PathLike[str],
    image: ArrayLike,
    *,
    resolution: float,
    origin: ArrayLike,
    occupied_thresh: float = 0.65,
    free_thresh: float = 0.196,
    negate: int = 0,
) -> Path:
    """Writes :func:`nav2_pixels` of a whole map (``(ny, nx)`` uint8, row 0 at the minimum y) as
    a Nav2 map: the P5 PGM and the YAML beside it; the arguments as :func:`write_nav2_map`'s.
    Returns the YAML path."""
    pgm = Path(pgm_path)
    pixels = np.asarray(image)
    if pixels.ndim != 2 or pixels.size == 0 or pixels.dtype != np.uint8:
        raise DataFormatError(
            f"image must be a non-empty 2-D uint8 array, got {pixels.dtype} {pixels.shape}", path=str(pgm), field="image"
        )
    if not (math.isfinite(resolution) and resolution > 0):
        raise ConfigError(f"resolution must be positive, got {resolution}")
    org = np.asarray(origin, dtype=np.float64).reshape(-1)
    if org.shape == (2,):
        org = np.append(org, 0.0)
    if org.shape != (3,) or not np.all(np.isfinite(org)):
        raise ConfigError(f"origin must be 2 or 3 finite numbers, got {origin!r}")
    _check_thresholds(occupied_thresh, free_thresh, negate)
    write_pgm(pgm, pixels[::-1])
    yaml_path = pgm.with_suffix(".yaml")
    doc = {
        "image": pgm.name,
        "mode": "trinary",
        "resolution": float(resolution),
        "origin": [float(v) for v in org.tolist()],
        "negate": int(negate),
        "occupied_thresh": float(occupied_thresh),
        "free_thresh": float(free_thresh),
    }
    # PyYAML writes a float without a dot as "1.0e-05", which every YAML parser reads as a float.
    yaml_path.write_text(yaml.safe_dump(doc, sort_keys=False, default_flow_style=None), encoding="utf-8")
    return yaml_path


def _yaml_number(doc: dict[str, object], key: str, path: Path, default: float | None) -> float:
    if key not in doc:
        if default is None:
            raise DataFormatError("missing key", path=str(path), field=key)
        return default
    try:
        v = float(doc[key])  # type: ignore[arg-type]
    except (TypeError, ValueError):
        raise DataFormatError(f"not a number: {doc[key]!r}", path=str(path), field=key) from None
    if not math.isfinite(v):
        raise DataFormatError(f"non-finite value {v}", path=str(path), field=key)
    return v


def read_nav2_map(yaml_path: str | os.PathLike[str], *, free_thresh: float | None = None) -> Nav2Map:
    """Read a Nav2 map (YAML + PGM/PNG image) into an occupancy grid.

    ``free_thresh`` replaces the YAML's (e.g. map_saver's 0.196 for a YAML whose 0.25 makes the
    unknown grey 205 free).

    ``image`` is resolved relative to the YAML file. ``mode`` defaults to trinary, ``negate``
    to 0, the thresholds to 0.65 / 0.196 when absent. In trinary mode an alpha channel is
    averaged with the colour channels; in scale mode a transparent pixel is unknown (both as
    in Nav2).

    Raises
    ------
    DataFormatError
        On invalid YAML (with its line), a missing or invalid key (named), or a bad image.
    """
    path = Path(yaml_path)
    doc = load_yaml_text(read_small_text(path, "Nav2 map YAML"), str(path))
    if not isinstance(doc, dict):
        raise DataFormatError("not a YAML mapping", path=str(path))
    if not isinstance(doc.get("image"), str) or not doc["image"]:
        raise DataFormatError("missing or invalid image path", path=str(path), field="image")
    resolution = _yaml_number(doc, "resolution", path, None)
    if resolution <= 0:
        raise DataFormatError(f"must be positive, got {resolution}", path=str(path), field="resolution")
    origin = doc.get("origin")
    if not isinstance(origin, list) or len(origin) not in (2, 3):
        raise DataFormatError(f"must be a list [x, y, yaw], got {origin!r}", path=str(path), field="origin")
    org = np.array([_yaml_number({"origin": v}, "origin", path, None) for v in origin] + [0.0])[:3]
    occ_t = _yaml_number(doc, "occupied_thresh", path, 0.65)
    free_t = _yaml_number(doc, "free_thresh", path, 0.196) if free_thresh is None else float(free_thresh)
    if not 0.0 <= free_t <= occ_t <= 1.0:
        raise DataFormatError(
            f"need 0 <= free_thresh <= occupied_thresh <= 1, got free_thresh {free_t}, occupied_thresh {occ_t}",
            path=str(path),
            field="free_thresh",
        )
    negate_raw = doc.get("negate", 0)
    if negate_raw not in (0, 1):  # True/False compare equal to 1/0
        raise DataFormatError(f"must be 0 or 1, got {negate_raw!r}", path=str(path), field="negate")
    mode = str(doc.get("mode", "trinary")).lower()
    if mode not in ("trinary", "scale", "raw"):
        raise DataFormatError(f"unknown mode {mode!r}", path=str(path), field="mode")
    image_path = Path(doc["image"])
    if not image_path.is_absolute():
        image_path = path.parent / image_path
    if not image_path.is_file():
        raise DataFormatError(f"image file not found: {image_path}", path=str(path), field="image")
    shade, alpha = _image_planes(image_path)
    negate = int(negate_raw)
    if mode == "trinary":
        if alpha is not None:
            shade = (3.0 * shade + alpha) / 4.0
        cls = _classify(shade if negate else 1.0 - shade, occ_t, free_t)
        occ = np.where(cls == _OCCUPIED, 1.0, np.where(cls == _FREE, 0.0, np.nan))
    elif mode == "scale":
        occ_raw = shade if negate else 1.0 - shade
        cls = _classify(occ_raw, occ_t, free_t)
        mid = np.rint((occ_raw - free_t) / (occ_t - free_t) * 100.0) / 100.0
        occ = np.where(cls == _OCCUPIED, 1.0, np.where(cls == _FREE, 0.0, mid))
        if alpha is not None:
            occ[alpha < 1.0] = np.nan
    else:
        percent = np.round(shade * 255.0)
        occ = np.where(percent <= 100.0, percent / 100.0, np.nan)
    return Nav2Map(
        occupancy=np.ascontiguousarray(occ[::-1]),
        resolution=resolution,
        origin=org,
        image_path=image_path,
        mode=mode,
        negate=negate,
        occupied_thresh=occ_t,
        free_thresh=free_t,
    )
