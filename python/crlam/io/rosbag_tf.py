"""Transforms of ROS bags: quaternions to matrices, planar projection, and the tree of fixed
transforms between frames that the bag reader (:mod:`crlam.io.rosbag`) resolves the laser's and
the IMU's mounts through.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import NDArray

from crlam.io.message_checks import MessagePlace, check_translation, unit_quaternion

__all__ = ["FixedTransforms", "TransformTree", "planar", "quat_matrix", "transform_matrix", "wrap", "yaw_of"]

#: Two readings of one transform that differ by more than this (m, or rad per matrix entry) are
#: not the same fixed transform.
_FIXED_TOLERANCE = 1e-6
#: The place named when a caller gives none.
_NOWHERE = MessagePlace("(a ROS bag)", "a message", 0)


def quat_matrix(q: Any, place: MessagePlace | None = None, field: str = "rotation") -> NDArray[np.float64]:
    """The rotation matrix of a ROS quaternion, checked and normalised by the rule of
    :func:`crlam.io.message_checks.unit_quaternion` (``place`` names the message in errors)."""
    x, y, z, w = unit_quaternion(q, place or _NOWHERE, field)
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def transform_matrix(t: Any, place: MessagePlace | None = None, child: str = "") -> NDArray[np.float64]:
    """A ``geometry_msgs/Transform`` or ``Pose`` as a 4x4 matrix; a rotation that is not a unit
    quaternion (within the tolerance) or a translation that is not finite is refused, naming
    ``place`` and the transform's ``child`` frame."""
    m = np.eye(4)
    rotation = getattr(t, "rotation", None)
    rot = rotation if rotation is not None else t.orientation
    translation = getattr(t, "translation", None)
    tr = translation if translation is not None else t.position
    where = f"transform to {child}" if child else "transform"
    m[:3, :3] = quat_matrix(rot, place, f"{where}: rotation")
    m[:3, 3] = check_translation(tr, place or _NOWHERE, f"{where}: translation")
    return m


def planar(m: NDArray[np.float64]) -> tuple[NDArray[np.float64], bool]:
    """``(x, y, yaw)`` of a 3D transform and whether its z axis points down (upside down)."""
    yaw = math.atan2(m[1, 0], m[0, 0])
    return np.array([m[0, 3], m[1, 3], yaw]), bool(m[2, 2] < 0.0)


def yaw_of(q: Any, place: MessagePlace | None = None, field: str = "orientation") -> float:
    """The yaw (rad) of a ROS quaternion, checked and normalised as :func:`quat_matrix` does."""
    x, y, z, w = unit_quaternion(q, place or _NOWHERE, field)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def wrap(a: float) -> float:
    return (a + math.pi) % (2.0 * math.pi) - math.pi


class TransformTree:
    """The static transforms as a forest of parent links; resolves the transform between two frames."""

    def __init__(self) -> None:
        self.parent: dict[str, tuple[str, NDArray[np.float64]]] = {}

    def add(self, parent: str, child: str, m: NDArray[np.float64]) -> None:
        self.parent[child.lstrip("/")] = (parent.lstrip("/"), m)

    def _to_root(self, frame: str) -> tuple[list[str], dict[str, NDArray[np.float64]]]:
        chain = [frame]
        poses = {frame: np.eye(4)}  # frame's pose in each ancestor, filled below
        acc = np.eye(4)
        seen = {frame}
        f = frame
        while f in self.parent:
            p, m = self.parent[f]
            if p in seen:
                break
            acc = m @ acc
            poses[p] = acc.copy()
            chain.append(p)
            seen.add(p)
            f = p
        return chain, poses

    def lookup(self, base: str, child: str) -> NDArray[np.float64] | None:
        """The pose of ``child`` in ``base`` (4x4), or None when no static chain links them."""
        base, child = base.lstrip("/"), child.lstrip("/")
        if base == child:
            return np.eye(4)
        chain_b, poses_b = self._to_root(base)
        chain_c, poses_c = self._to_root(child)
        common = next((f for f in chain_c if f in poses_b), None)
        if common is None:
            return None
        # T_common_base^-1 @ T_common_child
        return np.asarray(np.linalg.inv(poses_b[common]) @ poses_c[common])

    def reaches(self, base: str, child: str) -> bool:
        return self.lookup(base, child) is not None

    def root(self, frame: str) -> str:
        """The topmost ancestor of ``frame`` (``frame`` itself without a parent)."""
        return self._to_root(frame.lstrip("/"))[0][-1]

    def merged(self, other: TransformTree) -> TransformTree:
        """A tree with this tree's links and those of ``other`` for the frames this one lacks."""
        out = TransformTree()
        out.parent = {**other.parent, **self.parent}
        return out


class FixedTransforms:
    """Transforms published on ``/tf`` that never change: a fixed mount (base -> laser) that a
    bag publishes on ``/tf`` instead of ``/tf_static``.

    Feed it the ``/tf`` transforms with :meth:`add`; links whose parent is in ``skip_parents``
    (the odometry and map frames: moving transforms by definition) are left out, and a link
    whose value changes between two messages is dropped as moving (listed in :attr:`moving`).
    """

    def __init__(self, skip_parents: Iterable[str]) -> None:
        self.skip = {f.lstrip("/") for f in skip_parents}
        self.links: dict[str, tuple[str, NDArray[np.float64]]] = {}
        self.moving: set[str] = set()

    def add(self, parent: str, child: str, m: NDArray[np.float64]) -> None:
        parent, child = parent.lstrip("/"), child.lstrip("/")
        if parent in self.skip or child in self.moving:
            return
        seen = self.links.get(child)
        if seen is None:
            self.links[child] = (parent, m)
        elif seen[0] != parent or not np.allclose(seen[1], m, rtol=0.0, atol=_FIXED_TOLERANCE):
            del self.links[child]
            self.moving.add(child)

    def tree(self) -> TransformTree:
        out = TransformTree()
        for child, (parent, m) in self.links.items():
            out.add(parent, child, m)
        return out
