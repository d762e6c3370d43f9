"""The run plan of a ROS launch, its supervisor and the launcher."""
