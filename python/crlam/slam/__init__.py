"""SLAM with Rao-Blackwellized particle filters: RBPF-CLAM (the paper's) and the RBPF-OGM baseline.

The users of the library import from here: :class:`SlamConfig` (every setting, with the paper's
defaults), :func:`make_filter` (the native filter of a config) and :class:`SlamRun` (feeds a
filter a stream of scans and keeps one pose per scan). The modules, from the ground floor up
(each imports only the ones before it):

- :mod:`crlam.slam.fill`, :mod:`crlam.slam.grid_alignment`, :mod:`crlam.slam.motion_noise`,
  :mod:`crlam.slam.preset_files`: pose maths and the log-fitted odometry noise, and the preset
  files read as the fields of a class they are given;
- :mod:`crlam.slam.prior`: the saved run a new one continues; :mod:`crlam.slam.config`: the
  settings;
- :mod:`crlam.slam.presets`: the named presets bound to SlamConfig; :mod:`crlam.slam.run`: the
  filter and its run;
- :mod:`crlam.slam.scan_odometry`: scan-matching odometry, a motion input from the scans;
- :mod:`crlam.slam.time_offset`: the laser-to-odometry time offset, estimated with it.

The checks of a log made before the filter runs (body beams, laser mount, map reach) are in
:mod:`crlam.preflight`; whole runs with their output folders in :mod:`crlam.experiments.slam_run`.
"""

from __future__ import annotations

from crlam.slam.config import (
    DEGENERACIES,
    FRONT_ENDS,
    MATCH_CLIMBS,
    MAX_MATCH_RANGE,
    MAX_TIME_OFFSET,
    TIME_OFFSET_CHOICES,
    Method,
    SlamConfig,
    valid_time_offset,
)
from crlam.slam.run import (
    ParticleSetRecord,
    SlamRun,
    SlamStep,
    make_filter,
    mode_seeking_pose,
    particle_spread,
)

__all__ = [
    "FRONT_ENDS",
    "MATCH_CLIMBS",
    "DEGENERACIES",
    "MAX_MATCH_RANGE",
    "MAX_TIME_OFFSET",
    "TIME_OFFSET_CHOICES",
    "Method",
    "valid_time_offset",
    "SlamConfig",
    "SlamStep",
    "SlamRun",
    "ParticleSetRecord",
    "particle_spread",
    "mode_seeking_pose",
    "make_filter",
]
