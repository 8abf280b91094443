"""A Foxglove WebSocket client for the live-view tests: connects on 127.0.0.1, subscribes to topics
and decodes the ROS 2 (CDR) messages it receives with rosbags."""

from __future__ import annotations

import json
import struct
from typing import Any

from rosbags.typesys import Stores, get_typestore

__all__ = ["FoxgloveClient"]

#: The Foxglove SDK's WebSocket subprotocol.
SUBPROTOCOL = "foxglove.sdk.v1"
#: Binary opcode of a message on a subscribed channel: op (1 byte), subscription id (u32), log time (u64), payload.
MESSAGE_DATA = 0x01


class FoxgloveClient:
    """A synchronous client of ``ws://127.0.0.1:PORT``; ``timeout`` (s) bounds every receive
    (a failure guard only: a test never waits for it to pass)."""

    def __init__(self, port: int, timeout: float = 60.0) -> None:
        from websockets.sync.client import connect

        self._connection = connect(f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], open_timeout=timeout, close_timeout=2)  # type: ignore[list-item]
        self.ws = self._connection.__enter__()
        self.timeout = timeout
        self.channels: dict[str, dict[str, Any]] = {}
        self.by_subscription: dict[int, dict[str, Any]] = {}
        self.typestore = get_typestore(Stores.ROS2_HUMBLE)

    def _control(self, msg: dict[str, Any]) -> None:
        if msg.get("op") == "advertise":
            for c in msg["channels"]:
                self.channels[c["topic"]] = c
        elif msg.get("op") == "unadvertise":
            for cid in msg["channelIds"]:
                self.channels = {t: c for t, c in self.channels.items() if c["id"] != cid}

    def subscribe(self, topics: list[str]) -> None:
        """Waits until every topic is advertised, then subscribes to them, in the order given."""
        while not all(t in self.channels for t in topics):
            frame = self.ws.recv(timeout=self.timeout)
            assert isinstance(frame, str), "binary data before any subscription"
            self._control(json.loads(frame))
        # One message per topic, in order: the server handles a client's messages in turn, so
        # the topics before the last are subscribed once the server sees the last one's
        # subscription (the commands' --foxglove-wait waits for /map: tests list it last).
        for topic in topics:
            sid = len(self.by_subscription) + 1
            self.by_subscription[sid] = self.channels[topic]
            sub = {"id": sid, "channelId": self.channels[topic]["id"]}
            self.ws.send(json.dumps({"op": "subscribe", "subscriptions": [sub]}))

    def receive(self) -> tuple[str, int, Any]:
        """The next message on a subscribed channel: (topic, log time ns, decoded ROS 2 message)."""
        while True:
            frame = self.ws.recv(timeout=self.timeout)
            if isinstance(frame, str):
                self._control(json.loads(frame))
                continue
            assert frame[0] == MESSAGE_DATA, frame[0]
            sid, log_time = struct.unpack_from("<IQ", frame, 1)
            channel = self.by_subscription[sid]
            assert channel["encoding"] == "cdr" and channel["schemaEncoding"] == "ros2msg"
            return channel["topic"], log_time, self.typestore.deserialize_cdr(bytes(frame[13:]), channel["schemaName"])

    def close(self) -> None:
        self._connection.__exit__(None, None, None)
