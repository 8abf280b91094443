"""SE(2) pose algebra on numpy arrays.

A pose is ``(x, y, theta)`` in metres and radians, stored as float64 arrays whose last axis has
length 3. Every function broadcasts over leading axes. Headings are wrapped to ``(-pi, pi]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import ConfigError

__all__ = ["wrap_angle", "compose", "inverse", "between", "number_pair", "transform_points"]

Array = NDArray[np.float64]


def wrap_angle(theta: ArrayLike) -> Array:
    """Wrap angles (rad) to ``(-pi, pi]``."""
    t = np.asarray(theta, dtype=np.float64)
    w = np.mod(t + np.pi, 2.0 * np.pi) - np.pi
    # mod maps +pi to -pi; the convention here keeps +pi.
    return np.where(w == -np.pi, np.pi, w)


def number_pair(value: object, name: str, *, finite: bool = True) -> tuple[float, float]:
    """``value`` as two floats (a point, an origin, a bandwidth), finite unless ``finite=False``
    (NaN is refused either way), or :class:`ConfigError`."""
    try:
        a, b = (float(v) for v in value)  # type: ignore[attr-defined]
    except (TypeError, ValueError):
        raise ConfigError(f"{name} must be two numbers, got {value!r}") from None
    if np.isnan(a) or np.isnan(b) or (finite and not (np.isfinite(a) and np.isfinite(b))):
        raise ConfigError(f"{name} must be two {'finite ' if finite else ''}numbers, got {value!r}")
    return a, b


def _poses(a: ArrayLike, name: str) -> Array:
    """``a`` as a float64 array of poses, shape ``(..., 3)``."""
    p = np.asarray(a, dtype=np.float64)
    if p.ndim == 0 or p.shape[-1] != 3:
        raise ConfigError(f"{name} must hold poses (x, y, theta) along its last axis, got shape {p.shape}")
    return p


def compose(a: ArrayLike, b: ArrayLike) -> Array:
    """``a ⊕ b``: the pose ``b`` (expressed in frame ``a``) in the world frame. Shapes ``(..., 3)``."""
    a = _poses(a, "a")
    b = _poses(b, "b")
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def inverse(a: ArrayLike) -> Array:
    """``a⁻¹``, so that ``compose(a, inverse(a))`` is the identity. Shape ``(..., 3)``."""
    a = _poses(a, "a")
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(c * a[..., 0] + s * a[..., 1])
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack([x, y, wrap_angle(-a[..., 2])], axis=-1)


def between(a: ArrayLike, b: ArrayLike) -> Array:
    """``a⁻¹ ⊕ b``: pose ``b`` expressed in the frame of ``a`` (odometry increment)."""
    return compose(inverse(a), b)


def transform_points(pose: ArrayLike, points: ArrayLike) -> Array:
    """Map points ``(..., 2)`` from the frame of ``pose`` (shape ``(3,)``) to the world frame."""
    p = _poses(pose, "pose")
    q = np.asarray(points, dtype=np.float64)
    if p.shape != (3,) or q.ndim == 0 or q.shape[-1] != 2:
        raise ConfigError(f"need a pose (3,) and points (..., 2), got shapes {p.shape} and {q.shape}")
    c, s = np.cos(p[2]), np.sin(p[2])
    return np.stack([p[0] + c * q[..., 0] - s * q[..., 1], p[1] + s * q[..., 0] + c * q[..., 1]], axis=-1)
