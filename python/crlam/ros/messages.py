"""The ROS 2 messages crlam's nodes publish or read, as Cyclone DDS IDL types.

Each class is the DDS type a ROS 2 node on rmw_cyclonedds or rmw_fastrtps puts on the wire for
that message: the type name is ROS 2's (``<pkg>::msg::dds_::<Type>_``), the fields and their
order those of ROS 2 Humble's ``.msg`` files (the definitions of ``rosbags``' ``ROS2_HUMBLE``
type store), and a sample is serialised as plain CDR (XCDR1, the representation ROS 2 uses):
``tests/test_ros_messages.py`` checks byte for byte that :func:`to_cdr` equals ``rosbags``'
``serialize_cdr`` of the same message, the 4-byte encapsulation header included.

:data:`ROS_TYPES` maps each ROS type name (``sensor_msgs/msg/LaserScan``) to its class.
"""

# No `from __future__ import annotations`: cyclonedds reads the field annotations as objects.

import typing
from dataclasses import dataclass, field, fields
from typing import Any

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int8, int32, sequence, uint8, uint32

__all__ = [
    "ROS_TYPES",
    "ColorRGBA",
    "CompressedImage",
    "DiagnosticArray",
    "DiagnosticStatus",
    "Duration",
    "Header",
    "KeyValue",
    "LaserEcho",
    "LaserScan",
    "MapMetaData",
    "Marker",
    "MarkerArray",
    "MeshFile",
    "MultiEchoLaserScan",
    "OccupancyGrid",
    "Odometry",
    "Path",
    "Point",
    "Pose",
    "PoseArray",
    "PoseStamped",
    "PoseWithCovariance",
    "PoseWithCovarianceStamped",
    "Quaternion",
    "String",
    "TFMessage",
    "Time",
    "Transform",
    "TransformStamped",
    "Twist",
    "TwistWithCovariance",
    "UVCoordinate",
    "Vector3",
    "Clock",
    "dds_type_name",
    "from_cdr",
    "from_object",
    "to_cdr",
]


def dds_type_name(ros_type: str) -> str:
    """ROS 2's DDS type name of a ROS type: ``sensor_msgs/msg/LaserScan`` -> ``sensor_msgs::msg::dds_::LaserScan_``."""
    pkg, kind, name = ros_type.split("/")
    return f"{pkg}::{kind}::dds_::{name}_"


def _zeros36() -> list[float]:
    return [0.0] * 36


# --- builtin_interfaces, std_msgs ----------------------------------------------------------------


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Duration(IdlStruct, typename="builtin_interfaces::msg::dds_::Duration_"):
    sec: int32 = 0
    nanosec: uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str = ""


@dataclass
class ColorRGBA(IdlStruct, typename="std_msgs::msg::dds_::ColorRGBA_"):
    r: float32 = 0.0
    g: float32 = 0.0
    b: float32 = 0.0
    a: float32 = 0.0


@dataclass
class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
    clock: Time = field(default_factory=Time)


# --- geometry_msgs -------------------------------------------------------------------------------


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@dataclass
class PoseArray(IdlStruct, typename="geometry_msgs::msg::dds_::PoseArray_"):
    header: Header = field(default_factory=Header)
    poses: sequence[Pose] = field(default_factory=list)


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=_zeros36)


@dataclass
class PoseWithCovarianceStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovarianceStamped_"):
    header: Header = field(default_factory=Header)
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=_zeros36)


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped] = field(default_factory=list)


# --- sensor_msgs ---------------------------------------------------------------------------------


@dataclass
class LaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::LaserScan_"):
    header: Header = field(default_factory=Header)
    angle_min: float32 = 0.0
    angle_max: float32 = 0.0
    angle_increment: float32 = 0.0
    time_increment: float32 = 0.0
    scan_time: float32 = 0.0
    range_min: float32 = 0.0
    range_max: float32 = 0.0
    ranges: sequence[float32] = field(default_factory=list)
    intensities: sequence[float32] = field(default_factory=list)


@dataclass
class LaserEcho(IdlStruct, typename="sensor_msgs::msg::dds_::LaserEcho_"):
    echoes: sequence[float32] = field(default_factory=list)


@dataclass
class MultiEchoLaserScan(IdlStruct, typename="sensor_msgs::msg::dds_::MultiEchoLaserScan_"):
    header: Header = field(default_factory=Header)
    angle_min: float32 = 0.0
    angle_max: float32 = 0.0
    angle_increment: float32 = 0.0
    time_increment: float32 = 0.0
    scan_time: float32 = 0.0
    range_min: float32 = 0.0
    range_max: float32 = 0.0
    ranges: sequence[LaserEcho] = field(default_factory=list)
    intensities: sequence[LaserEcho] = field(default_factory=list)


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    header: Header = field(default_factory=Header)
    format: str = ""
    data: sequence[uint8] = field(default_factory=list)


# --- nav_msgs ------------------------------------------------------------------------------------


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class MapMetaData(IdlStruct, typename="nav_msgs::msg::dds_::MapMetaData_"):
    map_load_time: Time = field(default_factory=Time)
    resolution: float32 = 0.0
    width: uint32 = 0
    height: uint32 = 0
    origin: Pose = field(default_factory=Pose)


@dataclass
class OccupancyGrid(IdlStruct, typename="nav_msgs::msg::dds_::OccupancyGrid_"):
    header: Header = field(default_factory=Header)
    info: MapMetaData = field(default_factory=MapMetaData)
    data: sequence[int8] = field(default_factory=list)


@dataclass
class Path(IdlStruct, typename="nav_msgs::msg::dds_::Path_"):
    header: Header = field(default_factory=Header)
    poses: sequence[PoseStamped] = field(default_factory=list)


# --- visualization_msgs, diagnostic_msgs ---------------------------------------------------------


@dataclass
class UVCoordinate(IdlStruct, typename="visualization_msgs::msg::dds_::UVCoordinate_"):
    u: float32 = 0.0
    v: float32 = 0.0


@dataclass
class MeshFile(IdlStruct, typename="visualization_msgs::msg::dds_::MeshFile_"):
    filename: str = ""
    data: sequence[uint8] = field(default_factory=list)


@dataclass
class Marker(IdlStruct, typename="visualization_msgs::msg::dds_::Marker_"):
    header: Header = field(default_factory=Header)
    ns: str = ""
    id: int32 = 0
    type: int32 = 0
    action: int32 = 0
    pose: Pose = field(default_factory=Pose)
    scale: Vector3 = field(default_factory=Vector3)
    color: ColorRGBA = field(default_factory=ColorRGBA)
    lifetime: Duration = field(default_factory=Duration)
    frame_locked: bool = False
    points: sequence[Point] = field(default_factory=list)
    colors: sequence[ColorRGBA] = field(default_factory=list)
    texture_resource: str = ""
    texture: CompressedImage = field(default_factory=CompressedImage)
    uv_coordinates: sequence[UVCoordinate] = field(default_factory=list)
    text: str = ""
    mesh_resource: str = ""
    mesh_file: MeshFile = field(default_factory=MeshFile)
    mesh_use_embedded_materials: bool = False


@dataclass
class MarkerArray(IdlStruct, typename="visualization_msgs::msg::dds_::MarkerArray_"):
    markers: sequence[Marker] = field(default_factory=list)


@dataclass
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    key: str = ""
    value: str = ""


@dataclass
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    level: uint8 = 0
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: sequence[KeyValue] = field(default_factory=list)


@dataclass
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    header: Header = field(default_factory=Header)
    status: sequence[DiagnosticStatus] = field(default_factory=list)


#: Every ROS type of this module by its ROS name.
ROS_TYPES: dict[str, type[IdlStruct]] = {
    "builtin_interfaces/msg/Time": Time,
    "builtin_interfaces/msg/Duration": Duration,
    "std_msgs/msg/Header": Header,
    "std_msgs/msg/String": String,
    "std_msgs/msg/ColorRGBA": ColorRGBA,
    "rosgraph_msgs/msg/Clock": Clock,
    "geometry_msgs/msg/Point": Point,
    "geometry_msgs/msg/Vector3": Vector3,
    "geometry_msgs/msg/Quaternion": Quaternion,
    "geometry_msgs/msg/Pose": Pose,
    "geometry_msgs/msg/PoseStamped": PoseStamped,
    "geometry_msgs/msg/PoseArray": PoseArray,
    "geometry_msgs/msg/PoseWithCovariance": PoseWithCovariance,
    "geometry_msgs/msg/PoseWithCovarianceStamped": PoseWithCovarianceStamped,
    "geometry_msgs/msg/Twist": Twist,
    "geometry_msgs/msg/TwistWithCovariance": TwistWithCovariance,
    "geometry_msgs/msg/Transform": Transform,
    "geometry_msgs/msg/TransformStamped": TransformStamped,
    "tf2_msgs/msg/TFMessage": TFMessage,
    "sensor_msgs/msg/LaserScan": LaserScan,
    "sensor_msgs/msg/LaserEcho": LaserEcho,
    "sensor_msgs/msg/MultiEchoLaserScan": MultiEchoLaserScan,
    "sensor_msgs/msg/CompressedImage": CompressedImage,
    "nav_msgs/msg/Odometry": Odometry,
    "nav_msgs/msg/MapMetaData": MapMetaData,
    "nav_msgs/msg/OccupancyGrid": OccupancyGrid,
    "nav_msgs/msg/Path": Path,
    "visualization_msgs/msg/UVCoordinate": UVCoordinate,
    "visualization_msgs/msg/MeshFile": MeshFile,
    "visualization_msgs/msg/Marker": Marker,
    "visualization_msgs/msg/MarkerArray": MarkerArray,
    "diagnostic_msgs/msg/KeyValue": KeyValue,
    "diagnostic_msgs/msg/DiagnosticStatus": DiagnosticStatus,
    "diagnostic_msgs/msg/DiagnosticArray": DiagnosticArray,
}


def to_cdr(msg: IdlStruct) -> bytes:
    """``msg`` as ROS 2 puts it on the wire and in a bag: plain CDR (XCDR1), little endian,
    behind the 4-byte encapsulation header ``00 01 00 00``."""
    return bytes(msg.serialize(use_version_2=False))


def from_cdr(cls: type[IdlStruct], data: bytes) -> Any:
    """A message of type ``cls`` from its CDR bytes (with the encapsulation header)."""
    return cls.deserialize(data)


def _element_class(annotation: Any) -> type[IdlStruct] | None:
    """The message class of a sequence or array field's items (None for numbers and strings)."""
    outer = typing.get_args(annotation)
    inner = typing.get_args(outer[0]) if outer else ()
    item = inner[0] if inner else None
    return item if isinstance(item, type) and issubclass(item, IdlStruct) else None


def from_object(obj: Any, cls: type[IdlStruct]) -> Any:
    """A message of ``cls`` with the fields of ``obj`` (a ``rosbags`` message of a ROS 1 or ROS 2
    bag, or anything with those attributes), copied field by field. Fields ``obj`` lacks keep
    their defaults; fields only ``obj`` has (a ROS 1 header's ``seq``) are left out."""
    values: dict[str, Any] = {}
    hints = cls.__annotations__
    for f in fields(cls):
        if not hasattr(obj, f.name):
            continue
        v = getattr(obj, f.name)
        default = cls.__dataclass_fields__[f.name].default_factory  # type: ignore[attr-defined]
        if callable(default) and isinstance(sample := default(), IdlStruct):
            v = from_object(v, type(sample))
        elif (item := _element_class(hints[f.name])) is not None:
            v = [from_object(x, item) for x in v]
        elif hasattr(v, "tolist"):
            v = v.tolist()
        elif isinstance(v, (bytes, bytearray, memoryview)):
            v = list(bytes(v))
        values[f.name] = v
    # ROS 1 stores Header.stamp as Time with secs/nsecs: rosbags names them sec/nanosec already.
    return cls(**values)
