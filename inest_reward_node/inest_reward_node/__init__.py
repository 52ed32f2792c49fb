"""INEST reward: the representation learnt from demonstration videos and the reward it gives.

The libraries here never import rclpy; `node` (the reward node) is the thin ROS 2 adapter.
"""

__version__ = "0.1.0"
