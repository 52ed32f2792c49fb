"""The reward runtime: load a reward model folder and turn camera frames into rewards.

Task-free: it never imports the simulator, the training code or rclpy, so a reward server on a
robot needs nothing else (docs/design.md, "Packages and layers").
"""
