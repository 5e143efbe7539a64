"""The ROS 2 node: a ROS 2 robot's camera, transforms and laser scans in, its people out, over rmw_zenoh."""
