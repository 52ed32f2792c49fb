"""INEST simulator: the "sweep to top in order" world, its scripted expert and demonstration datasets.

Importing this package registers the gymnasium id `inest/SweepToTop-v0`. Nothing here imports
rclpy: the ROS 2 node is a thin adapter in `inest_sim_node.node`.
"""

import gymnasium as gym

from .config import EnvConfig, LayoutConfig, WorldConfig
from .env import ENV_ID, STATE_FIELDS, SweepToTopEnv

__version__ = "0.1.0"

if ENV_ID not in gym.registry:
    gym.register(ENV_ID, entry_point="inest_sim_node.env:SweepToTopEnv")

__all__ = ["ENV_ID", "STATE_FIELDS", "EnvConfig", "LayoutConfig", "SweepToTopEnv", "WorldConfig", "__version__"]
