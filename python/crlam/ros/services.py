"""ROS 2 services over DDS request/reply: the nodes' ``save_map`` service.

A ROS 2 service ``/<node>/save_map`` is two DDS topics, ``rq/<node>/save_mapRequest`` and
``rr/<node>/save_mapReply``, of the types ``<pkg>::srv::dds_::<Srv>_Request_`` and
``..._Response_``. As rmw_cyclonedds puts them on the wire, each sample starts with a request
header, the client's 64-bit id and the request's sequence number (``cdds_request_header_t``),
then the request or response fields; the reply repeats the request's header, which is how a
client matches replies to its requests. (A client on rmw_fastrtps carries the same pair as
the sample identity instead: crlam answers clients on Cyclone DDS, which is what a ROS 2 robot
talking to crlam over Cyclone uses.)

The service type is **slam_toolbox's** ``slam_toolbox/srv/SaveMap``, what ``ros2 service call
/slam_toolbox/save_map slam_toolbox/srv/SaveMap "{name: {data: 'FOLDER'}}"`` sends to
slam_toolbox: request ``std_msgs/String name`` (the folder; empty: the node's
``output_folder``), response ``int8 result`` (:data:`RESULT_SUCCESS`,
:data:`RESULT_NO_MAP_RECEIVED`, :data:`RESULT_UNDEFINED_FAILURE`).
"""

# No `from __future__ import annotations`: cyclonedds reads the field annotations as objects.

from dataclasses import dataclass, field

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import int8, int64, uint64

from crlam.ros.messages import String

__all__ = [
    "RESULT_NO_MAP_RECEIVED",
    "RESULT_SUCCESS",
    "RESULT_UNDEFINED_FAILURE",
    "SAVE_MAP_TYPE",
    "SaveMapRequest",
    "SaveMapResponse",
    "service_topics",
]

#: slam_toolbox/srv/SaveMap's result codes.
RESULT_SUCCESS = 0
RESULT_NO_MAP_RECEIVED = 1
RESULT_UNDEFINED_FAILURE = 255

#: The ROS 2 service type of ``save_map``.
SAVE_MAP_TYPE = "slam_toolbox/srv/SaveMap"


@dataclass
class SaveMapRequest(IdlStruct, typename="slam_toolbox::srv::dds_::SaveMap_Request_"):
    """rmw_cyclonedds' request header, then slam_toolbox/srv/SaveMap's request."""

    client_guid: uint64 = 0
    sequence_number: int64 = 0
    name: String = field(default_factory=String)


@dataclass
class SaveMapResponse(IdlStruct, typename="slam_toolbox::srv::dds_::SaveMap_Response_"):
    """The request's header, then slam_toolbox/srv/SaveMap's response."""

    client_guid: uint64 = 0
    sequence_number: int64 = 0
    result: int8 = RESULT_SUCCESS


def service_topics(service: str) -> tuple[str, str]:
    """(request, reply) DDS topics of ROS 2 service ``service``:
    ``/crlam_slam/save_map`` -> (``rq/crlam_slam/save_mapRequest``, ``rr/crlam_slam/save_mapReply``)."""
    name = "/" + service.strip().strip("/")
    return f"rq{name}Request", f"rr{name}Reply"
