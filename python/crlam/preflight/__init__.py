"""What a run learns from a log's own readings before its filter runs (``crlam slam``, ``crlam localize``).

Each module reads the log's own scans (and odometry) and none reads the filters' modules, so
the SLAM and localization runs build on them:

- :mod:`crlam.preflight.body_mask`: the beams that read the robot's own body;
- :mod:`crlam.preflight.laser_mount`: the laser's mount estimated against the odometry;
- :mod:`crlam.preflight.lidar_check`: both applied to the first scans of a log (``--laser-mount``,
  ``body_mask``);
- :mod:`crlam.preflight.map_range`: the map's reach chosen from the log's readings;
- :mod:`crlam.preflight.odometry_retime`: each scan's odometry re-attached at its corrected stamp
  (the time offset itself is estimated by :mod:`crlam.slam.time_offset`, which needs
  scan-matching odometry).
"""
