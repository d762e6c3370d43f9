"""rclpy's message classes and QoS profiles for the specs of the topic contract.

The contract (:mod:`comems4build_ros.wire.contract`) is plain data without rclpy; the nodes
build their publishers and subscriptions with the classes and profiles made here.
"""

from __future__ import annotations

import importlib

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from comems4build_ros.wire.contract import QoSSpec, TopicSpec


def message_class(topic: TopicSpec | str) -> type:
    """The Python message class of a topic (``std_msgs/msg/Float64`` -> ``std_msgs.msg.Float64``)."""
    type_name = topic.type if isinstance(topic, TopicSpec) else topic
    pkg, sub, cls = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.{sub}"), cls)


def qos_profile(topic: TopicSpec | QoSSpec) -> QoSProfile:
    """The rclpy QoS profile of a topic (or of a :class:`~comems4build_ros.wire.contract.QoSSpec`)."""
    qos = topic.qos if isinstance(topic, TopicSpec) else topic
    return QoSProfile(
        reliability=ReliabilityPolicy.RELIABLE if qos.reliability == "reliable" else ReliabilityPolicy.BEST_EFFORT,
        history=HistoryPolicy.KEEP_LAST if qos.history == "keep_last" else HistoryPolicy.KEEP_ALL,
        depth=qos.depth,
        durability=(
            DurabilityPolicy.TRANSIENT_LOCAL if qos.durability == "transient_local" else DurabilityPolicy.VOLATILE
        ),
    )
