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
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml
from numpy.typing import ArrayLike, NDArray

from crlam.errors import ConfigError, DataFormatError

__all__ = ["Nav2Map", "read_image", "read_nav2_map", "read_pgm", "write_nav2_map", "write_pgm"]

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


def _read_pgm(path: str | os.PathLike[str]) -> tuple[NDArray[np.uint16] | NDArray[np.uint8], int]:
    data = Path(path).read_bytes()
    if data[:2] not in (b"P5", b"P2"):
        raise _pgm_error(path, f"not a PGM file (magic {data[:2]!r}, want P5 or P2)", "magic")
    pos = 2
    header: list[int] = []
    while len(header) < 3:
        while pos < len(data) and data[pos : pos + 1].isspace():
            pos += 1
        if pos < len(data) and data[pos : pos + 1] == b"#":
            end = data.find(b"\n", pos)
            pos = len(data) if end < 0 else end + 1
            continue
        start = pos
        while pos < len(data) and not data[pos : pos + 1].isspace() and data[pos] != ord("#"):
            pos += 1
        name = ("width", "height", "maxval")[len(header)]
        token = data[start:pos]
        if not token.isdigit():
            raise _pgm_error(path, f"bad header value {token[:16]!r}", name)
        header.append(int(token))
    width, height, maxval = header
    if width <= 0 or height <= 0:
        raise _pgm_error(path, f"image size {width} x {height} is empty", "width")
    if not 0 < maxval < 65536:
        raise _pgm_error(path, f"maxval {maxval} outside 1..65535", "maxval")
    dtype = np.dtype(np.uint8) if maxval < 256 else np.dtype(">u2")
    count = width * height
    if data[:2] == b"P5":
        # Exactly one whitespace byte separates maxval from the raster.
        raster = data[pos + 1 : pos + 1 + count * dtype.itemsize]
        if len(raster) < count * dtype.itemsize:
            raise _pgm_error(path, f"raster truncated: {len(raster)} of {count * dtype.itemsize} bytes", "raster")
        values = np.frombuffer(raster, dtype=dtype).astype(dtype.newbyteorder("="))
    else:
        text = re.sub(rb"#[^\n]*", b" ", data[pos:]).split()
        if len(text) < count:
            raise _pgm_error(path, f"raster truncated: {len(text)} of {count} values", "raster")
        try:
            ints = np.array([int(t) for t in text[:count]], dtype=np.int64)
        except ValueError:
            raise _pgm_error(path, "non-integer pixel value", "raster") from None
        if ints.min() < 0 or ints.max() > maxval:
            raise _pgm_error(path, f"pixel values must lie in 0..{maxval}", "raster")
        values = ints.astype(np.uint8 if maxval < 256 else np.uint16)
    if int(values.max()) > maxval:
        raise _pgm_error(path, f"pixel value {int(values.max())} above maxval {maxval}", "raster")
    return values.reshape(height, width), maxval


def read_pgm(path: str | os.PathLike[str]) -> NDArray[np.uint8] | NDArray[np.uint16]:
    """Read a binary (P5) or ASCII (P2) PGM image, comments allowed.

    Returns
    -------
    ndarray, shape (height, width)
        Pixel values as stored, row 0 = top of the image: ``uint8`` when maxval <= 255,
        ``uint16`` otherwise (native byte order).
    """
    return _read_pgm(path)[0]


def write_pgm(path: str | os.PathLike[str], image: ArrayLike, *, comment: str | None = None) -> None:
    """Write a binary (P5) PGM, row 0 = top of the image.

    Parameters
    ----------
    image : array_like, shape (height, width), integer
        ``uint8`` (maxval 255) or wider integers up to 65535 (maxval 65535, 16-bit big endian).
    comment : str, optional
        One comment line written in the header.
    """
    a = np.asarray(image)
    if a.ndim != 2 or a.size == 0:
        raise DataFormatError(f"image must be a non-empty 2-D array, got shape {a.shape}", path=str(path), field="image")
    if a.dtype == np.bool_ or not np.issubdtype(a.dtype, np.integer):
        raise DataFormatError(f"image must hold integers, got {a.dtype}", path=str(path), field="image")
    if int(a.min()) < 0 or int(a.max()) > 65535:
        raise DataFormatError("pixel values must lie in 0..65535", path=str(path), field="image")
    wide = a.dtype == np.uint16 or (a.dtype.itemsize > 1 and int(a.max()) > 255)
    maxval = 65535 if wide else 255
    raster = a.astype(">u2" if wide else np.uint8).tobytes()
    head = "P5\n" + ("" if comment is None else f"# {comment}\n") + f"{a.shape[1]} {a.shape[0]}\n{maxval}\n"
    Path(path).write_bytes(head.encode("ascii") + raster)


def _image_planes(path: Path) -> tuple[FloatArray, FloatArray | None]:
    """Brightness (mean of the colour channels) and opacity, both in [0, 1], row 0 = top."""
    with open(path, "rb") as fh:
        magic = fh.read(2)
    if magic in (b"P5", b"P2"):
        values, maxval = _read_pgm(path)
        return values.astype(np.float64) / maxval, None
    from PIL import Image, UnidentifiedImageError

    try:
        img: Image.Image = Image.open(path)
        img.load()
    except (UnidentifiedImageError, OSError) as exc:
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


def _yaml_float(v: float) -> str:
    text = repr(float(v))
    # PyYAML (YAML 1.1) reads "1e-05" as a string; "1.0e-05" is a float for every parser.
    if "e" in text and "." not in text:
        text = text.replace("e", ".0e")
    return text


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
    finite = occ[np.isfinite(occ)]
    if np.isinf(occ).any() or (finite.size and (finite.min() < 0.0 or finite.max() > 1.0)):
        raise DataFormatError("occupancy must lie in [0, 1] or be NaN", path=str(pgm), field="occupancy")
    if not (math.isfinite(resolution) and resolution > 0):
        raise ConfigError(f"resolution must be positive, got {resolution}")
    org = np.asarray(origin, dtype=np.float64).reshape(-1)
    if org.shape == (2,):
        org = np.append(org, 0.0)
    if org.shape != (3,) or not np.all(np.isfinite(org)):
        raise ConfigError(f"origin must be 2 or 3 finite numbers, got {origin!r}")
    if not 0.0 <= free_thresh < occupied_thresh <= 1.0:
        raise ConfigError(f"need 0 <= free_thresh < occupied_thresh <= 1, got {free_thresh}, {occupied_thresh}")
    if negate not in (0, 1):
        raise ConfigError(f"negate must be 0 or 1, got {negate!r}")
    negate = int(negate)
    lut = _class_pixels(occupied_thresh, free_thresh, negate)
    classes = _classify(occ, occupied_thresh, free_thresh)
    image = np.empty(occ.shape, dtype=np.uint8)
    for cls, px in lut.items():
        image[classes == cls] = px
    write_pgm(pgm, image[::-1])
    yaml_path = pgm.with_suffix(".yaml")
    yaml_path.write_text(
        f"image: {pgm.name}\n"
        "mode: trinary\n"
        f"resolution: {_yaml_float(resolution)}\n"
        f"origin: [{', '.join(_yaml_float(v) for v in org.tolist())}]\n"
        f"negate: {negate}\n"
        f"occupied_thresh: {_yaml_float(occupied_thresh)}\n"
        f"free_thresh: {_yaml_float(free_thresh)}\n",
        encoding="utf-8",
    )
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
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        raise DataFormatError(f"invalid YAML ({exc})", path=str(path), line=None if mark is None else mark.line + 1) from exc
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
