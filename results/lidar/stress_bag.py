"""A lidar stress variant of a ROS bag, and crlam slam on it with and without the lidar checks.

    python results/lidar/stress_bag.py BAG OUT_DIR [--seed 0] [--mount X Y YAW] [--no-returns 0.1]

Writes ``OUT_DIR/stress.mcap``: the bag's scans and odometry with

* the laser upside down (every scan mirrored: the range at bearing b is the one at -b),
* the mount hidden (the scans' frame is one that no transform links to the base); with
  ``--mount X Y YAW`` the laser sits at that pose in the base frame: the odometry written is
  that of a base from which the bag's laser pose is reached through that mount (the bag's own
  mount composed with the inverse of the new one),
* a share of the readings (``--no-returns``, 10 %), drawn at random, replaced by ``+inf``,
* 5 % of the beams (three sectors) reading the robot's body: 0.155 m +- 5 mm in every scan,

then runs ``crlam slam`` (``robust`` preset, seed 0) on the original bag (``OUT_DIR/original``),
on the stress bag (``OUT_DIR/stress``, the lidar checks on: the default) and on the stress bag
with them off (``OUT_DIR/stress_unchecked``: ``no_return = "z_max"``, ``body_mask = "off"``,
``--laser-mount data``), and prints the trajectories' differences from the original run's after
an SE(2) alignment (RMSE of positions, m) and what metrics.json reports under ``input.lidar``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from crlam.experiments.slam_run import run_slam_log
from crlam.io.rosbag_writer import McapBagWriter
from crlam.io.tum import read_tum
from crlam.pose import compose
from crlam.slam import SlamConfig

BODY_SECTORS = ((0.30, 0.317), (0.55, 0.567), (0.80, 0.817))  # fractions of the beams: 5 % in all


def _inverse(p: np.ndarray) -> np.ndarray:
    c, s = math.cos(p[2]), math.sin(p[2])
    return np.array([-(c * p[0] + s * p[1]), -(-s * p[0] + c * p[1]), -p[2]])


def write_stress_bag(
    bag: Path, out: Path, seed: int, mount: list[float] | None = None, no_returns: float = 0.10
) -> np.ndarray | None:
    """Writes the stress bag; returns the shift of the base frame (base' = base o shift), or None."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from crlam.io.rosbag import RosbagReader

    reader0 = RosbagReader(bag)
    next(iter(reader0))
    stated = np.asarray(reader0.stats.laser_offset, dtype=np.float64)
    # base' = base o stated o mount^-1: the laser's pose is base' o mount, as in the bag.
    shift = None if mount is None else np.asarray(compose(stated, _inverse(np.asarray(mount, dtype=np.float64))))
    rng = np.random.default_rng(seed)
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader, McapBagWriter(out) as w:
        scan_conns = [c for c in reader.connections if c.msgtype == "sensor_msgs/msg/LaserScan"]
        odom_conns = [c for c in reader.connections if c.msgtype == "nav_msgs/msg/Odometry"]
        for conn, t_ns, raw in reader.messages(connections=scan_conns + odom_conns):
            msg = reader.deserialize(raw, conn.msgtype)
            t = msg.header.stamp.sec + msg.header.stamp.nanosec * 1e-9
            if conn.msgtype == "nav_msgs/msg/Odometry":
                p, q = msg.pose.pose.position, msg.pose.pose.orientation
                yaw = math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))
                pose = np.array([p.x, p.y, yaw])
                if shift is not None:
                    pose = np.asarray(compose(pose, shift))
                w.write("/odom", conn.msgtype, t_ns, w.odometry(t, "odom", "base_link", pose))
                continue
            r = np.asarray(msg.ranges, dtype=np.float64)[::-1].copy()  # mirrored: upside down
            n, inc = len(r), float(msg.angle_increment)
            amin = -(float(msg.angle_min) + inc * (n - 1))
            r[rng.random(n) < no_returns] = np.inf
            for lo, hi in BODY_SECTORS:
                k = np.arange(int(lo * n), int(hi * n))
                r[k] = 0.155 + rng.uniform(-0.005, 0.005, k.size)
            scan = w.laser_scan(t, "hidden_laser", r, amin, inc, float(msg.range_max))
            w.write("/scan", conn.msgtype, t_ns, scan)
    return shift


def aligned_rmse(a: np.ndarray, b: np.ndarray) -> float:
    """Position RMSE (m) of ``a`` (n, 2) against ``b`` after the rigid motion that fits them best."""
    ca, cb = a.mean(axis=0), b.mean(axis=0)
    h = (a - ca).T @ (b - cb)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    rot = vt.T @ np.diag([1.0, d]) @ u.T
    return float(np.sqrt(np.mean(np.sum(((a - ca) @ rot.T - (b - cb)) ** 2, axis=1))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("bag", type=Path)
    ap.add_argument("out", type=Path)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--mount", type=float, nargs=3, default=None, metavar=("X", "Y", "YAW"))
    ap.add_argument("--no-returns", type=float, default=0.10, help="share of the readings replaced by +inf")
    args = ap.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    stress = args.out / "stress.mcap"
    shift = write_stress_bag(args.bag, stress, args.seed, args.mount, args.no_returns)
    runs = {
        "original": (args.bag, SlamConfig.from_preset("robust"), "auto"),
        "stress": (stress, SlamConfig.from_preset("robust"), "auto"),
        "stress_unchecked": (stress, SlamConfig.from_preset("robust", no_return="z_max", body_mask="off"), "data"),
    }
    traj = {}
    for name, (log, cfg, mount) in runs.items():
        res = run_slam_log(log, args.out / name, cfg, progress=False, laser_mount=mount)
        poses = read_tum(args.out / name / "trajectory.tum").poses
        if shift is not None and name != "original":
            # Back to the bag's own base frame, to compare with the original run.
            back = _inverse(shift)
            poses = np.array([compose(p, back) for p in poses])
        traj[name] = poses
        lidar = res.metrics["input"]["lidar"]
        est = lidar.get("mount_estimate") or {}
        print(
            f"{name}: mount used {lidar.get('mount_used')}; estimate {est.get('reason')}; body beams "
            f"{(lidar.get('body_mask') or {}).get('n_masked')}; readings {json.dumps(lidar.get('readings'))}"
        )
    for name in ("stress", "stress_unchecked"):
        n = min(len(traj[name]), len(traj["original"]))
        print(
            f"{name}: trajectory RMSE against the original run {aligned_rmse(traj[name][:n, :2], traj['original'][:n, :2]):.3f} m"
        )


if __name__ == "__main__":
    main()
