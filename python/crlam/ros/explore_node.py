"""``crlam ros explore``: ``crlam ros slam`` that also chooses where to go next.

After each ``/map`` update the node takes an exploration decision on the map built so far
(:func:`crlam.ros.explore_goal.choose_goal`: CRMI, or UCRMI with the filter's particles) and
publishes the goal as ``geometry_msgs/PoseStamped`` on ``/goal_pose`` (what Nav2's
``bt_navigator`` takes, as RViz's "Goal Pose" tool sends it), facing from the robot to the goal,
and the candidates with their scores as a ``visualization_msgs/MarkerArray`` on
``/explore/candidates`` (spheres coloured from low, blue, to high, red; the goal larger).
Exploration settings are :class:`crlam.experiments.explore.ExploreConfig` fields in the
parameter file under ``explore_<name>`` (``explore_function: ucrmi``, ``explore_radius_m: 5.0``).
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from crlam.ros.params import NodeParameters
from crlam.ros.slam_node import SlamNode, pose_msg, ros_messages, ros_stamp

__all__ = ["EXPLORE_TOPICS", "ExploreNode", "split_explore_parameters"]

EXPLORE_TOPICS = (
    ("/goal_pose", "geometry_msgs/msg/PoseStamped", "out", "reliable", "the next goal (Nav2's bt_navigator)"),
    ("/explore/candidates", "visualization_msgs/msg/MarkerArray", "out", "reliable", "candidate goals coloured by score"),
)


def split_explore_parameters(params: dict[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """(the ``explore_*`` parameters as ExploreConfig fields, the others)."""
    explore = {k[len("explore_") :]: v for k, v in params.items() if k.startswith("explore_")}
    rest = {k: v for k, v in params.items() if not k.startswith("explore_")}
    return explore, rest


class ExploreNode(SlamNode):
    """The exploration node (see the module docstring)."""

    NODE_NAME = "crlam_explore"

    def __init__(
        self,
        node: NodeParameters,
        slam_overrides: dict[str, Any],
        explore_settings: dict[str, Any],
        *,
        domain: int | None = None,
        dds_config: str = "loopback",
    ) -> None:
        from crlam.errors import ConfigError
        from crlam.experiments.explore import ExploreConfig

        super().__init__(node, slam_overrides, domain=domain, dds_config=dds_config)
        try:
            self.explore = ExploreConfig(**explore_settings)
        except TypeError as exc:
            names = ", ".join(f"explore_{f.name}" for f in dataclasses.fields(ExploreConfig))
            raise ConfigError(f"exploration parameters: {exc} (known: {names})") from exc
        if self.explore.function not in ("crmi", "ucrmi"):
            raise ConfigError(f"explore_function must be crmi or ucrmi, got {self.explore.function!r}")
        self.decisions: list[Any] = []

    def start(self) -> None:
        from crlam.ros import qos

        m = ros_messages()
        super().start()
        self.w_goal = self.dds.writer("/goal_pose", m.PoseStamped, qos.reliable())
        self.w_candidates = self.dds.writer("/explore/candidates", m.MarkerArray, qos.reliable())

    def _publish_map(self, t: float) -> None:
        super()._publish_map(t)
        self._decide(t)

    def _decide(self, t: float) -> None:
        from crlam.mapping import ConfidenceRichMap

        best_map = self.run.best_map()
        if not isinstance(best_map, ConfidenceRichMap):
            return  # RBPF-OGM has no confidence-rich map to score
        estimate = np.asarray(self.run.estimates[-1], dtype=np.float64)
        belief = None
        if self.explore.function == "ucrmi":
            from crlam.experiments.explore import _filter_belief

            belief = _filter_belief(self.run.filter)
        from crlam.ros.explore_goal import choose_goal

        d = choose_goal(best_map, estimate, self.explore, self.explore.seed + len(self.decisions), belief)
        self.decisions.append(d)
        self._publish_decision(t, estimate, d)

    def _publish_decision(self, t: float, estimate: np.ndarray, d: Any) -> None:
        m = ros_messages()
        header = m.Header(stamp=ros_stamp(t), frame_id=self.params.map_frame)
        markers = [m.Marker(header=header, ns="candidates", id=0, action=3)]  # DELETEALL first
        if len(d.scores):
            s = np.asarray(d.scores, dtype=np.float64)
            lo, hi = float(np.min(s)), float(np.max(s))
            span = hi - lo if hi > lo else 1.0
            for i, (c, v) in enumerate(zip(d.candidates, s)):
                a = (float(v) - lo) / span
                size = 0.3 if i == d.best else 0.12
                markers.append(
                    m.Marker(
                        header=header,
                        ns="candidates",
                        id=i + 1,
                        type=2,  # SPHERE
                        action=0,
                        pose=pose_msg(np.array([c[0], c[1], 0.0])),
                        scale=m.Vector3(x=size, y=size, z=size),
                        color=m.ColorRGBA(r=a, g=0.2, b=1.0 - a, a=1.0),
                        text=f"{float(v):.4g}",
                    )
                )
        self._write(self.w_candidates, m.MarkerArray(markers=markers))
        if d.best >= 0:
            g = d.candidates[d.best]
            heading = math.atan2(g[1] - estimate[1], g[0] - estimate[0])
            self._write(self.w_goal, m.PoseStamped(header=header, pose=pose_msg(np.array([g[0], g[1], heading]))))

    def _extra_diagnostics(self) -> dict[str, object]:
        last = self.decisions[-1] if self.decisions else None
        return super()._extra_diagnostics() | {
            "decisions": len(self.decisions),
            "explore_stop": "" if last is None or last.stop is None else last.stop,
        }
