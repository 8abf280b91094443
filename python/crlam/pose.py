"""SE(2) pose algebra on numpy arrays.

A pose is ``(x, y, theta)`` in metres and radians, stored as float64 arrays whose last axis has
length 3. Every function broadcasts over leading axes. Headings are wrapped to ``(-pi, pi]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike, NDArray

__all__ = ["wrap_angle", "compose", "inverse", "between", "transform_points"]

Array = NDArray[np.float64]


def wrap_angle(theta: ArrayLike) -> Array:
    """Wrap angles (rad) to ``(-pi, pi]``."""
    t = np.asarray(theta, dtype=np.float64)
    w = np.mod(t + np.pi, 2.0 * np.pi) - np.pi
    # mod maps +pi to -pi; the convention here keeps +pi.
    return np.where(w == -np.pi, np.pi, w)


def compose(a: ArrayLike, b: ArrayLike) -> Array:
    """``a ⊕ b``: the pose ``b`` (expressed in frame ``a``) in the world frame. Shapes ``(..., 3)``."""
    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, wrap_angle(a[..., 2] + b[..., 2])], axis=-1)


def inverse(a: ArrayLike) -> Array:
    """``a⁻¹``, so that ``compose(a, inverse(a))`` is the identity. Shape ``(..., 3)``."""
    a = np.asarray(a, dtype=np.float64)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -(c * a[..., 0] + s * a[..., 1])
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack([x, y, wrap_angle(-a[..., 2])], axis=-1)


def between(a: ArrayLike, b: ArrayLike) -> Array:
    """``a⁻¹ ⊕ b``: pose ``b`` expressed in the frame of ``a`` (odometry increment)."""
    return compose(inverse(a), b)


def transform_points(pose: ArrayLike, points: ArrayLike) -> Array:
    """Map points ``(..., 2)`` from the frame of ``pose`` (shape ``(3,)``) to the world frame."""
    p = np.asarray(pose, dtype=np.float64)
    q = np.asarray(points, dtype=np.float64)
    c, s = np.cos(p[2]), np.sin(p[2])
    return np.stack([p[0] + c * q[..., 0] - s * q[..., 1], p[1] + s * q[..., 0] + c * q[..., 1]], axis=-1)
