"""INEST agent: SAC policy learning on the learned reward, in process or over ROS 2 topics.

Pure logic here never imports rclpy; the ROS 2 node will be a thin adapter module.
"""

__version__ = "0.1.0"
