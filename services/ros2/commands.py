COMMANDS = {
    "ros2": ("services.ros2.main", "run the ROS 2 node: a ROS 2 camera and /tf in, the people out as ROS 2 topics"),
}
