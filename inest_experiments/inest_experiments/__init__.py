"""INEST experiments: the tooling around training, on the public APIs of the reward runtime and the
agent. `experiments` runs and reports grids of `inest-train` runs (`config`: the grid settings,
`grid_quality`: the report's reward-quality columns), `summary` summarises runs across seeds,
`reevaluate` plays a trained policy again on any layouts and `record_clips` records a policy's own
rollouts as labelled clips. Nothing here imports rclpy, and no other INEST package imports this one.
"""

__version__ = "0.1.0"
