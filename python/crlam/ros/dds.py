"""The DDS side of crlam's nodes: one Cyclone DDS participant, its configuration, ROS 2 topic names.

**Network.** Unless told otherwise, crlam's participants run on the loopback interface only
(:data:`LOOPBACK_CONFIG`: interface ``lo``, multicast off, unicast discovery of peers on
127.0.0.1), so trying crlam, its tests and ``crlam ros play`` never send a packet off the
machine. crlam passes that configuration to Cyclone DDS as ``CYCLONEDDS_URI`` of its own
process. On a robot whose other nodes run on other machines, pass ``--dds-config env`` to
use the ``CYCLONEDDS_URI`` of the environment as it is (Cyclone's own defaults when unset: every
interface, multicast discovery), or ``--dds-config FILE.xml`` for a configuration file of your
own (see the tutorial "crlam on a ROS 2 robot"). (Cyclone DDS opens its unicast receive
sockets on the wildcard address; with this configuration it advertises only 127.0.0.1 locators,
discovers peers only there and sends nothing elsewhere.)

**Naming.** ROS 2 puts topic ``/scan`` on the DDS topic ``rt/scan``, with the type name
``sensor_msgs::msg::dds_::LaserScan_`` (:mod:`crlam.ros.messages`); the domain is
``ROS_DOMAIN_ID`` (default 0).
"""

from __future__ import annotations

import os
import queue
import sys
import threading
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from crlam.errors import ConfigError

__all__ = ["LOOPBACK_CONFIG", "DdsNode", "configure_dds", "dds_topic_name", "domain_id"]

#: Cyclone DDS on the loopback interface only: no multicast, peers found by unicast on 127.0.0.1
#: (participant indices 0..MaxAutoParticipantIndex give each participant its own port).
LOOPBACK_CONFIG = (
    '<CycloneDDS><Domain Id="any">'
    '<General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
    "<AllowMulticast>false</AllowMulticast></General>"
    "<Discovery><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>60</MaxAutoParticipantIndex>"
    '<Peers><Peer address="127.0.0.1"/></Peers></Discovery>'
    "</Domain></CycloneDDS>"
)

_configured: str | None = None
_lock = threading.Lock()


def configure_dds(choice: str = "loopback") -> str:
    """Sets ``CYCLONEDDS_URI`` of this process for ``choice``: ``loopback`` (default,
    :data:`LOOPBACK_CONFIG`), ``env`` (the environment's value, untouched) or the path of a
    Cyclone DDS XML file. Returns a description. Must be called before the first participant:
    Cyclone reads its configuration once per process, so a second, different choice is an error."""
    global _configured
    with _lock:
        if choice == "loopback":
            os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG
            described = "loopback (lo, 127.0.0.1, no multicast)"
        elif choice == "env":
            described = f"CYCLONEDDS_URI={os.environ.get('CYCLONEDDS_URI', '(unset: Cyclone defaults)')}"
        else:
            path = Path(choice)
            if not path.is_file():
                raise ConfigError(f"--dds-config {choice}: no such file (loopback, env or a Cyclone DDS XML file)")
            os.environ["CYCLONEDDS_URI"] = path.resolve().as_uri()
            described = f"file {path}"
        if _configured is not None and _configured != choice:
            raise ConfigError(f"DDS already configured as {_configured!r} in this process; cannot switch to {choice!r}")
        _configured = choice
        return described


def domain_id(value: int | None = None) -> int:
    """The DDS domain: ``value``, else ``ROS_DOMAIN_ID``, else 0 (checked to be 0..232)."""
    if value is None:
        text = os.environ.get("ROS_DOMAIN_ID", "").strip() or "0"
        try:
            value = int(text)
        except ValueError:
            raise ConfigError(f"ROS_DOMAIN_ID={text!r} is not an integer") from None
    if not 0 <= value <= 232:
        raise ConfigError(f"ROS domain id {value} is outside 0..232")
    return value


def dds_topic_name(topic: str) -> str:
    """ROS 2's DDS topic for ``topic``: ``/scan`` -> ``rt/scan``."""
    name = topic.strip()
    if not name.startswith("/"):
        name = "/" + name
    return "rt" + name


class DdsNode:
    """One participant with ROS 2 topic naming: :meth:`writer` and :meth:`reader` by ROS topic
    name and message class; readers can call a function for each sample (on Cyclone's thread:
    it must only hand the sample over, never compute).

    Parameters
    ----------
    name : str
        The node's name (in the participant's entity name, as ROS 2 shows it).
    domain : int, optional
        DDS domain (default ``ROS_DOMAIN_ID`` or 0).
    dds_config : str
        ``loopback`` (default), ``env`` or an XML file: see :func:`configure_dds`.
    """

    def __init__(self, name: str, domain: int | None = None, dds_config: str = "loopback") -> None:
        self.config_description = configure_dds(dds_config)
        from cyclonedds.core import Policy, Qos
        from cyclonedds.domain import DomainParticipant

        self.name = name
        self.domain = domain_id(domain)
        self.participant: Any = DomainParticipant(self.domain, qos=Qos(Policy.EntityName(name)))
        self._topics: dict[str, Any] = {}
        self._entities: list[Any] = []
        #: Each writer's (ROS topic, ROS type name ``pkg/msg/Type``, transient local), by ``id(writer)``.
        self.writer_topics: dict[int, tuple[str, str, bool]] = {}
        #: Called with (ROS topic, ROS type name) of each new writer (the live view advertises it).
        self.on_new_writer: Callable[[str, str], None] | None = None
        # Samples go from Cyclone's listeners to one dispatcher thread, which calls the readers'
        # callbacks. A listener runs in the thread that delivers the sample, for a reader of the
        # same process the writer's own thread, inside Cyclone's write: a callback that waited
        # there for a lock of the node (held by a thread that is itself writing) deadlocked the
        # two writes. Queued, a listener only takes the samples and returns.
        self._inbox: queue.SimpleQueue[tuple[Callable[[Any], None], Any] | None] = queue.SimpleQueue()
        self._dispatcher: threading.Thread | None = None
        self._delivery = threading.Condition()
        self._queued = self._delivered = 0

    def _topic(self, topic: str, cls: type, raw: bool = False) -> Any:
        from cyclonedds.topic import Topic

        dds = topic if raw else dds_topic_name(topic)
        if dds not in self._topics:
            self._topics[dds] = Topic(self.participant, dds, cls)
        return self._topics[dds]

    def writer(self, topic: str, cls: type, qos: Any, *, raw: bool = False) -> Any:
        """A DataWriter of ``cls`` on ROS topic ``topic`` (``raw``: ``topic`` is the DDS topic's
        own name, such as a service's ``rr/NODE/SERVICEReply``)."""
        from cyclonedds.core import Policy
        from cyclonedds.pub import DataWriter

        from crlam.live_view import ros_type_name

        w = DataWriter(self.participant, self._topic(topic, cls, raw), qos=qos)
        self._entities.append(w)
        if raw:
            return w
        msgtype = ros_type_name(cls.__idl_typename__)  # type: ignore[attr-defined]
        self.writer_topics[id(w)] = (topic, msgtype, Policy.Durability.TransientLocal in qos)
        if self.on_new_writer is not None:
            self.on_new_writer(topic, msgtype)
        return w

    def reader(
        self, topic: str, cls: type, qos: Any, on_sample: Callable[[Any], None] | None = None, *, raw: bool = False
    ) -> Any:
        """A DataReader of ``cls`` on ROS topic ``topic`` (``raw``: the DDS topic's own name);
        ``on_sample`` is called with each sample."""
        from cyclonedds.core import Listener
        from cyclonedds.sub import DataReader

        r = DataReader(self.participant, self._topic(topic, cls, raw), qos=qos)
        self._entities.append(r)
        if on_sample is not None:
            self._start_dispatcher()
            lock = threading.Lock()  # the drain below and Cyclone's thread never interleave samples

            def available(_: Any = None) -> None:
                with lock:
                    while samples := r.take(N=64):
                        for sample in samples:
                            info = getattr(sample, "sample_info", None)
                            if info is None or info.valid_data:
                                with self._delivery:
                                    self._queued += 1
                                self._inbox.put((on_sample, sample))

            # The listener is set once the reader exists (a transient-local sample can arrive while
            # it is being made, before Cyclone can name it); what came before is drained here.
            r.set_listener(Listener(on_data_available=available))
            available()
        return r

    def _start_dispatcher(self) -> None:
        if self._dispatcher is None:
            self._dispatcher = threading.Thread(target=self._dispatch, name=f"{self.name}-dds-dispatch", daemon=True)
            self._dispatcher.start()

    def _dispatch(self) -> None:
        """Calls each queued sample's callback in arrival order until :meth:`close`."""
        while (item := self._inbox.get()) is not None:
            on_sample, sample = item
            try:
                on_sample(sample)
            except Exception:  # a callback's bug must not stop every other topic's samples
                print(f"crlam: a DDS callback of {self.name} failed:\n{traceback.format_exc()}", file=sys.stderr, flush=True)
            finally:
                with self._delivery:
                    self._delivered += 1
                    self._delivery.notify_all()

    def wait_delivered(self) -> None:
        """Returns once every sample taken so far has been handed to its callback (call it
        without holding a lock that a callback takes)."""
        if self._dispatcher is None or threading.current_thread() is self._dispatcher:
            return
        with self._delivery:
            target = self._queued
            while self._delivered < target and self._dispatcher is not None:
                self._delivery.wait(0.5)

    def close(self) -> None:
        """Deletes the participant (and with it every reader and writer). Listeners are removed
        first: deleting a reader whose listener is set crashes the binding (a use after free in
        Cyclone DDS Python 11) when another participant of the process uses the same type. The
        samples already taken are handed to their callbacks before this returns (unless a
        callback itself closes the node)."""
        from cyclonedds.sub import DataReader

        for e in self._entities:
            if isinstance(e, DataReader):
                e.set_listener(None)
        if self._dispatcher is not None:
            self._inbox.put(None)
            if threading.current_thread() is not self._dispatcher:
                self._dispatcher.join()
            self._dispatcher = None
        self._entities.clear()
        self._topics.clear()
        self.participant = None
