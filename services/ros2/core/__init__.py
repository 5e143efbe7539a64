"""ROS 2 over rmw_zenoh: rmw_zenoh's wire format, ROS 2 types and CDR, images and people."""
