"""File formats of crlam: CARMEN logs, ROS bags, TUM trajectories, Nav2 maps, relations, belief archives.

Pure Python + numpy. Readers raise :class:`crlam.errors.DataFormatError` naming the file, the
line and the field of malformed input. Grids follow the project convention: ``[iy, ix]`` with
``iy = 0`` at the minimum y, origin at the lower-left corner of cell ``[0, 0]``.
"""

from __future__ import annotations

from crlam.io.belief import BeliefArchive, load_belief, save_belief
from crlam.io.carmen import (
    DEFAULT_FLASER_MAX_RANGE,
    CarmenLog,
    CarmenReader,
    CarmenRecord,
    CarmenStats,
    LaserScan,
    OdometryReading,
    flaser_geometry,
    load_log,
    open_binary,
    read_carmen,
    read_scans,
)
from crlam.io.carmen_types import ImuReading
from crlam.io.carmen_writer import CarmenWriter, write_carmen
from crlam.io.datasets import (
    DATASETS,
    Dataset,
    DatasetNotFoundError,
    data_root,
    dataset_path,
)
from crlam.io.logs import open_log, read_records, read_scans_any
from crlam.io.nav2 import (
    Nav2Map,
    read_image,
    read_nav2_map,
    read_pgm,
    write_nav2_map,
    write_pgm,
)
from crlam.io.relations import Relations, read_relations, write_relations
from crlam.io.rosbag import BagStats, RosbagReader, is_bag, read_bag
from crlam.io.tum import Trajectory, read_tum, write_tum

__all__ = [
    "DATASETS",
    "DEFAULT_FLASER_MAX_RANGE",
    "BagStats",
    "BeliefArchive",
    "CarmenLog",
    "CarmenReader",
    "CarmenRecord",
    "CarmenStats",
    "CarmenWriter",
    "Dataset",
    "DatasetNotFoundError",
    "ImuReading",
    "LaserScan",
    "Nav2Map",
    "OdometryReading",
    "Relations",
    "RosbagReader",
    "Trajectory",
    "data_root",
    "dataset_path",
    "flaser_geometry",
    "is_bag",
    "load_belief",
    "load_log",
    "open_binary",
    "open_log",
    "read_bag",
    "read_carmen",
    "read_image",
    "read_nav2_map",
    "read_pgm",
    "read_records",
    "read_relations",
    "read_scans",
    "read_scans_any",
    "read_tum",
    "save_belief",
    "write_carmen",
    "write_nav2_map",
    "write_pgm",
    "write_relations",
    "write_tum",
]
