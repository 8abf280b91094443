"""crlam as live ROS 2 nodes over DDS, without a ROS installation (``pip install crlam[ros]``).

- :mod:`crlam.ros.messages`: the ROS 2 messages as Cyclone DDS IDL types.
- :mod:`crlam.ros.qos`: ROS 2's QoS profiles (sensor data, reliable, transient-local map).
- :mod:`crlam.ros.dds`: the DDS participant, restricted to the loopback interface unless told
  otherwise (:data:`crlam.ros.dds.LOOPBACK_CONFIG`), with ROS 2's topic naming (``rt/<name>``).
- :mod:`crlam.ros.play`: ``crlam ros play``, a bag published onto DDS.
- :mod:`crlam.ros.odometry_buffer`: scans matched to odometry as the offline bag reader does.
- :mod:`crlam.ros.slam_node`: ``crlam ros slam``.
- :mod:`crlam.ros.localize_node`: ``crlam ros localize``.
- :mod:`crlam.ros.explore_node`, :mod:`crlam.ros.explore_goal`: ``crlam ros explore``.
- :mod:`crlam.ros.params`: ROS 2 parameter files (``node: ros__parameters: ...``).
- :mod:`crlam.ros.reference`: the topic and parameter reference of the documentation.
- :mod:`crlam.ros.bench`: the node's latency figure of ``crlam bench``.
"""
