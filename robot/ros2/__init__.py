"""ROS 2 robots over Zenoh, in rmw_zenoh's wire format, with no ROS install (``homing[ros2]``)."""
