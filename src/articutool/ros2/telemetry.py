"""The tool's telemetry on the ROS 2 graph: ``articutool/joint_states`` (under the ROS 2 joint
names, ``joint_names``, for [pitch, roll]), ``articutool/imu_data_and_orientation``,
``articutool/health`` and ``articutool/battery`` as the tool sent them, plus the topics
upstream's helper nodes publish (:mod:`articutool.ros2.wrist_topics`). Each publisher is fed
by a link subscription; only well-formed messages reach the graph, the others are counted in
``counters['dropped']``. Reliable, volatile, depth 10 (ROS 2's default subscribers match).
"""

from __future__ import annotations

from typing import Any

from articutool.ros2 import wrist_topics

__all__ = ["TelemetryServer"]


class TelemetryServer:
    """Publishers on ``node`` (the main node) fed by ``client``'s telemetry."""

    def __init__(self, node: Any, client: Any, names: dict[str, str],
                 joint_names: tuple[str, str], republish_joint_states: bool,
                 counters: dict[str, int]) -> None:
        from diagnostic_msgs.msg import DiagnosticArray
        from rclpy.qos import QoSProfile
        from sensor_msgs.msg import BatteryState, Imu, JointState

        qos = QoSProfile(depth=10)
        c = client.names
        self._handles = [
            client.transport.subscribe(ep, wrist_topics.forwarder(
                node.create_publisher(cls, names[key], qos), ep.type, convert, counters))
            for ep, cls, key, convert in (
                (c.joint_states, JointState, "joint_states", wrist_topics.renamer(joint_names)),
                (c.imu, Imu, "imu", None), (c.health, DiagnosticArray, "health", None),
                (c.battery, BatteryState, "battery", None))]
        self._handles += wrist_topics.setup(node, client, names, joint_names,
                                            republish_joint_states, counters)

    def close(self) -> None:
        """Stop forwarding (the link subscriptions)."""
        for h in self._handles:
            h.close()
