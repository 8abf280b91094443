"""A node's inputs on the live view (``--foxglove``): the scans the filter took, ``odom -> base_link`` at them."""

from __future__ import annotations

import threading
from typing import Any

from crlam.ros.odometry_buffer import PendingScan

__all__ = ["LiveViewMirror"]


class LiveViewMirror:
    """The input side of :class:`crlam.ros.slam_node.SlamNode`'s live view (its outputs go
    there from ``SlamNode._write``); each message is serialised only while a client listens."""

    live_view: Any
    write_lock: threading.Lock
    params: Any
    base_frame: str

    def _view_input(self, topic: str, msgtype: str, msg: Any, latched: bool = False) -> None:
        """Mirrors an input message (a scan, the laser mount) to the live view, if any listens."""
        view = self.live_view
        if view is not None and (latched or view.has_subscriber(topic, msgtype)):
            with self.write_lock:
                view.publish_cdr(topic, msgtype, msg.serialize(), latched=latched)

    def _view_scan(self, scan: PendingScan) -> None:
        """The live view's scan and ``odom -> base_link`` at its stamp (the odometry it was matched with)."""
        from crlam.ros.message_helpers import ros_messages, yaw_quaternion

        m = ros_messages()

        assert scan.odom is not None
        msg = scan.payload
        self._view_input("/scan", "sensor_msgs/msg/LaserScan", msg)
        o = scan.odom
        tr = m.TransformStamped(
            header=m.Header(stamp=msg.header.stamp, frame_id=self.params.odom_frame),  # type: ignore[attr-defined]
            child_frame_id=self.base_frame or "base_link",
            transform=m.Transform(
                translation=m.Vector3(x=float(o[0]), y=float(o[1]), z=0.0), rotation=yaw_quaternion(float(o[2]))
            ),
        )
        self._view_input("/tf", "tf2_msgs/msg/TFMessage", m.TFMessage(transforms=[tr]))

    def _view_static(self, static: list[tuple[tuple[str, str], Any]]) -> None:
        """The laser mount (every static transform known: ((parent, child), Transform)), latched."""
        from crlam.ros.message_helpers import ros_messages

        m = ros_messages()
        transforms = [
            m.TransformStamped(header=m.Header(frame_id=parent), child_frame_id=child, transform=tr)
            for (parent, child), tr in static
        ]
        self._view_input("/tf_static", "tf2_msgs/msg/TFMessage", m.TFMessage(transforms=transforms), latched=True)
