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


@dataclasses.dataclass
class NodeParameters:
    """The node's own settings (the SLAM settings are a :class:`crlam.slam.SlamConfig`)."""

    #: Frames (slam_toolbox's names and defaults).
    map_frame: str = "map"
    odom_frame: str = "odom"
    base_frame: str = ""  # "": the child frame of the odometry messages
    #: Topics.
    scan_topic: str = "/scan"
    odom_topic: str = "/odom"
    save_map_topic: str = "/crlam/save_map"
    #: Period (s) of the map -> odom transform (slam_toolbox: transform_publish_period).
    transform_publish_period: float = 0.05
    #: Scan time (s) between two /map messages (slam_toolbox: map_update_interval).
    map_update_interval: float = 5.0
    #: Stamp output with /clock instead of the wall clock.
    use_sim_time: bool = False
    #: Where a save request or Ctrl-C writes the run folder ("" : no save on exit).
    output_folder: str = ""
    #: A scan stamped this long (s) before the first or after the last odometry still takes the nearest one.
    odom_tolerance: float = 0.25
    #: Wall seconds a scan waits for the odometry after it before it is resolved with the newest.
    max_scan_wait: float = 0.5
    #: Queue every matched scan for the filter instead of keeping only the newest (replaying a bag
    #: in lock-step, where the node must see every scan; live, a slow filter then falls behind).
    process_every_scan: bool = False
    #: The laser mount "x y yaw" in the base frame; "" : from /tf_static.
    laser_mount: str = ""
    #: The named crlam preset the SLAM settings start from.
    preset: str = "robust"


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
