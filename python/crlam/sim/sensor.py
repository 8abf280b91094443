"""Simulated 2D laser range finder: exact ray casting plus Thrun's beam-mixture noise.

A reading ``z < max_range`` is a return ("hit" in the log); ``z == max_range`` means no return.
The noise follows the beam mixture of the spec (section 2.3) with the cause at the true range
``d`` (``d = inf`` when nothing is within range):

- hit (probability ``1 - p_short - p_rand - p_max``): ``d + N(0, sigma_hit²)``, clipped to
  ``[0, max_range)``; a no-return when nothing is within range (the spec's cause ``∞``);
- short (``p_short``): exponential of rate ``lambda_short`` truncated to ``[0, min(d, max_range))``;
- random (``p_rand``): uniform on ``[0, max_range)``;
- max (``p_max``): a dropout, ``max_range``.

Readings below ``min_range`` are reported as they are; consumers drop them (spec 2.1).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from crlam.errors import ConfigError
from crlam.sim.raycast import cast_ranges_numpy
from crlam.sim.world import World

__all__ = ["RangeSensor", "native_cast_available", "noiseless", "paper_lidar", "sick_lms200", "true_ranges"]


def native_cast_available() -> bool:
    """Whether the Rust ray caster ``crlam._native.cast_ranges`` is importable."""
    try:
        import crlam._native as native
    except ImportError:
        return False
    return hasattr(native, "cast_ranges")


def true_ranges(
    world: World, poses: ArrayLike, angles: ArrayLike, max_range: float, backend: str = "auto"
) -> NDArray[np.float64]:
    """Exact distances (m) from each pose along each beam to the first occupied cell.

    Parameters
    ----------
    world:
        The ground-truth world.
    poses:
        ``(n, 3)`` sensor poses ``(x, y, theta)`` (m, rad).
    angles:
        ``(m,)`` beam angles relative to the heading (rad).
    max_range:
        Rays are followed up to this distance (m).
    backend:
        ``"native"`` (Rust ``crlam._native.cast_ranges``), ``"numpy"``
        (:func:`crlam.sim.raycast.cast_ranges_numpy`) or ``"auto"`` (native when available).

    Returns
    -------
    ``(n, m)`` float64: entry distance of the first occupied cell, ``inf`` when none lies within
    ``max_range``, 0 when the pose is inside an occupied cell. Cells outside the grid are free.
    """
    p = np.ascontiguousarray(np.asarray(poses, dtype=np.float64).reshape(-1, 3))
    a = np.ascontiguousarray(np.asarray(angles, dtype=np.float64).reshape(-1))
    if backend not in ("auto", "native", "numpy"):
        raise ConfigError(f"unknown ray-casting backend {backend!r}")
    use_native = backend == "native" or (backend == "auto" and native_cast_available())
    ox, oy = float(world.origin[0]), float(world.origin[1])
    if use_native:
        import crlam._native as native

        occ = np.ascontiguousarray(world.occupied, dtype=np.uint8)
        out = native.cast_ranges(occ, ox, oy, float(world.resolution), p, a, float(max_range))
        return np.asarray(out, dtype=np.float64).reshape(len(p), len(a))
    return cast_ranges_numpy(world.occupied, ox, oy, world.resolution, p, a, float(max_range))


@dataclass(frozen=True)
class RangeSensor:
    """A planar laser scanner and its noise model.

    Attributes
    ----------
    n_beams:
        Number of beams per scan.
    fov:
        Field of view (rad). With ``endpoint=True`` the beams span ``[-fov/2, +fov/2]``
        inclusive (step ``fov / (n_beams - 1)``); with ``endpoint=False`` they start at
        ``-fov/2`` with step ``fov / n_beams`` (the CARMEN FLASER layout: -90 deg + k deg).
    max_range:
        Maximum range (m); a reading equal to it means "no return".
    min_range:
        Minimum valid range (m); informative only (see module docstring).
    sigma_hit:
        Standard deviation (m) of hit readings around the true range.
    p_short, p_rand, p_max:
        Probabilities of a short reading, a uniform random reading and a dropout.
    lambda_short:
        Rate (1/m) of the short-reading exponential.
    endpoint:
        Whether the last beam sits at ``+fov/2`` (see ``fov``).
    name:
        Preset name, written to simulation metadata.
    """

    n_beams: int
    fov: float
    max_range: float
    min_range: float = 0.0
    sigma_hit: float = 0.0
    p_short: float = 0.0
    p_rand: float = 0.0
    p_max: float = 0.0
    lambda_short: float = 0.2
    endpoint: bool = True
    name: str = "custom"

    def __post_init__(self) -> None:
        if int(self.n_beams) != self.n_beams or self.n_beams < 1:
            raise ConfigError(f"n_beams must be a positive integer, got {self.n_beams}")
        if not 0.0 < self.fov <= 2.0 * math.pi + 1e-12:
            raise ConfigError(f"fov must be in (0, 2*pi] rad, got {self.fov}")
        if not (0.0 <= self.min_range < self.max_range and math.isfinite(self.max_range)):
            raise ConfigError(f"need 0 <= min_range < max_range < inf, got {self.min_range}, {self.max_range}")
        if self.sigma_hit < 0.0 or self.lambda_short < 0.0:
            raise ConfigError("sigma_hit and lambda_short must be >= 0")
        probs = (self.p_short, self.p_rand, self.p_max)
        if any(p < 0.0 for p in probs) or sum(probs) > 1.0 + 1e-12:
            raise ConfigError(f"p_short, p_rand, p_max must be >= 0 with sum <= 1, got {probs}")

    # ------------------------------------------------------------------ geometry
    @property
    def angle_increment(self) -> float:
        """Angle (rad) between consecutive beams."""
        if self.n_beams == 1:
            return 0.0
        return self.fov / (self.n_beams - 1 if self.endpoint else self.n_beams)

    @property
    def angle_min(self) -> float:
        """Angle (rad) of the first beam, relative to the heading."""
        return 0.0 if self.n_beams == 1 else -0.5 * self.fov

    @property
    def angles(self) -> NDArray[np.float64]:
        """Beam angles (rad) relative to the heading, ``(n_beams,)``, increasing."""
        return self.angle_min + np.arange(self.n_beams, dtype=np.float64) * self.angle_increment

    @property
    def p_hit(self) -> float:
        """Probability of the hit component."""
        return 1.0 - self.p_short - self.p_rand - self.p_max

    # ------------------------------------------------------------------ simulation
    def true_ranges(self, world: World, poses: ArrayLike, backend: str = "auto") -> NDArray[np.float64]:
        """Noise-free ranges ``(n, n_beams)``: ``inf`` where nothing is within ``max_range``."""
        return true_ranges(world, poses, self.angles, self.max_range, backend)

    def apply_noise(self, true: ArrayLike, rng: np.random.Generator) -> NDArray[np.float64]:
        """Turn true ranges ``(n, n_beams)`` (``inf`` = nothing) into readings with the mixture noise.

        Draws exactly ``4 * n * n_beams`` uniforms, scan by scan (row-major), so the readings of
        the first scans do not depend on how many scans are simulated.
        """
        d = np.asarray(true, dtype=np.float64)
        zmax = self.max_range
        below = np.nextafter(zmax, 0.0)  # largest value that still counts as a return
        u = rng.random(d.shape + (4,))
        nothing = ~(d < zmax)
        d_in = np.where(nothing, zmax, d)
        c1 = self.p_hit
        c2 = c1 + self.p_short
        c3 = c2 + self.p_rand
        comp = u[..., 0]
        # Hit: Box-Muller from two uniforms (1 - u lies in (0, 1], so the log is finite).
        normal = np.sqrt(-2.0 * np.log1p(-u[..., 1])) * np.cos(2.0 * math.pi * u[..., 2])
        hit = np.where(nothing, zmax, np.clip(d + self.sigma_hit * normal, 0.0, below))
        # Short: inverse CDF of the exponential truncated to [0, d_in).
        if self.lambda_short > 0.0:
            mass = -np.expm1(-self.lambda_short * d_in)
            short = -np.log1p(-u[..., 3] * mass) / self.lambda_short
        else:
            short = u[..., 3] * d_in
        short = np.minimum(short, np.where(d_in > 0.0, np.nextafter(d_in, 0.0), 0.0))
        rand = np.minimum(u[..., 3] * zmax, below)
        z = np.where(comp < c1, hit, np.where(comp < c2, short, np.where(comp < c3, rand, zmax)))
        return z

    def simulate_ranges(
        self, world: World, poses: ArrayLike, rng: np.random.Generator, backend: str = "auto"
    ) -> NDArray[np.float64]:
        """Simulated readings ``(n, n_beams)`` (m) for sensor poses ``(n, 3)``."""
        return self.apply_noise(self.true_ranges(world, poses, backend), rng)

    # ------------------------------------------------------------------ metadata
    def to_dict(self) -> dict[str, Any]:
        """Plain-data description (JSON-serialisable)."""
        return asdict(self)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> RangeSensor:
        """Inverse of :meth:`to_dict`."""
        return cls(**data)


def paper_lidar(max_range: float = 8.0) -> RangeSensor:
    """The paper's Museum lidar: 1079 beams over 270 deg, 8 m range, sigma_hit 1 cm, small outliers."""
    return RangeSensor(
        n_beams=1079,
        fov=math.radians(270.0),
        max_range=max_range,
        min_range=0.1,
        sigma_hit=0.01,
        p_short=0.01,
        p_rand=0.005,
        p_max=0.005,
        lambda_short=0.2,
        name="paper_lidar",
    )


def sick_lms200(max_range: float = 81.0) -> RangeSensor:
    """SICK LMS200 in the Intel/ACES layout: 180 beams at -90 deg + k deg (k = 0..179).

    The default maximum range is 81 m, the value the project's CARMEN reader assumes for FLASER
    scans (the format does not log it), so a simulated log is written as FLASER and its
    no-returns read back as such. Other ranges are written as ROBOTLASER1.
    """
    return RangeSensor(
        n_beams=180,
        fov=math.pi,
        max_range=max_range,
        min_range=0.0,
        sigma_hit=0.01,
        p_short=0.01,
        p_rand=0.005,
        p_max=0.005,
        lambda_short=0.2,
        endpoint=False,
        name="sick_lms200",
    )


def noiseless(
    n_beams: int = 1079, fov: float = math.radians(270.0), max_range: float = 8.0, endpoint: bool = True
) -> RangeSensor:
    """A sensor that returns the exact ray-cast ranges (no-return = ``max_range``)."""
    return RangeSensor(n_beams=n_beams, fov=fov, max_range=max_range, endpoint=endpoint, name="noiseless")
