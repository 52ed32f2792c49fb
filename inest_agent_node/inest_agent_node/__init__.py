"""INEST agent: SAC policy learning on the learned reward, in process or over ROS 2 topics.

The libraries here never import rclpy; `node` (the agent node) and `graph_env` (its vector env
over the graph's topics) are the thin ROS 2 adapters.
"""

__version__ = "0.1.0"
