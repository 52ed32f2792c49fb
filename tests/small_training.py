"""The small training settings the agent tests share: two environments, 200 steps, tiny networks."""

from __future__ import annotations

from typing import Any

from inest_reward_node.runtime.intrinsic import IntrinsicConfig

from inest_agent_node.config import SacConfig, TrainConfig

SMALL_SAC = SacConfig(learning_starts=50, buffer_size=1000, batch_size=16, net_arch=(16, 16))


def small_train_config(**settings: Any) -> TrainConfig:
    """A TrainConfig that trains, evaluates and checkpoints once in 200 steps; `settings` override."""
    small: dict[str, Any] = {
        "intrinsic": IntrinsicConfig(mode="none"),
        "num_envs": 2,
        "total_steps": 200,
        "eval_every": 200,
        "eval_episodes": 1,
        "final_eval_episodes": 1,
        "checkpoint_every": 200,
        "sac": SMALL_SAC,
    }
    return TrainConfig(**(small | settings))
