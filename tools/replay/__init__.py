"""Record the perception streams to MCAP, replay MCAP recordings and ROS 1/2 bags, inspect them."""
