"""``crlam ros play``: a ROS 1 bag, a ROS 2 bag or an MCAP file published onto DDS as ROS 2 topics.

Every topic whose type :mod:`crlam.ros.messages` knows is published under its own name with the
QoS ROS 2 drivers use for it (:func:`crlam.ros.qos.qos_for_topic`; a topic a ROS 2 bag
recorded as transient local stays so); the others are counted and named in the summary.
Messages go out in the bag's order, spaced by their recording times divided by ``rate``;
``clock`` publishes ``/clock`` (rosgraph_msgs/Clock, the bag time) before each message, for
nodes with ``use_sim_time``.

**Lock-step** (``lockstep=True``): before each laser scan, the player waits until the node
under test reports (``/diagnostics``, :data:`crlam.ros.slam_node.DIAGNOSTIC_NAME`) that it has
settled (filtered, or dropped for want of odometry) every scan it could match with the odometry
sent so far (those stamped at or before the newest odometry), and at the end that it has
received every scan and odometry message: the node then sees each scan with the same odometry as an offline run, at
whatever speed the machine has, so a test's outcome does not depend on timing.
"""

from __future__ import annotations

import math
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from crlam.errors import ConfigError, CrlamError, DataFormatError

__all__ = ["PlayStats", "play_bag"]

#: Message types that are laser scans (what lock-step counts).
SCAN_TYPES = ("sensor_msgs/msg/LaserScan", "sensor_msgs/msg/MultiEchoLaserScan")


@dataclass
class PlayStats:
    """What :func:`play_bag` published: messages per topic, the topics it could not publish."""

    published: dict[str, int] = field(default_factory=dict)
    skipped_topics: dict[str, str] = field(default_factory=dict)
    clock_messages: int = 0
    wall_time_s: float = 0.0


class _NodeProgress:
    """The node's counters from ``/diagnostics``, with a condition to wait on."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.values: dict[str, int] = {}

    def update(self, sample: Any) -> None:
        from crlam.ros.slam_node import DIAGNOSTIC_NAME

        for status in sample.status:
            if status.hardware_id != "crlam" or not status.name.endswith(DIAGNOSTIC_NAME):
                continue
            with self.cond:
                for kv in status.values:
                    if kv.value.lstrip("-").isdigit():
                        self.values[kv.key] = max(self.values.get(kv.key, 0), int(kv.value))
                self.cond.notify_all()

    def wait(self, need: dict[str, int], timeout: float) -> None:
        """Waits until every counter of ``need`` reaches its value; a node silent for ``timeout``
        s is an error (it died or is on another domain), never a decision about the data."""
        with self.cond:
            seen = dict(self.values)
            deadline = time.monotonic() + timeout
            while not all(self.values.get(k, 0) >= v for k, v in need.items()):
                if self.values != seen:  # progress: the node is alive and working
                    seen, deadline = dict(self.values), time.monotonic() + timeout
                left = deadline - time.monotonic()
                if left <= 0:
                    raise CrlamError(f"lock-step: the node did not report {need} within {timeout:.0f} s (has {self.values})")
                self.cond.wait(left)


def _stamp(t: Any) -> float:
    return float(t.sec) + float(t.nanosec) * 1e-9


def _wait_matched(writers: dict[str, Any], topics: list[str], timeout: float) -> None:
    """Waits until each writer of ``topics`` has a matched reader (discovery on loopback takes a
    moment; messages written before would be lost to a volatile reader)."""
    deadline = time.monotonic() + timeout
    for topic in topics:
        w = writers.get(topic)
        if w is None:
            continue
        while w.get_publication_matched_status().current_count < 1:
            if time.monotonic() > deadline:
                raise CrlamError(f"no subscriber of {topic} appeared within {timeout:.0f} s")
            time.sleep(0.01)  # polling discovery; the outcome does not depend on how long it takes


def play_bag(
    path: str | os.PathLike[str],
    *,
    rate: float = 1.0,
    clock: bool = False,
    topics: list[str] | None = None,
    lockstep: bool = False,
    wait_for: list[str] | None = None,
    domain: int | None = None,
    dds_config: str = "loopback",
    timeout: float = 60.0,
    duration: float | None = None,
    on_message: Callable[[str, int], None] | None = None,
) -> PlayStats:
    """Publishes the bag at ``path`` onto DDS (see the module docstring).

    Parameters
    ----------
    rate : float
        Playback speed (2: twice as fast); ``math.inf`` publishes as fast as possible.
    topics : list of str, optional
        Only these topics (default: every topic of a known type).
    lockstep : bool
        Wait for the node's progress before each scan (implies waiting for the subscribers of
        the scan, odometry and transform topics first).
    wait_for : list of str, optional
        Topics whose subscriber must be matched before the first message.
    timeout : float
        Seconds to wait for a subscriber or for the node's progress before giving up (an error).
    duration : float, optional
        Stop after this many seconds of bag time.
    """
    if not (rate > 0):
        raise ConfigError(f"--rate must be > 0, got {rate}")
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    from crlam.ros import messages, qos
    from crlam.ros.dds import DdsNode

    bag = Path(path)
    if not bag.exists():
        raise DataFormatError("no such bag", path=str(bag))
    stats = PlayStats()
    node = DdsNode("crlam_play", domain=domain, dds_config=dds_config)
    progress = _NodeProgress()
    if lockstep:
        node.reader("/diagnostics", messages.DiagnosticArray, qos.reliable(50), progress.update)
    t_start = time.monotonic()
    try:
        reader_cm = AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_HUMBLE))
        with reader_cm as reader:
            writers: dict[str, Any] = {}
            conns = []
            for c in reader.connections:
                if topics is not None and c.topic not in topics:
                    continue
                if c.msgtype not in messages.ROS_TYPES:
                    stats.skipped_topics[c.topic] = f"type {c.msgtype} is not one crlam publishes"
                    continue
                if c.topic not in writers:
                    latched = any(
                        getattr(getattr(q, "durability", None), "value", None) == 1
                        for q in getattr(c.ext, "offered_qos_profiles", []) or []
                    )
                    writers[c.topic] = node.writer(c.topic, messages.ROS_TYPES[c.msgtype], qos.qos_for_topic(c.topic, latched))
                conns.append(c)
            clock_writer = node.writer("/clock", messages.Clock, qos.reliable(1)) if clock else None
            scan_topics = sorted({c.topic for c in conns if c.msgtype in SCAN_TYPES})
            odom_topics = sorted({c.topic for c in conns if c.msgtype == "nav_msgs/msg/Odometry"})
            # Without an Odometry topic a node takes its odometry from /tf: lock-step follows /tf then.
            odom_types = ("nav_msgs/msg/Odometry",) if odom_topics else ("tf2_msgs/msg/TFMessage",)
            tf_topics = ("/tf", "tf")
            must_match = list(wait_for or [])
            if lockstep:
                must_match += [t for t in (*scan_topics, *odom_topics, "/tf", "/tf_static") if t in writers]
            _wait_matched(writers, must_match, timeout)
            if lockstep:
                progress.wait({"ready": 1}, timeout)
            first_t: int | None = None
            n_scans = n_odom = 0
            scan_stamps: list[float] = []
            odom_until = -math.inf
            for conn, t_ns, raw in reader.messages(connections=conns):
                if first_t is None:
                    first_t = t_ns
                if duration is not None and (t_ns - first_t) * 1e-9 > duration:
                    break
                if math.isfinite(rate):
                    due = t_start + (t_ns - first_t) * 1e-9 / rate
                    delay = due - time.monotonic()
                    if delay > 0:
                        time.sleep(delay)  # pacing the playback; never deciding an outcome
                msg = messages.from_object(reader.deserialize(raw, conn.msgtype), messages.ROS_TYPES[conn.msgtype])
                if lockstep and conn.msgtype in SCAN_TYPES:
                    # Every scan the node can match by now (stamped before the newest odometry sent) is settled.
                    progress.wait({"scans_settled": sum(t <= odom_until for t in scan_stamps)}, timeout)
                    scan_stamps.append(_stamp(msg.header.stamp))
                elif conn.msgtype in odom_types and (odom_topics or conn.topic in tf_topics):
                    stamps = [msg.header.stamp] if odom_topics else [tr.header.stamp for tr in msg.transforms]
                    odom_until = max([odom_until, *(_stamp(t) for t in stamps)])
                if clock_writer is not None:
                    sec, nsec = divmod(int(t_ns), 1_000_000_000)
                    clock_writer.write(messages.Clock(clock=messages.Time(sec=sec, nanosec=nsec)))
                    stats.clock_messages += 1
                writers[conn.topic].write(msg)
                stats.published[conn.topic] = stats.published.get(conn.topic, 0) + 1
                n_scans += conn.msgtype in SCAN_TYPES
                n_odom += conn.msgtype in odom_types and bool(odom_topics or conn.topic in tf_topics)
                if on_message is not None:
                    on_message(conn.topic, t_ns)
            if lockstep:
                settled = sum(t <= odom_until for t in scan_stamps)
                progress.wait({"scans_received": n_scans, "odometry_received": n_odom, "scans_settled": settled}, timeout)
    except CrlamError:
        raise
    except Exception as exc:
        from rosbags.highlevel import AnyReaderError

        if isinstance(exc, AnyReaderError):
            raise DataFormatError(f"unreadable ROS bag ({exc})", path=str(bag)) from exc
        raise
    finally:
        stats.wall_time_s = time.monotonic() - t_start
        node.close()
    return stats
