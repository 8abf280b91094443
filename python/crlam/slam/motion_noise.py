"""Odometry noise estimated from a log's own scans: GMapping's motion-model parameters fitted to
how far the odometry increments stray from scan-matched increments.

A single-particle scan matcher (RBPF-OGM with one particle that keeps its match and starts each
climb at the odometry guess, GMapping's cells on a 0.05 m grid) runs over the log with the
filter's update triggers. At each processed scan k the odometry increment ``u_k`` (in the
previous robot frame) and the matched increment ``v_k`` give a residual ``r_k = v_k - u_k``
(heading wrapped). GMapping's model gives each residual component a standard deviation linear in
the increment (:func:`gmapping_sigmas`); with ``E|r| = sigma * sqrt(2/pi)`` for a normal residual
the four parameters follow from two non-negative least-squares fits of ``|r| * sqrt(pi/2)`` on
the increment's features: ``srr, str`` from the translational residuals, ``stt, srt`` from the
rotational ones. Steps whose residual is more than four fitted sigmas (a failed match, a wheel
slip) are left out and the fit repeated once. The scan matcher's own error (about a centimetre
and a few tenths of a degree per step) is part of the residual, so the estimate cannot go to
zero.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from statistics import NormalDist

import numpy as np
from numpy.typing import NDArray

from crlam import _native
from crlam.errors import DataFormatError
from crlam.io.carmen import LaserScan
from crlam.pose import between

__all__ = ["MotionNoiseEstimate", "estimate_gmapping_noise", "fit_gmapping_noise", "gmapping_sigmas"]

#: Fewer processed steps than this and the fit is refused (too little motion to tell noise apart).
MIN_STEPS = 20
#: Residuals beyond this many fitted standard deviations are outliers.
OUTLIER_SIGMAS = 4.0
#: GMapping's default parameters (srr, srt, str, stt), used where a fit has no data.
GMAPPING_DEFAULT = (0.1, 0.2, 0.1, 0.2)
#: Share of the log's residuals (outliers included) that the fitted normals must cover.
TAIL_COVERAGE = 0.95
#: Processed scans per map of the pre-pass's matcher.
WINDOW_STEPS = 200


@dataclass(frozen=True)
class MotionNoiseEstimate:
    """GMapping's motion-model parameters fitted to a log.

    Attributes
    ----------
    params : tuple of float
        ``(srr, srt, str, stt)``: standard deviations per metre or radian of the increment
        (``--motion gmapping --motion-params``).
    n_steps : int
        Processed steps with an increment.
    n_used : int
        Steps left after the outliers were dropped.
    fitted : bool
        False when the log had too few processed steps with motion (fewer than
        :data:`MIN_STEPS`) and ``params`` are :data:`GMAPPING_DEFAULT`.
    """

    params: tuple[float, float, float, float]
    n_steps: int
    n_used: int
    fitted: bool = True

    def describe(self) -> str:
        """One line saying what the run's odometry noise is and where it came from."""
        values = " ".join(f"{v:.3g}" for v in self.params)
        if not self.fitted:
            return (
                f"odometry noise: GMapping's defaults {values} (estimate: {self.n_steps} processed steps with motion, "
                f"at least {MIN_STEPS} needed)"
            )
        return f"odometry noise: srr srt str stt {values} fitted to {self.n_used} of {self.n_steps} steps (estimate)"

    def to_dict(self) -> dict[str, object]:
        return {"params": list(self.params), "n_steps": self.n_steps, "n_used": self.n_used, "fitted": self.fitted}


def gmapping_sigmas(params: tuple[float, float, float, float], u: NDArray[np.float64]) -> NDArray[np.float64]:
    """Standard deviations ``(k, 3)`` of GMapping's model for increments ``u`` ``(k, 3)`` (m, m, rad)."""
    srr, srt, str_, stt = params
    ax, ay, at = np.abs(u[:, 0]), np.abs(u[:, 1]), np.abs(u[:, 2])
    return np.stack(
        [
            srr * ax + str_ * at + 0.3 * srr * ay,
            srr * ay + str_ * at + 0.3 * srr * ax,
            stt * at + srt * np.hypot(u[:, 0], u[:, 1]),
        ],
        axis=1,
    )


def _nnls2(features: NDArray[np.float64], target: NDArray[np.float64]) -> NDArray[np.float64]:
    """Least squares ``target ~ features @ c`` with ``c >= 0`` for two columns (exact: the best of
    the unconstrained solution and the two one-column fits)."""
    best, best_cost = np.zeros(2), float(np.sum(target**2))
    candidates: list[NDArray[np.float64]] = []
    sol, *_ = np.linalg.lstsq(features, target, rcond=None)
    candidates.append(np.asarray(sol, dtype=np.float64))
    for j in range(2):
        col = features[:, j]
        denom = float(col @ col)
        c = np.zeros(2)
        if denom > 0:
            c[j] = max(0.0, float(col @ target) / denom)
        candidates.append(c)
    for c in candidates:
        if np.all(c >= 0):
            cost = float(np.sum((features @ c - target) ** 2))
            if cost < best_cost:
                best, best_cost = c, cost
    return best


def fit_gmapping_noise(u: NDArray[np.float64], r: NDArray[np.float64]) -> MotionNoiseEstimate:
    """Fits ``(srr, srt, str, stt)`` to odometry increments ``u`` ``(k, 3)`` and residuals ``r`` ``(k, 3)``
    (matched minus odometry increment, heading wrapped); see the module documentation."""
    u = np.asarray(u, dtype=np.float64).reshape(-1, 3)
    r = np.asarray(r, dtype=np.float64).reshape(-1, 3)
    moving = np.hypot(u[:, 0], u[:, 1]) + np.abs(u[:, 2]) > 1e-6
    u, r = u[moving], r[moving]
    if len(u) < MIN_STEPS:
        raise DataFormatError(f"{len(u)} processed steps with motion; the odometry noise needs at least {MIN_STEPS}")
    scale = math.sqrt(math.pi / 2)
    keep = np.ones(len(u), dtype=bool)
    params = GMAPPING_DEFAULT
    for _ in range(2):
        uk, rk = u[keep], r[keep]
        ax, ay, at = np.abs(uk[:, 0]), np.abs(uk[:, 1]), np.abs(uk[:, 2])
        # Translation: |rx| ~ srr (|ux| + 0.3 |uy|) + str |ut|, and the same for y.
        feat_t = np.concatenate([np.stack([ax + 0.3 * ay, at], 1), np.stack([ay + 0.3 * ax, at], 1)])
        targ_t = scale * np.concatenate([np.abs(rk[:, 0]), np.abs(rk[:, 1])])
        srr, str_ = _nnls2(feat_t, targ_t)
        # Rotation: |rt| ~ stt |ut| + srt |u_xy|.
        feat_r = np.stack([at, np.hypot(uk[:, 0], uk[:, 1])], 1)
        stt, srt = _nnls2(feat_r, scale * np.abs(rk[:, 2]))
        params = (float(srr), float(srt), float(str_), float(stt))
        sig = gmapping_sigmas(params, u)
        with np.errstate(divide="ignore", invalid="ignore"):
            z = np.abs(r) / np.where(sig > 0, sig, np.inf)
        keep = np.all(z <= OUTLIER_SIGMAS, axis=1)
        if keep.sum() < MIN_STEPS:
            keep = np.ones(len(u), dtype=bool)
            break
    params = _cover_the_tail(params, u, r)
    return MotionNoiseEstimate(params, n_steps=len(u), n_used=int(keep.sum()))


def _cover_the_tail(
    params: tuple[float, float, float, float], u: NDArray[np.float64], r: NDArray[np.float64]
) -> tuple[float, float, float, float]:
    """``params`` scaled up (never down) until :data:`TAIL_COVERAGE` of the residuals ``r`` of all
    steps, outliers included, lie within the normal's central interval of that probability:
    ``srr, str`` by the translational residuals, ``stt, srt`` by the rotational ones."""
    z_target = NormalDist().inv_cdf(0.5 + TAIL_COVERAGE / 2)
    sig = gmapping_sigmas(params, u)
    with np.errstate(divide="ignore", invalid="ignore"):
        z = np.abs(r) / np.where(sig > 0, sig, np.inf)
    z = np.where(np.isnan(z), 0.0, z)  # 0 / 0: no motion in that component, no residual
    scale_t = max(1.0, float(np.quantile(z[:, :2].ravel(), TAIL_COVERAGE)) / z_target)
    scale_r = max(1.0, float(np.quantile(z[:, 2], TAIL_COVERAGE)) / z_target)
    srr, srt, str_, stt = params
    return (srr * scale_t, srt * scale_r, str_ * scale_t, stt * scale_r)


def estimate_gmapping_noise(
    scans: Iterable[object],
    *,
    linear_update: float,
    angular_update: float,
    max_range: float,
    max_scans: int | None = None,
    seed: int = 0,
) -> MotionNoiseEstimate:
    """GMapping's motion-model parameters for a log (see the module documentation).

    Parameters
    ----------
    scans : iterable
        The log's records (``crlam.io.open_log``); laser scans are used, other records skipped.
    linear_update, angular_update : float
        The filter's update triggers (m, rad): the residuals are taken over the same steps.
    max_range : float
        Usable range of the matcher's map (m).
    max_scans : int, optional
        Stop after this many scans.
    seed : int
        Seed of the matcher's motion draws.
    """
    matcher: _native.OgmFilter | None = None
    odoms: list[NDArray[np.float64]] = []
    poses: list[NDArray[np.float64]] = []
    n = 0
    n_window = 0
    for rec in scans:
        if not isinstance(rec, LaserScan):
            continue
        if max_scans is not None and n >= max_scans:
            break
        n += 1
        odom = np.asarray(rec.odom, dtype=np.float64)
        if matcher is not None and n_window >= WINDOW_STEPS:
            # A fresh map every WINDOW_STEPS processed scans bounds the map (a long log's whole
            # map at 0.05 m exceeds the cell limit) and its drift; the pair across the restart
            # is not a residual.
            matcher, n_window = None, 0
            odoms.append(np.full(3, np.nan))
            poses.append(np.full(3, np.nan))
        if matcher is None:
            matcher = _native.OgmFilter(
                odom,
                n_particles=1,
                resolution=0.05,
                usable_range=max_range,
                motion="gmapping",
                # Next to no noise: every match starts from the odometry guess itself, so what it
                # corrects is the odometry's error, not a draw's.
                motion_params=[1e-6, 1e-6, 1e-6, 1e-6],
                linear_update=linear_update,
                angular_update=angular_update,
                proposal_pose="match",
                map_model="gmapping",
                motion_draws="per_update",
                seed=seed,
            )
        ranges = np.where(rec.ranges >= rec.max_range, np.inf, rec.ranges)
        processed, estimate, _, _ = matcher.process(
            odom, np.ascontiguousarray(rec.angles), np.ascontiguousarray(ranges), np.asarray(rec.laser_offset, dtype=np.float64)
        )
        if processed:
            n_window += 1
            odoms.append(odom)
            poses.append(np.asarray(estimate, dtype=np.float64))
    o, p = np.array(odoms).reshape(-1, 3), np.array(poses).reshape(-1, 3)
    u = np.array([between(o[k - 1], o[k]) for k in range(1, len(o))]).reshape(-1, 3)
    v = np.array([between(p[k - 1], p[k]) for k in range(1, len(p))]).reshape(-1, 3)
    r = v - u
    r[:, 2] = (r[:, 2] + math.pi) % (2 * math.pi) - math.pi
    whole = np.all(np.isfinite(u), axis=1) & np.all(np.isfinite(v), axis=1)
    u, r = u[whole].reshape(-1, 3), r[whole].reshape(-1, 3)
    moving = int(np.count_nonzero(np.hypot(u[:, 0], u[:, 1]) + np.abs(u[:, 2]) > 1e-6))
    if moving < MIN_STEPS:
        # Too little motion to tell the noise apart: GMapping's defaults, and the run says so.
        return MotionNoiseEstimate(GMAPPING_DEFAULT, n_steps=moving, n_used=0, fitted=False)
    return fit_gmapping_noise(u, r)
