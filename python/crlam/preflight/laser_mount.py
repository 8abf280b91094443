"""The laser's mount estimated from the scans against the odometry (``--laser-mount auto``).

A laser turned on its mount, or mounted upside down, that the data does not describe makes the
scans move against the odometry: a yaw ψ turns every scan-to-scan translation by −ψ, and a laser
upside down sees the world mirrored, so it sees each turn of the robot with the opposite sign.

Method
------
Pairs
    Consecutive scans of the first scans with motion are paired so that the odometry moved at
    least 0.1 m or turned at least 0.1 rad between them, and at most 0.5 m and 0.5 rad.
Match
    Each pair is matched by point-to-point ICP (nearest neighbours within 0.5 m, then within
    0.2 m) in the laser frame as read, started at no translation and at each of the turns +Δθ,
    0 and −Δθ (Δθ the odometry's turn: its sign in the laser frame is what is unknown); the
    start whose match keeps the most points within 5 cm wins. A match with under half the
    points within 5 cm is left out.
Flip
    A laser mounted as the data says turns with the odometry: θ_laser ≈ θ_odom. Mirrored, it
    turns against it: θ_laser ≈ −θ_odom. Over the pairs that turned at least 3 deg, each votes
    for the sign that explains its turn better; the flip is decided when at least
    :data:`FLIP_MIN_PAIRS` (10) pairs voted and at least :data:`FLIP_AGREEMENT` (80 %) agree.
Yaw and offset
    With the laser pose the base pose composed with the mount (m, ψ), a pair's laser-frame
    translation t_L and the odometry's increment (t, φ) satisfy R(ψ) t_L = t + (R(φ) − I) m.
    ψ (Procrustes over the pairs, weighed by |t|) and m (linear least squares) are solved in
    turn, ten times. The yaw is decided when the pairs' directions agree: the mean resultant
    length of the angle between R(ψ) t_L and t + (R(φ) − I) m, weighed by |t|, is at least
    :data:`YAW_CONCENTRATION` (0.8) over at least 10 pairs and 1 m of travel. Mounts are built
    square: a yaw within :data:`SNAP` (5 deg) of a multiple of 90 deg is taken as that multiple.
    The offset m is estimated only when the turns make it observable (Σ(2 − 2 cos φ) ≥ 0.25, and
    a standard error of at most 5 cm); otherwise the data's offset (or none) is kept.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.spatial import cKDTree

__all__ = ["FLIP_AGREEMENT", "FLIP_MIN_PAIRS", "SNAP", "YAW_CONCENTRATION", "MountEstimate", "estimate_mount", "icp"]

FLIP_MIN_PAIRS = 10
FLIP_AGREEMENT = 0.8
YAW_CONCENTRATION = 0.8
SNAP = math.radians(5.0)
_MIN_STEP = (0.1, 0.1)
_MAX_STEP = (0.5, 0.5)
_MIN_TURN = math.radians(3.0)


def _rot(a: float) -> NDArray[np.float64]:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def icp(
    src: NDArray[np.float64], dst: NDArray[np.float64], turn0: float = 0.0, iterations: int = 30
) -> tuple[NDArray[np.float64], float]:
    """Point-to-point ICP of points ``src`` (k, 2) onto ``dst`` (m, 2), from (0, 0, ``turn0``).

    Returns (x, y, θ) with dst ≈ R(θ) src + (x, y), and the share of ``src`` within 5 cm of
    ``dst`` at the end."""
    tree = cKDTree(dst)
    a, t = turn0, np.zeros(2)
    it = 0
    while it < iterations:
        moved = src @ _rot(a).T + t
        dist, idx = tree.query(moved, distance_upper_bound=0.5 if it < iterations // 2 else 0.2)
        ok = np.isfinite(dist)
        if ok.sum() < 10:
            break
        p, q = src[ok], dst[idx[ok]]
        pc, qc = p.mean(axis=0), q.mean(axis=0)
        h = (p - pc).T @ (q - qc)
        a_next = math.atan2(h[0, 1] - h[1, 0], h[0, 0] + h[1, 1])
        t_next = qc - _rot(a_next) @ pc
        # A fixed point: the same pose gives the same matches, hence the same pose again, so the
        # remaining iterations of this search radius would repeat it bit for bit. Skip them (to
        # the second half's narrower radius, or to the end): the result is the 30 iterations'.
        fixed = a_next == a and np.array_equal(t_next, t)
        a, t = a_next, t_next
        if fixed:
            it = iterations // 2 if it < iterations // 2 else iterations
        else:
            it += 1
    dist, _ = tree.query(src @ _rot(a).T + t)
    return np.array([t[0], t[1], a]), float(np.mean(dist < 0.05))


@dataclass
class MountEstimate:
    """What :func:`estimate_mount` found, relative to the bearings as read.

    Attributes
    ----------
    flip : bool or None
        True when the bearings as read are mirrored (upside down against the data); None when
        undecided.
    yaw : float or None
        Mount yaw (rad) in the base frame, after the flip; None when undecided.
    yaw_continuous : float or None
        The yaw before snapping to a multiple of 90 deg (rad).
    offset : ndarray, shape (2,) or None
        Mount position (m) in the base frame; None when not observable.
    offset_std : float or None
        The standard error (m) of the offset's fit (also when it was not observable enough).
    offset_fit : ndarray, shape (2,) or None
        The fitted offset (m), kept or not.
    n_pairs, n_turning : int
        Matched pairs, and those that turned at least 3 deg.
    flip_agreement : float
        Share of the turning pairs that voted for the chosen sign.
    yaw_concentration : float
        Mean resultant length of the pairs' direction residuals (1: all agree).
    reason : str
        What was decided, or why not.
    """

    flip: bool | None
    yaw: float | None
    yaw_continuous: float | None
    offset: NDArray[np.float64] | None
    offset_std: float | None
    n_pairs: int
    n_turning: int
    flip_agreement: float
    yaw_concentration: float
    reason: str
    offset_fit: NDArray[np.float64] | None = None

    @property
    def decided(self) -> bool:
        return self.flip is not None and self.yaw is not None

    def record(self) -> dict[str, Any]:
        return {
            "decided": self.decided,
            "flip": self.flip,
            "yaw_deg": None if self.yaw is None else math.degrees(self.yaw),
            "yaw_continuous_deg": None if self.yaw_continuous is None else math.degrees(self.yaw_continuous),
            "offset_m": None if self.offset is None else [float(v) for v in self.offset],
            "offset_std_m": self.offset_std,
            "offset_fit_m": None if self.offset_fit is None else [float(v) for v in self.offset_fit],
            "n_pairs": self.n_pairs,
            "n_turning_pairs": self.n_turning,
            "flip_agreement": self.flip_agreement,
            "yaw_concentration": self.yaw_concentration,
            "reason": self.reason,
        }


def _points(bearings: NDArray[np.float64], ranges: NDArray[np.float64], max_range: float) -> NDArray[np.float64]:
    ok = np.isfinite(ranges) & (ranges > 0) & (ranges < min(max_range, 20.0))
    b, r = bearings[ok], ranges[ok]
    return np.column_stack([r * np.cos(b), r * np.sin(b)])


def _increment(a: NDArray[np.float64], b: NDArray[np.float64]) -> NDArray[np.float64]:
    d = b[:2] - a[:2]
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([c * d[0] + s * d[1], -s * d[0] + c * d[1], math.remainder(b[2] - a[2], math.tau)])


def estimate_mount(
    bearings: Sequence[NDArray[np.float64]],
    ranges: Sequence[NDArray[np.float64]],
    max_ranges: Sequence[float],
    odometry: NDArray[np.float64],
) -> MountEstimate:
    """Estimates the mount from scans (bearings and ranges as read, each (n,)) and the robot's
    odometry pose at each scan, (m, 3); see the module docstring."""
    odo = np.asarray(odometry, dtype=np.float64)
    pairs: list[tuple[NDArray[np.float64], NDArray[np.float64]]] = []  # (laser match, odometry increment)
    i = 0
    while i < len(ranges) - 1:
        j = i + 1
        while j < len(ranges):
            inc = _increment(odo[i], odo[j])
            if math.hypot(inc[0], inc[1]) >= _MIN_STEP[0] or abs(inc[2]) >= _MIN_STEP[1]:
                break
            j += 1
        if j >= len(ranges):
            break
        if math.hypot(inc[0], inc[1]) <= _MAX_STEP[0] and abs(inc[2]) <= _MAX_STEP[1]:
            src = _points(bearings[j], ranges[j], max_ranges[j])
            dst = _points(bearings[i], ranges[i], max_ranges[i])
            if len(src) >= 20 and len(dst) >= 20:
                best = max((icp(src, dst, t0) for t0 in {inc[2], 0.0, -inc[2]}), key=lambda m: m[1])
                if best[1] >= 0.5:
                    pairs.append((best[0], inc))
        i = j
    n = len(pairs)
    if n == 0:
        return MountEstimate(None, None, None, None, None, 0, 0, 0.0, 0.0, "no scan pairs matched (too little motion?)")
    lm = np.array([p[0] for p in pairs])
    od = np.array([p[1] for p in pairs])
    turning = np.abs(od[:, 2]) >= _MIN_TURN
    nt = int(turning.sum())
    same = np.abs(lm[turning, 2] - od[turning, 2]) < np.abs(lm[turning, 2] + od[turning, 2])
    agree_same = float(same.mean()) if nt else 0.0
    flip: bool | None = None
    agreement = max(agree_same, 1.0 - agree_same) if nt else 0.0
    if nt >= FLIP_MIN_PAIRS and agreement >= FLIP_AGREEMENT:
        flip = agree_same < 0.5
    if flip is None:
        why = f"{nt} turning pairs, {agreement:.0%} agree on the turn's sign (needs {FLIP_MIN_PAIRS} and {FLIP_AGREEMENT:.0%})"
        return MountEstimate(None, None, None, None, None, n, nt, agreement, 0.0, f"flip undecided: {why}")
    t_l = lm[:, :2] * (np.array([1.0, -1.0]) if flip else 1.0)
    t_b, phi = od[:, :2], od[:, 2]
    a_mats = np.array([_rot(p) - np.eye(2) for p in phi])  # (n, 2, 2)
    w = np.hypot(t_b[:, 0], t_b[:, 1])
    m = np.zeros(2)
    yaw = 0.0
    for _ in range(10):
        v = t_b + a_mats @ m
        cross = t_l[:, 0] * v[:, 1] - t_l[:, 1] * v[:, 0]
        dot = (t_l * v).sum(axis=1)
        yaw = math.atan2(float((w * cross).sum()), float((w * dot).sum()))
        rhs = t_l @ _rot(yaw).T - t_b
        m = np.linalg.lstsq(a_mats.reshape(-1, 2), rhs.reshape(-1), rcond=None)[0]
    v = t_b + a_mats @ m
    resid = np.angle(np.exp(1j * (np.arctan2(v[:, 1], v[:, 0]) - np.arctan2(t_l[:, 1], t_l[:, 0]) - yaw)))
    conc = float(abs((w * np.exp(1j * resid)).sum()) / max(w.sum(), 1e-12))
    if n < 10 or w.sum() < 1.0 or conc < YAW_CONCENTRATION:
        why = f"{n} pairs over {w.sum():.1f} m, direction agreement {conc:.2f} (needs 10 pairs, 1 m and {YAW_CONCENTRATION})"
        return MountEstimate(flip, None, None, None, None, n, nt, agreement, conc, f"yaw undecided: {why}")
    snapped = round(yaw / (math.pi / 2)) * (math.pi / 2)
    yaw_used = math.remainder(snapped if abs(yaw - snapped) <= SNAP else yaw, math.tau)
    # The offset with the yaw as used, and its standard error from the residuals.
    rhs = t_l @ _rot(yaw_used).T - t_b
    a_flat = a_mats.reshape(-1, 2)
    m, *_ = np.linalg.lstsq(a_flat, rhs.reshape(-1), rcond=None)
    info = float(np.sum(2.0 - 2.0 * np.cos(phi)))
    res = rhs.reshape(-1) - a_flat @ m
    sigma = float(np.sqrt(np.sum(res**2) / max(len(res) - 2, 1)))
    std = sigma / math.sqrt(info) if info > 0 else math.inf
    offset = m if info >= 0.25 and std <= 0.05 else None
    reason = f"flip {'yes' if flip else 'no'} ({agreement:.0%} of {nt} turning pairs), yaw {math.degrees(yaw_used):.1f} deg"
    fit = f"offset ({m[0]:.3f}, {m[1]:.3f}) m +- {std:.3f}"
    reason += f" (concentration {conc:.2f}), " + (fit if offset is not None else f"offset not observable ({fit})")
    return MountEstimate(flip, yaw_used, math.remainder(yaw, math.tau), offset, std, n, nt, agreement, conc, reason, offset_fit=m)
