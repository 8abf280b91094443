"""ROS 2 parameter files (``--params-file``) for crlam's nodes.

The layout is ROS 2's: ``NODE_NAME: {ros__parameters: {name: value, ...}}`` (``/**`` matches
every node). Names follow slam_toolbox and AMCL where the meaning is the same
(:data:`ROS_NAMES`: ``resolution``, ``max_laser_range``, ``minimum_travel_distance``, ...); every
other :class:`crlam.slam.SlamConfig` field is reachable under its own name (``particles``,
``seed``, ``mapping_model``...), and :data:`NODE_PARAMETERS` are the node's own settings. An
unknown name is an error naming the file and the parameter.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

from crlam.errors import ConfigError

__all__ = ["NODE_PARAMETERS", "ROS_NAMES", "NodeParameters", "load_params_file", "split_parameters"]

#: slam_toolbox / AMCL names of SlamConfig fields.
ROS_NAMES = {
    "resolution": "resolution",
    "max_laser_range": "max_range",
    "minimum_travel_distance": "linear_update",
    "minimum_travel_heading": "angular_update",
    "max_particles": "particles",
}


def _p(default: Any, help: str) -> Any:
    return dataclasses.field(default=default, metadata={"help": help})


@dataclasses.dataclass
class NodeParameters:
    """The node's own settings (the SLAM settings are a :class:`crlam.slam.SlamConfig`); each
    field's ``metadata["help"]`` says what it does (the documentation's parameter table)."""

    map_frame: str = _p("map", "the map's frame (the parent of the map -> odom transform)")
    odom_frame: str = _p("odom", "the odometry's frame (the child of map -> odom)")
    base_frame: str = _p("", "the robot's frame; empty: the child frame of the odometry messages")
    scan_topic: str = _p("/scan", "sensor_msgs/LaserScan input")
    scan_type: str = _p("LaserScan", "the scan topic's type: LaserScan or MultiEchoLaserScan")
    echo: str = _p("first", "the echo a MultiEchoLaserScan beam's range is taken from: first, last or strongest")
    odom_topic: str = _p("/odom", "nav_msgs/Odometry input, or /tf: odom_frame -> base_frame transforms")
    save_map_topic: str = _p("/crlam/save_map", "std_msgs/String: a folder to save to (empty: output_folder)")
    transform_publish_period: float = _p(0.05, "seconds between two map -> odom transforms (slam_toolbox's name)")
    map_update_interval: float = _p(5.0, "scan-time seconds between two /map messages (slam_toolbox's name)")
    use_sim_time: bool = _p(False, "stamp output with /clock instead of the wall clock")
    output_folder: str = _p("", "folder a save request without a folder, Ctrl-C and SIGTERM write (empty: no save on exit)")
    odom_tolerance: float = _p(0.25, "a scan stamped this long (s) outside the odometry still takes the nearest reading")
    max_scan_wait: float = _p(0.5, "wall seconds a scan waits for the odometry after its stamp (.inf: for ever)")
    odom_extrapolation: float = _p(
        0.2,
        "a scan stamped at most this long (s) after the newest odometry reading does not wait for the next one: its odometry "
        "is extrapolated at the odometry's velocity (0: wait, as crlam slam reads a bag; for a replay equal to the offline run)",
    )
    process_every_scan: bool = _p(
        False,
        "queue every matched scan instead of keeping the newest (bag replay in lock-step; live, the filter may fall behind)",
    )
    laser_mount: str = _p("", "the laser mount 'x y yaw' in the base frame (empty: from /tf_static)")
    preset: str = _p("robust", "the crlam preset the SLAM settings start from (crlam slam's --preset)")


NODE_PARAMETERS = tuple(f.name for f in dataclasses.fields(NodeParameters))


def load_params_file(path: str | os.PathLike[str], node_name: str) -> dict[str, Any]:
    """The parameters of ``node_name`` (and of ``/**``) in the ROS 2 parameter file ``path``."""
    import yaml

    p = Path(path)
    try:
        doc = yaml.safe_load(p.read_text())
    except OSError as exc:
        raise ConfigError(f"--params-file {p}: {exc.strerror or exc}") from exc
    except yaml.YAMLError as exc:
        raise ConfigError(f"--params-file {p}: not YAML ({exc})") from exc
    if not isinstance(doc, dict):
        raise ConfigError(f"--params-file {p}: expected 'NODE_NAME: ros__parameters: ...'")
    out: dict[str, Any] = {}
    for key in ("/**", node_name, "/" + node_name):
        section = doc.get(key)
        if section is None:
            continue
        if not isinstance(section, dict) or not isinstance(section.get("ros__parameters"), dict):
            raise ConfigError(f"--params-file {p}: {key}: expected a 'ros__parameters:' mapping")
        out.update(section["ros__parameters"])
    if not out and doc:
        raise ConfigError(f"--params-file {p}: no section for node {node_name!r} (nor /**); sections: {', '.join(map(str, doc))}")
    return out


def split_parameters(params: dict[str, Any], source: str) -> tuple[NodeParameters, dict[str, Any]]:
    """(the node's settings, SlamConfig overrides) of ``params``; an unknown name is an error."""
    from crlam.slam import SlamConfig

    slam_fields = {f.name for f in dataclasses.fields(SlamConfig)} - {"preset"}
    node: dict[str, Any] = {}
    slam: dict[str, Any] = {}
    for name, value in params.items():
        if name in NODE_PARAMETERS:
            node[name] = value
        elif name in ROS_NAMES:
            slam[ROS_NAMES[name]] = value
        elif name in slam_fields:
            slam[name] = list(value) if isinstance(value, list) else value
        else:
            raise ConfigError(
                f"{source}: unknown parameter {name!r} (node parameters: {', '.join(NODE_PARAMETERS)}; slam_toolbox names: "
                f"{', '.join(ROS_NAMES)}; or any crlam SLAM setting)"
            )
    for tup in ("lattice_step", "init_sigma", "mode_bandwidth", "motion_params"):
        if isinstance(slam.get(tup), list):
            slam[tup] = tuple(slam[tup])
    try:
        return NodeParameters(**node), slam
    except TypeError as exc:
        raise ConfigError(f"{source}: {exc}") from exc
