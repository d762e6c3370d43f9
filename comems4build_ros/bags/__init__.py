"""rosbag2/MCAP bags: writing, reading, and the evaluation of a recorded run (no rclpy)."""
