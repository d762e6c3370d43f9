"""MQTT side of the EMS (no rclpy): topic map and codec, safety, Home Assistant discovery,
broker connection, embedded broker, clock and the simulated house behind MQTT.

The ROS node that uses it is :mod:`comems4build_ros.ros.nodes.mqtt_bridge`; the wiring of
a real building is described in docs/real_building.md.
"""
