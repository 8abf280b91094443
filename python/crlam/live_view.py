"""``--foxglove [PORT]``: a run served live on a Foxglove WebSocket (``crlam[live]``, the ``foxglove-sdk`` package).

The server speaks the Foxglove WebSocket protocol (what Foxglove's "Open connection ->
Foxglove WebSocket" opens). Every channel carries **ROS 2 messages**: message encoding ``cdr``,
schema encoding ``ros2msg`` with the ROS 2 message definition, the same bytes a ROS 2 node puts
on DDS. Foxglove shows them as it shows a ROS 2 robot's topics (``/map`` as a map in the 3D panel,
``/scan``, ``/particles``, ``/path``, ``/pose`` and ``/tf``), so a view of an offline run, of a
live node and of ``run.mcap`` looks the same.

**Network.** The server binds to 127.0.0.1 unless given another host (``--foxglove-host``):
only programs on the same machine can connect. Port 0 picks a free port (the command prints it).

**Never blocking.** :meth:`LiveView.publish` serialises the message and queues it for each
client; a client that reads too slowly loses its *oldest* queued messages (the SDK's message
backlog, :data:`BACKLOG` messages per client), it never makes the caller wait.
"""

from __future__ import annotations

import threading
from typing import Any

from crlam.errors import ConfigError

__all__ = ["BACKLOG", "DEFAULT_PORT", "LiveView", "need_foxglove", "ros_type_name"]

#: Foxglove's usual WebSocket port.
DEFAULT_PORT = 8765
#: Messages queued per client before its oldest are dropped (maps are the large ones: a few per second).
BACKLOG = 256


def need_foxglove() -> None:
    """Raises a :class:`~crlam.errors.ConfigError` naming the extra when ``foxglove-sdk`` is missing."""
    try:
        import foxglove  # noqa: F401
    except ImportError:
        raise ConfigError("--foxglove needs the foxglove-sdk package: pip install 'crlam[live]'") from None


def ros_type_name(dds_type_name: str) -> str:
    """``nav_msgs::msg::dds_::OccupancyGrid_`` -> ``nav_msgs/msg/OccupancyGrid``."""
    parts = [p for p in dds_type_name.split("::") if p != "dds_"]
    if parts and parts[-1].endswith("_"):
        parts[-1] = parts[-1][:-1]
    return "/".join(parts)


class _Subscriptions:
    """A foxglove ServerListener that counts each topic's subscribers (and wakes waiters); a
    client that disconnects is unsubscribed from everything. ``fresh`` lists the topics a client
    has just subscribed to (their latched message is sent again)."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.topics: dict[str, int] = {}
        self.fresh: list[str] = []

    def on_subscribe(self, client: Any, channel: Any) -> None:
        # The server's own thread: only note it (logging from here could wait on the server).
        with self.cond:
            self.topics[channel.topic] = self.topics.get(channel.topic, 0) + 1
            self.fresh.append(channel.topic)
            self.cond.notify_all()

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        with self.cond:
            self.topics[channel.topic] = max(self.topics.get(channel.topic, 0) - 1, 0)
            self.cond.notify_all()


class LiveView:
    """A Foxglove WebSocket server of ROS 2 messages.

    Parameters
    ----------
    port : int
        TCP port; 0 picks a free one (:attr:`port` says which).
    host : str
        Address to bind; 127.0.0.1 (default) serves this machine only, 0.0.0.0 every interface.
    name : str
        The server's name, shown by Foxglove.
    """

    def __init__(self, port: int = DEFAULT_PORT, host: str = "127.0.0.1", name: str = "crlam") -> None:
        need_foxglove()
        import foxglove
        from rosbags.typesys import Stores, get_typestore

        self.typestore = get_typestore(Stores.ROS2_HUMBLE)
        #: ROS 2 message classes by type name (``nav_msgs/msg/OccupancyGrid``), to build messages with.
        self.types: dict[str, Any] = self.typestore.types
        self.context = foxglove.Context()
        self.subscriptions = _Subscriptions()
        try:
            self.server = foxglove.start_server(
                name=name,
                host=host,
                port=int(port),
                context=self.context,
                server_listener=self.subscriptions,  # type: ignore[arg-type]
                message_backlog_size=BACKLOG,
            )
        except Exception as exc:  # the SDK raises its own error types for a port in use, a bad host...
            raise ConfigError(f"--foxglove: cannot serve on {host}:{port}: {exc}") from exc
        self.host = host
        self.port: int = int(self.server.port)
        self._channels: dict[str, tuple[str, Any]] = {}
        self._lock = threading.Lock()
        self.counts: dict[str, int] = {}
        self._latched: dict[str, tuple[str, bytes, int | None]] = {}
        self._closed = False
        self._republisher = threading.Thread(target=self._republish, name="crlam-foxglove-latch", daemon=True)
        self._republisher.start()

    @property
    def url(self) -> str:
        """The address to open in Foxglove."""
        return f"ws://{self.host}:{self.port}"

    def _channel(self, topic: str, msgtype: str) -> Any:
        import foxglove

        with self._lock:
            got = self._channels.get(topic)
            if got is None:
                text, _ = self.typestore.generate_msgdef(msgtype, ros_version=2)
                schema = foxglove.Schema(name=msgtype, encoding="ros2msg", data=text.encode())
                channel = foxglove.Channel(topic, message_encoding="cdr", schema=schema, context=self.context)
                got = self._channels[topic] = (msgtype, channel)
            elif got[0] != msgtype:
                raise ConfigError(f"live view: topic {topic} carries {got[0]}, not {msgtype}")
            return got[1]

    def publish_cdr(self, topic: str, msgtype: str, data: bytes, t_ns: int | None = None, *, latched: bool = False) -> None:
        """Queues the CDR bytes ``data`` (with their 4-byte encapsulation header) of a ``msgtype``
        message on ``topic``; ``t_ns``: the log time (ns since the epoch; default now).
        ``latched`` (``/map``, ``/tf_static``: transient local on DDS) keeps the message and sends
        it again whenever a client subscribes to the topic, as a late RViz gets a latched map."""
        channel = self._channel(topic, msgtype)
        data = bytes(data)
        if latched:
            with self._lock:
                self._latched[topic] = (msgtype, data, t_ns)
        channel.log(data, log_time=t_ns)
        with self._lock:
            self.counts[topic] = self.counts.get(topic, 0) + 1

    def publish(self, topic: str, msgtype: str, msg: Any, t_ns: int | None = None, *, latched: bool = False) -> None:
        """Serialises ``msg`` (built from :attr:`types`) and queues it on ``topic``."""
        if not (latched or self.has_subscriber(topic, msgtype)):
            return  # nobody listens: skip the serialisation
        self.publish_cdr(topic, msgtype, bytes(self.typestore.serialize_cdr(msg, msgtype)), t_ns, latched=latched)

    def republish(self, topic: str) -> bool:
        """Sends ``topic``'s latched message again (False if it has none)."""
        with self._lock:
            got = self._latched.get(topic)
            channel = self._channels.get(topic)
        if got is None or channel is None:
            return False
        channel[1].log(got[1], log_time=got[2])
        return True

    def has_subscriber(self, topic: str, msgtype: str) -> bool:
        """Whether a client subscribes to ``topic`` (advertised as ``msgtype`` from now on)."""
        return bool(self._channel(topic, msgtype).has_sinks())

    def _republish(self) -> None:
        """Sends the latched message of each newly subscribed topic again (its own thread)."""
        cond = self.subscriptions.cond
        while True:
            with cond:
                while not self.subscriptions.fresh and not self._closed:
                    cond.wait()
                if self._closed:
                    return
                topics, self.subscriptions.fresh = self.subscriptions.fresh, []
            for topic in dict.fromkeys(topics):
                with self._lock:
                    got = self._latched.get(topic)
                    channel = self._channels.get(topic)
                if got is not None and channel is not None:
                    channel[1].log(got[1], log_time=got[2])

    def wants(self, topic: str) -> bool:
        """Whether a client subscribes to ``topic`` now (expensive messages are made only then)."""
        with self.subscriptions.cond:
            return self.subscriptions.topics.get(topic, 0) > 0

    def wait_for_subscriber(self, topic: str, timeout: float | None = None) -> bool:
        """Blocks until a client subscribes to ``topic`` (a channel must be announced first:
        :meth:`announce`); False after ``timeout`` seconds without one."""
        with self.subscriptions.cond:
            return self.subscriptions.cond.wait_for(lambda: self.subscriptions.topics.get(topic, 0) > 0, timeout)

    def wait_until_unsubscribed(self, stop: threading.Event | None = None) -> None:
        """Blocks until no client subscribes to anything (they left), or ``stop`` is set."""
        cond = self.subscriptions.cond
        with cond:
            while any(self.subscriptions.topics.values()) and not (stop is not None and stop.is_set()):
                cond.wait(0.5)  # re-checks ``stop`` (set by a signal handler, which cannot notify)

    def announce(self, topics: dict[str, str]) -> None:
        """Advertises ``topics`` (topic -> ROS 2 type) before their first message, so that a
        client can subscribe to them at once."""
        for topic, msgtype in topics.items():
            self._channel(topic, msgtype)

    def close(self) -> None:
        """Stops the server (queued messages not yet sent are dropped)."""
        with self.subscriptions.cond:
            self._closed = True
            self.subscriptions.cond.notify_all()
        self._republisher.join()
        with self._lock:
            for _, channel in self._channels.values():
                channel.close()
            self._channels.clear()
        self.server.stop()
