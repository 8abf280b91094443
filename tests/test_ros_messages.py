"""The ROS 2 message types of :mod:`crlam.ros.messages` against ``rosbags``' serialisation.

For every message type the nodes publish or read, messages with seeded random contents (strings,
sequences of 0 to 3 items, fixed arrays, extreme numbers) are built as ``rosbags`` objects,
copied field by field into the Cyclone DDS type, and the two CDR serialisations must be equal
byte for byte, the 4-byte encapsulation header included; the Cyclone type also reads
``rosbags``' bytes back to the same bytes.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

pytest.importorskip("cyclonedds", reason="crlam[ros] (cyclonedds) is not installed")

from rosbags.typesys import Stores, get_typestore  # noqa: E402
from rosbags.typesys.base import Nodetype  # noqa: E402

from crlam.ros import messages  # noqa: E402

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)

#: Every type a node publishes or reads.
NODE_TYPES = [
    "sensor_msgs/msg/LaserScan",
    "sensor_msgs/msg/MultiEchoLaserScan",
    "nav_msgs/msg/Odometry",
    "tf2_msgs/msg/TFMessage",
    "nav_msgs/msg/OccupancyGrid",
    "nav_msgs/msg/MapMetaData",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/PoseArray",
    "nav_msgs/msg/Path",
    "geometry_msgs/msg/PoseStamped",
    "rosgraph_msgs/msg/Clock",
    "visualization_msgs/msg/MarkerArray",
    "diagnostic_msgs/msg/DiagnosticArray",
    "std_msgs/msg/String",
]

_NUMPY = {
    "bool": np.bool_,
    "int8": np.int8,
    "uint8": np.uint8,
    "byte": np.uint8,
    "char": np.uint8,
    "int16": np.int16,
    "uint16": np.uint16,
    "int32": np.int32,
    "uint32": np.uint32,
    "int64": np.int64,
    "uint64": np.uint64,
    "float32": np.float32,
    "float64": np.float64,
}


def _base_value(kind: str, rng: np.random.Generator) -> Any:
    if kind == "string":
        return "".join(rng.choice(list("abc_/xyz"), size=int(rng.integers(0, 9))))
    if kind == "bool":
        return bool(rng.integers(0, 2))
    if kind == "byte":
        # rosbags packs ROS 2's byte (an octet) as a signed char: its values above 127 fail there.
        return int(rng.choice([0, 1, 3, 127]))
    dtype = _NUMPY[kind]
    if kind.startswith("float"):
        return float(dtype(rng.choice([0.0, -1.5, 1e-3, 12.0, np.inf, rng.normal() * 100])))
    info = np.iinfo(dtype)
    return int(rng.choice([info.min, info.max, 0, 1]))


def _value(desc: tuple[Any, Any], rng: np.random.Generator) -> Any:
    node, spec = desc
    if node == Nodetype.BASE:
        return _base_value(spec[0], rng)
    if node == Nodetype.NAME:
        return random_message(spec, rng)
    sub, size = spec
    n = size if node == Nodetype.ARRAY else int(rng.integers(0, 4))
    if sub[0] == Nodetype.BASE and sub[1][0] != "string":
        return np.array([_base_value(sub[1][0], rng) for _ in range(n)], dtype=_NUMPY[sub[1][0]])
    return [_value(sub, rng) for _ in range(n)]


def random_message(ros_type: str, rng: np.random.Generator) -> Any:
    """A ``rosbags`` message of ``ros_type`` with random contents."""
    _, fields = TYPESTORE.fielddefs[ros_type]
    return TYPESTORE.types[ros_type](**{name: _value(desc, rng) for name, desc in fields})


def to_cyclone(msg: Any, ros_type: str) -> Any:
    """The Cyclone DDS message with ``msg``'s contents, copied field by field (not through CDR)."""
    _, fields = TYPESTORE.fielddefs[ros_type]
    values = {}
    for name, (node, spec) in fields:
        v = getattr(msg, name)
        if node == Nodetype.NAME:
            v = to_cyclone(v, spec)
        elif node in (Nodetype.ARRAY, Nodetype.SEQUENCE):
            sub = spec[0]
            v = (
                [to_cyclone(x, sub[1]) for x in v]
                if sub[0] == Nodetype.NAME
                else [x.item() if hasattr(x, "item") else x for x in v]
            )
        values[name] = v
    return messages.ROS_TYPES[ros_type](**values)


@pytest.mark.parametrize("ros_type", NODE_TYPES)
def test_fields_match_rosbags_definition(ros_type: str) -> None:
    from dataclasses import fields

    cls = messages.ROS_TYPES[ros_type]
    assert cls.__idl_typename__ == messages.dds_type_name(ros_type)
    assert [f.name for f in fields(cls)] == [name for name, _ in TYPESTORE.fielddefs[ros_type][1]]


@pytest.mark.parametrize("ros_type", NODE_TYPES)
def test_cdr_bytes_equal_rosbags(ros_type: str) -> None:
    rng = np.random.default_rng(sum(map(ord, ros_type)))
    for _ in range(12):
        msg = random_message(ros_type, rng)
        expected = bytes(TYPESTORE.serialize_cdr(msg, ros_type))
        ours = messages.to_cdr(to_cyclone(msg, ros_type))
        assert expected[:4] == b"\x00\x01\x00\x00"
        assert ours == expected
        # And the Cyclone type reads rosbags' bytes back to the same bytes.
        assert messages.to_cdr(messages.from_cdr(messages.ROS_TYPES[ros_type], expected)) == expected


def test_dds_type_name() -> None:
    assert messages.dds_type_name("sensor_msgs/msg/LaserScan") == "sensor_msgs::msg::dds_::LaserScan_"


def test_save_map_service_wire_format() -> None:
    """rmw_cyclonedds' service samples: the request header (client id u64, sequence number i64),
    then slam_toolbox/srv/SaveMap's fields, as plain little-endian CDR."""
    import struct

    from crlam.ros.services import SaveMapRequest, SaveMapResponse

    req = SaveMapRequest(client_guid=0x0102030405060708, sequence_number=-3, name=messages.String(data="run"))
    assert req.serialize() == b"\x00\x01\x00\x00" + struct.pack("<QqI", 0x0102030405060708, -3, 4) + b"run\x00"
    assert SaveMapRequest.deserialize(req.serialize()) == req
    rep = SaveMapResponse(client_guid=7, sequence_number=9, result=1)
    assert rep.serialize()[:21] == b"\x00\x01\x00\x00" + struct.pack("<Qqb", 7, 9, 1)
