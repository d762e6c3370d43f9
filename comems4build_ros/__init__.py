"""comems4build_ros: ComEMS4Build energy management as plain Python core and ROS 2 nodes.

The core (``config``, ``types``, ``models``, ``plant``, ``scenario``, ``ems``, ``kpi``,
``sim``) imports no rclpy; the ROS 2 nodes live in ``comems4build_ros.ros``.
"""

__version__ = "0.1.0"
