"""ROS 2 nodes of comems4build_ros (one module per executable).

``plant_sim`` (plant and lock-step master), ``feed`` (scenario inputs and forecasts),
``ems_node`` (``fuzzy_ems``, ``rbc_ems``, ``mpc_ems``, ...), ``recorder`` (rosbag2/MCAP)
and ``replay``. Each module exposes ``main(args=None)``; see docs/ros_nodes.md.
"""
