"""Plumbing every INEST package shares: atomic, versioned files (`files`), line-aware progress
(`progress`) and the ROS 2 node helpers (`rosutil`, the only module here that imports rclpy).

Importing the package imports nothing heavy; take the module you need.
"""

__version__ = "0.1.0"
