"""INEST reward: representation learning and the learned reward (issue: representation learning).

Pure logic here never imports rclpy; the ROS 2 node will be a thin adapter module.
"""

__version__ = "0.1.0"
