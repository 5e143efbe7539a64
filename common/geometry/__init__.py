"""Geometry: the camera model, rigid transforms and the transform buffer, 4x4 poses, the robot's static map
(an occupancy grid, its ROS map files, the distances to its obstacles), and their messages."""
