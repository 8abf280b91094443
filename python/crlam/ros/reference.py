"""The topic and parameter reference of crlam's ROS 2 nodes, as Markdown, from the code itself
(the documentation's hook puts it into ``docs/tutorials/ros2.md``; needs no DDS library)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence

__all__ = ["ros_reference"]


def _table(header: tuple[str, ...], rows: Sequence[tuple[str, ...]]) -> str:
    lines = ["| " + " | ".join(header) + " |", "| " + " | ".join("---" for _ in header) + " |"]
    lines += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in rows]
    return "\n".join(lines)


def ros_reference() -> str:
    """Markdown: the nodes' topics, their parameters and the slam_toolbox / AMCL names."""
    from crlam.experiments.explore import ExploreConfig
    from crlam.experiments.explore_live_view import TOPICS as EXPLORE_VIEW_TOPICS
    from crlam.experiments.slam_live_view import TOPICS as OFFLINE_VIEW_TOPICS
    from crlam.localize import LocalizeConfig
    from crlam.ros.explore_node import EXPLORE_TOPICS
    from crlam.ros.localize_node import AMCL_NAMES, LOCALIZE_TOPICS
    from crlam.ros.params import ROS_NAMES, NodeParameters
    from crlam.ros.save_map_service import SERVICES
    from crlam.ros.slam_node import SLAM_TOPICS
    from crlam.slam import SlamConfig

    out = ["### Topics of `crlam ros slam`", ""]
    out.append(
        _table(
            ("topic", "type", "in/out", "QoS", "what"),
            [tuple(f"`{c}`" if i < 2 else c for i, c in enumerate(r)) for r in SLAM_TOPICS],
        )
    )
    out += ["", "### Topics of `crlam ros localize` (besides those above, less `/map_confidence`)", ""]
    out.append(
        _table(
            ("topic", "type", "in/out", "QoS", "what"),
            [tuple(f"`{c}`" if i < 2 else c for i, c in enumerate(r)) for r in LOCALIZE_TOPICS],
        )
    )
    out += ["", "### Topics of `crlam ros explore` (besides those of `crlam ros slam`)", ""]
    out.append(
        _table(
            ("topic", "type", "in/out", "QoS", "what"),
            [tuple(f"`{c}`" if i < 2 else c for i, c in enumerate(r)) for r in EXPLORE_TOPICS],
        )
    )
    out += ["", "### Services (every node; `<node>`: `crlam_slam`, `crlam_localize`, `crlam_explore`)", ""]
    out.append(
        _table(
            ("service", "type", "DDS topics", "what"),
            [tuple(f"`{c}`" if i < 3 else c for i, c in enumerate(r)) for r in SERVICES],
        )
    )
    out += ["", "### Live view (`--foxglove`): the Foxglove WebSocket's topics", ""]
    node_view = ", ".join(f"`{t}`" for t, _, io, _, _ in SLAM_TOPICS + EXPLORE_TOPICS if io == "out")
    out.append(
        f"The nodes serve every output topic ({node_view}), latched where DDS has it transient local, and the inputs "
        "the filter used: `/scan` (each scan it took), `/tf` `odom -> base_link` at those scans, `/tf_static`. "
        "`crlam slam` and `crlam localize` serve:"
    )
    out += [""]
    out.append(_table(("topic", "type"), [(f"`{t}`", f"`{ty}`") for t, ty in OFFLINE_VIEW_TOPICS.items()]))
    out += ["", "`crlam explore` (a simulated exploration; stamps: 0.1 s of simulated time per scan) serves:", ""]
    out.append(_table(("topic", "type"), [(f"`{t}`", f"`{ty}`") for t, ty in EXPLORE_VIEW_TOPICS.items()]))
    out += ["", "### Node parameters (every node)", ""]
    rows = [(f"`{f.name}`", f"`{f.default!r}`", f.metadata.get("help", "")) for f in dataclasses.fields(NodeParameters)]
    out.append(_table(("parameter", "default", "what"), rows))
    out += ["", "### slam_toolbox names (`crlam ros slam`)", ""]
    out.append(_table(("parameter", "crlam setting"), [(f"`{k}`", f"`{v}`") for k, v in ROS_NAMES.items()]))
    slam_fields = ", ".join(f"`{f.name}`" for f in dataclasses.fields(SlamConfig) if f.name != "preset")
    out += ["", f"Every other SLAM setting under its own name (see `crlam slam --help`): {slam_fields}.", ""]
    out += ["### AMCL names (`crlam ros localize`)", ""]
    out.append(_table(("parameter", "crlam setting"), [(f"`{k}`", f"`{v}`") for k, v in AMCL_NAMES.items()]))
    loc_fields = ", ".join(f"`{f.name}`" for f in dataclasses.fields(LocalizeConfig))
    out += [
        "",
        "Also `nav2_free_thresh`, `nav2_occupied`, `nav2_free` (how a Nav2 map is read), `initial_pose` "
        f"(`[x, y, theta]`), `initial_cov`, and every localization setting under its own name: {loc_fields}.",
    ]
    exp_fields = ", ".join(f"`explore_{f.name}`" for f in dataclasses.fields(ExploreConfig))
    out += ["", f"`crlam ros explore` takes the SLAM node's parameters and the exploration settings: {exp_fields}."]
    return "\n".join(out) + "\n"
