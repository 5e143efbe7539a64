"""The ROS 2 node: a ROS 2 robot's camera and transforms in, its people out, over rmw_zenoh."""
