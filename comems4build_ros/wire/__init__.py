"""The wire contract of the ROS node set: topics, CDR, run tokens, exit codes (no rclpy)."""
