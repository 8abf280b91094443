"""The CRM scan likelihood along the corridor: how the weight ranks poses the scan cannot tell apart.

    python results/corridor/probe_likelihood.py LOG SCAN [SCAN ...]

Runs the filter with the scan read in every direction (the `robust` preset with
`degeneracy = "off"`; its odometry noise fitted to the log first, as `crlam slam` does) up to
each SCAN, then evaluates the CRM predictive log-likelihood of that scan, on the best particle's
map, at poses moved along the robot's heading from the odometry's guess (the best particle's pose
composed with the odometry increment). In a featureless corridor the walls do not change along
it, so any slope is the map's own: cells seen more often (behind the robot) are more confident.
"""

from __future__ import annotations

import sys
from dataclasses import replace

import numpy as np

from crlam import _native
from crlam.io import open_log
from crlam.io.carmen import LaserScan
from crlam.pose import between, compose
from crlam.slam import SlamConfig, SlamRun
from crlam.slam.motion_noise import estimate_gmapping_noise

OFFSETS = np.round(np.arange(-0.3, 0.301, 0.05), 2)


def main(log: str, stops: list[int]) -> None:
    config = SlamConfig.from_preset("robust")
    noise = estimate_gmapping_noise(
        open_log(log), linear_update=config.linear_update, angular_update=config.angular_update, max_range=config.max_range
    )
    config = replace(
        config, motion_noise="model", motion_params=noise.params, map_range="fixed", time_offset="off", degeneracy="off"
    )
    run = SlamRun(config)
    weight_model = config.mapping_config().sensor_model(config.weight_model)
    print("scan | " + " | ".join(f"{d + 0.0:+.2f} m" for d in OFFSETS))
    scans = (r for r in open_log(log) if isinstance(r, LaserScan))
    for i, rec in enumerate(scans):
        if i > max(stops):
            break
        if i in stops and isinstance(run.filter, _native.ClamFilter):
            poses, weights = run.filter.weighed_set()
            best = np.asarray(poses)[int(np.argmax(weights))]
            guess = np.asarray(compose(best, between(run.odometry[-1], run._to_map_frame(np.asarray(rec.odom)))))
            lidar = np.asarray(compose(guess, rec.laser_offset))
            lls = []
            for d in OFFSETS:
                pose = lidar + np.array([d * np.cos(guess[2]), d * np.sin(guess[2]), 0.0])
                ll, _ = run.filter.best_map().scan_log_likelihood(pose, rec.angles, rec.ranges, weight_model)
                lls.append(ll)
            ref = lls[list(OFFSETS).index(0.0)]
            print(f"{i} | " + " | ".join(f"{ll - ref:+.0f}" for ll in lls))
        run.step(rec.odom, rec.angles, rec.ranges, rec.laser_offset, rec.timestamp)


if __name__ == "__main__":
    main(sys.argv[1], [int(s) for s in sys.argv[2:]])
