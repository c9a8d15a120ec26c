"""ROS 2 interop: rmw_zenoh's wire format, channel-to-message mappings and the bridge's port (docs/ros2.md)."""
