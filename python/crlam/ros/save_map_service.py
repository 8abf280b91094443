"""The nodes' ``/<node>/save_map`` service: slam_toolbox/srv/SaveMap over DDS request/reply (:mod:`crlam.ros.services`)."""

from __future__ import annotations

import threading
from collections import deque
from typing import Any

__all__ = ["SERVICES", "SaveMapService"]

#: (service, ROS 2 type, DDS topics, what) of every node (the documentation's service table).
SERVICES = (
    (
        "/<node>/save_map",
        "slam_toolbox/srv/SaveMap",
        "rq/<node>/save_mapRequest` and `rr/<node>/save_mapReply",
        "save the run folder (name.data: folder, or empty for output_folder); result 0 saved, 1 nothing to save yet, "
        "255 failed (no folder, an error)",
    ),
)


class SaveMapService:
    """The service side of :class:`crlam.ros.slam_node.SlamNode`: a request joins the node's
    save requests with its (client id, sequence number); the worker saves and replies."""

    NODE_NAME: str
    dds: Any
    lock: threading.Lock
    wake: threading.Condition
    save_requests: deque[tuple[str, tuple[int, int] | None]]

    def _write(self, writer: Any, msg: Any) -> None:  # pragma: no cover - SlamNode's
        raise NotImplementedError

    def _serve_save_map(self) -> None:
        """The ``/<node>/save_map`` service (slam_toolbox/srv/SaveMap over DDS request/reply: :mod:`crlam.ros.services`)."""
        from crlam.ros import qos
        from crlam.ros.services import SaveMapRequest, SaveMapResponse, service_topics

        request_topic, reply_topic = service_topics(f"/{self.NODE_NAME}/save_map")
        self.w_save_reply = self.dds.writer(reply_topic, SaveMapResponse, qos.reliable(), raw=True)
        self.dds.reader(request_topic, SaveMapRequest, qos.reliable(), self._on_save_request, raw=True)

    def _on_save_request(self, msg: Any) -> None:
        with self.lock:
            self.save_requests.append((msg.name.data.strip(), (int(msg.client_guid), int(msg.sequence_number))))
            self.wake.notify_all()

    def _reply_save(self, client: tuple[int, int], saved: bool | None) -> None:
        """Answers a save_map request: saved (RESULT_SUCCESS), nothing to save yet
        (RESULT_NO_MAP_RECEIVED) or failed (None: no folder, an error; RESULT_UNDEFINED_FAILURE)."""
        from crlam.ros import services

        result = {True: services.RESULT_SUCCESS, False: services.RESULT_NO_MAP_RECEIVED, None: services.RESULT_UNDEFINED_FAILURE}
        reply = services.SaveMapResponse(client_guid=client[0], sequence_number=client[1], result=result[saved])
        self._write(self.w_save_reply, reply)
