"""The ROS 2 side: the node, its parameters and the demo. The numerics never import rclpy."""
