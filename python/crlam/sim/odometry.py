"""Odometry noise models: sampling the odometry a robot reports, and its density.

An odometry *increment* is the relative pose ``(dx, dy, dtheta)`` (m, m, rad) between two
consecutive robot poses, expressed in the frame of the first one (``crlam.pose.between``).
The simulator turns the true increments into reported ones with a noise model, then accumulates
them (:func:`integrate_odometry`) into the odometry poses a CARMEN log stores.

Two models:

- :class:`GaussianIncrementNoise`: the spec's model (4.4): ``u = delta + eps``,
  ``eps ~ N(0, diag(sigma_x², sigma_y², sigma_theta²))`` per step, angle wrapped.
- :class:`ThrunOdometryNoise`: Thrun, Burgard and Fox's ``sample_motion_model_odometry``
  (Probabilistic Robotics, table 5.6): the increment is decomposed into a rotation ``rot1``
  towards the direction of travel, a translation ``trans`` and a final rotation ``rot2``; each is
  perturbed with a variance growing with the motion.

Both give ``log_pdf(increment, commanded)``, the log density of an increment given the commanded
(true) one, with respect to Lebesgue measure on ``(dx, dy, dtheta)``, which the particle filter
needs (``p(x_k | x_{k-1}, u_k)`` with ``increment = between(x_{k-1}, x_k)``; both models are
symmetric enough that the roles of the two arguments may be swapped, as the spec does).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import ConfigError
from crlam.pose import between, wrap_angle

__all__ = [
    "GaussianIncrementNoise",
    "OdometryNoise",
    "ThrunOdometryNoise",
    "increments_from_poses",
    "integrate_odometry",
    "odometry_noise_from_dict",
]

Array = NDArray[np.float64]
_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


def _log_normal(residual: Array, sigma: Array) -> Array:
    return -0.5 * (residual / sigma) ** 2 - np.log(sigma) - _LOG_SQRT_2PI


@dataclass(frozen=True)
class GaussianIncrementNoise:
    """Additive Gaussian noise on each increment (spec 4.4); standard deviations in m, m, rad per step."""

    sigma_x: float = 0.01
    sigma_y: float = 0.01
    sigma_theta: float = 0.01

    def __post_init__(self) -> None:
        if min(self.sigma_x, self.sigma_y, self.sigma_theta) <= 0.0:
            raise ConfigError("GaussianIncrementNoise standard deviations must be > 0")

    @property
    def sigmas(self) -> Array:
        """``(3,)`` standard deviations ``(sigma_x, sigma_y, sigma_theta)``."""
        return np.array([self.sigma_x, self.sigma_y, self.sigma_theta])

    @property
    def covariance(self) -> Array:
        """``(3, 3)`` covariance of the increment noise."""
        return np.diag(self.sigmas**2)

    def sample_increments(self, true_increments: ArrayLike, rng: np.random.Generator) -> Array:
        """Noisy increments ``(n, 3)`` from true ones ``(n, 3)``; draws one ``(n, 3)`` normal block."""
        u = np.asarray(true_increments, dtype=np.float64).reshape(-1, 3)
        out = u + rng.standard_normal(u.shape) * self.sigmas
        out[:, 2] = wrap_angle(out[:, 2])
        return out

    def log_pdf(self, increments: ArrayLike, commanded: ArrayLike) -> Array:
        """Log density of ``increments`` ``(..., 3)`` given ``commanded`` ``(..., 3)``; shape ``(...)``."""
        z = np.asarray(increments, dtype=np.float64)
        c = np.asarray(commanded, dtype=np.float64)
        r = z - c
        r[..., 2] = wrap_angle(r[..., 2])
        return _log_normal(r, self.sigmas).sum(axis=-1)

    def to_dict(self) -> dict[str, Any]:
        return {"model": "gaussian_increment", "sigma_x": self.sigma_x, "sigma_y": self.sigma_y, "sigma_theta": self.sigma_theta}


@dataclass(frozen=True)
class ThrunOdometryNoise:
    """Thrun's odometry motion model (rot1, trans, rot2 decomposition).

    Attributes
    ----------
    alpha1:
        Rotation variance per squared rotation (rad²/rad²).
    alpha2:
        Rotation variance per squared translation (rad²/m²).
    alpha3:
        Translation variance per squared translation (m²/m²).
    alpha4:
        Translation variance per squared rotation (m²/rad²), applied to ``rot1² + rot2²``.
    floor_rot, floor_trans:
        Standard deviations (rad, m) added in quadrature, so a standing robot still gets a
        proper (non-degenerate) density.
    """

    alpha1: float = 0.01
    alpha2: float = 0.01
    alpha3: float = 0.01
    alpha4: float = 0.001
    floor_rot: float = 1e-4
    floor_trans: float = 1e-4

    def __post_init__(self) -> None:
        if min(self.alpha1, self.alpha2, self.alpha3, self.alpha4) < 0.0:
            raise ConfigError("ThrunOdometryNoise alphas must be >= 0")
        if min(self.floor_rot, self.floor_trans) <= 0.0:
            raise ConfigError("ThrunOdometryNoise floors must be > 0")

    @staticmethod
    def decompose(increments: ArrayLike) -> tuple[Array, Array, Array]:
        """``(rot1, trans, rot2)`` of increments ``(..., 3)``; ``rot1 = 0`` for a pure rotation."""
        u = np.asarray(increments, dtype=np.float64)
        trans = np.hypot(u[..., 0], u[..., 1])
        # Below 1e-9 m the direction of travel is numerical noise: treat as a turn on the spot.
        rot1 = np.where(trans > 1e-9, np.arctan2(u[..., 1], u[..., 0]), 0.0)
        rot2 = wrap_angle(u[..., 2] - rot1)
        return rot1, trans, rot2

    @staticmethod
    def recompose(rot1: Array, trans: Array, rot2: Array) -> Array:
        """Increments ``(..., 3)`` from ``(rot1, trans, rot2)``."""
        return np.stack([trans * np.cos(rot1), trans * np.sin(rot1), wrap_angle(rot1 + rot2)], axis=-1)

    def stds(self, commanded: ArrayLike) -> tuple[Array, Array, Array]:
        """Standard deviations of ``(rot1, trans, rot2)`` for commanded increments ``(..., 3)``."""
        r1, t, r2 = self.decompose(commanded)
        s_r1 = np.sqrt(self.alpha1 * r1**2 + self.alpha2 * t**2 + self.floor_rot**2)
        s_t = np.sqrt(self.alpha3 * t**2 + self.alpha4 * (r1**2 + r2**2) + self.floor_trans**2)
        s_r2 = np.sqrt(self.alpha1 * r2**2 + self.alpha2 * t**2 + self.floor_rot**2)
        return s_r1, s_t, s_r2

    def sample_increments(self, true_increments: ArrayLike, rng: np.random.Generator) -> Array:
        """Noisy increments ``(n, 3)``; draws one ``(n, 3)`` standard-normal block, row by row."""
        u = np.asarray(true_increments, dtype=np.float64).reshape(-1, 3)
        r1, t, r2 = self.decompose(u)
        s_r1, s_t, s_r2 = self.stds(u)
        e = rng.standard_normal(u.shape)
        return self.recompose(r1 + s_r1 * e[:, 0], t + s_t * e[:, 1], r2 + s_r2 * e[:, 2])

    def log_pdf(self, increments: ArrayLike, commanded: ArrayLike, jacobian: bool = True) -> Array:
        """Log density of ``increments`` ``(..., 3)`` given ``commanded`` ``(..., 3)``.

        The sampler's output is ``recompose(rot1', trans', rot2')`` with independent normal
        ``rot1', trans', rot2'``. That map is two-to-one: ``(r1, t, r2)`` and
        ``(r1 + pi, -t, r2 - pi)`` give the same increment, so the density sums both preimages.
        With ``jacobian=True`` (default) it is a density on ``(dx, dy, dtheta)``, which includes
        the factor ``1/|t|`` of the polar change of variables; with ``jacobian=False`` it is
        Thrun's ``motion_model_odometry`` value, a density on ``(rot1, trans, rot2)``.
        """
        c = np.asarray(commanded, dtype=np.float64)
        c_r1, c_t, c_r2 = self.decompose(c)
        s_r1, s_t, s_r2 = self.stds(c)
        z = np.asarray(increments, dtype=np.float64)
        t = np.hypot(z[..., 0], z[..., 1])
        r1 = np.arctan2(z[..., 1], z[..., 0])
        terms = []
        for sign, shift in ((1.0, 0.0), (-1.0, math.pi)):
            a1 = r1 + shift
            a2 = z[..., 2] - a1
            lp = (
                _log_normal(wrap_angle(a1 - c_r1), s_r1)
                + _log_normal(sign * t - c_t, s_t)
                + _log_normal(wrap_angle(a2 - c_r2), s_r2)
            )
            terms.append(lp)
        out = np.logaddexp(terms[0], terms[1])
        if jacobian:
            out = out - np.log(np.maximum(t, 1e-300))
        return out

    def to_dict(self) -> dict[str, Any]:
        return {
            "model": "thrun",
            "alpha1": self.alpha1,
            "alpha2": self.alpha2,
            "alpha3": self.alpha3,
            "alpha4": self.alpha4,
            "floor_rot": self.floor_rot,
            "floor_trans": self.floor_trans,
        }


OdometryNoise = GaussianIncrementNoise | ThrunOdometryNoise


def odometry_noise_from_dict(data: dict[str, Any]) -> OdometryNoise:
    """Inverse of ``to_dict()`` of either model."""
    d = dict(data)
    model = d.pop("model", None)
    if model == "gaussian_increment":
        return GaussianIncrementNoise(**d)
    if model == "thrun":
        return ThrunOdometryNoise(**d)
    raise ConfigError(f"unknown odometry model {model!r}")


def increments_from_poses(poses: ArrayLike) -> Array:
    """Increments ``(n - 1, 3)`` between consecutive poses ``(n, 3)``: ``between(p[k-1], p[k])``."""
    p = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    return between(p[:-1], p[1:])


def integrate_odometry(start_pose: ArrayLike, increments: ArrayLike) -> Array:
    """Accumulate increments ``(n, 3)`` from ``start_pose`` ``(3,)``; returns poses ``(n + 1, 3)``.

    Pose ``k + 1`` is ``pose_k ⊕ increment_k``, with the heading wrapped to ``(-pi, pi]``:
    the odometry poses a CARMEN log stores.
    """
    u = np.asarray(increments, dtype=np.float64).reshape(-1, 3)
    out = np.empty((len(u) + 1, 3))
    x, y, th = (float(v) for v in np.asarray(start_pose, dtype=np.float64).reshape(3))
    th = float(wrap_angle(th))
    out[0] = (x, y, th)
    # A scalar loop: each step depends on the previous heading, and floats keep it fast.
    for k, (dx, dy, dth) in enumerate(u.tolist()):
        c, s = math.cos(th), math.sin(th)
        x, y = x + c * dx - s * dy, y + s * dx + c * dy
        th = th + dth
        th = math.remainder(th, 2.0 * math.pi)
        if th == -math.pi:
            th = math.pi
        out[k + 1] = (x, y, th)
    return out
