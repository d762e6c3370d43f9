"""The commands on top: the ``comems4build`` command line, its subcommands, benchmarks, the ROS launch file."""
