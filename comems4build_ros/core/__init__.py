"""The pure core: parameters, device models, plant, scenarios, EMS, KPIs and the in-process loop (no rclpy)."""
