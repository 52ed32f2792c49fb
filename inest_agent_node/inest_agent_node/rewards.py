"""The reward a training or evaluation run scores its steps with, whatever its kind, behind the
runtime's one interface (RewardFunction): the learned rewards' RewardScorer, and the
simulator's own reward (`EnvironmentReward`, the oracle). `build_reward` chooses it by the
run's `reward` setting from `REWARD_BUILDERS`, so no caller asks which reward it holds.
"""

from __future__ import annotations

from collections.abc import Callable, Iterable

import numpy as np
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.model import load_model
from inest_reward_node.runtime.rewards import RewardFunction, RewardParts, RewardScorer, Steps
from inest_sim_node.scoring import NUM_BLOCKS

from .config import REWARDS, TrainConfig, reward_scheme


class EnvironmentReward:
    """The simulator's own dense reward (the oracle) as a RewardFunction: it reads no camera, its
    reward is the environment's (`Steps.env_rewards`) and its stage the true ordered progress
    (`Steps.known_stages`)."""

    camera: str | None = None
    image_size = 0  # no frames
    stage_camera: str | None = None
    needs_known_stages = True
    num_subtasks = NUM_BLOCKS

    def __init__(self, num_envs: int) -> None:
        self.stages = np.zeros(num_envs, dtype=int)  # each environment's stage after its last step

    @property
    def num_envs(self) -> int:
        return len(self.stages)

    def reset(self, env_indices: Iterable[int] | int | None = None) -> None:
        self.stages[slice(None) if env_indices is None else np.asarray(env_indices)] = 0

    def score(
        self, frames: np.ndarray | None, stage_frames: np.ndarray | None = None, steps: Steps | None = None
    ) -> RewardParts:
        if steps is None or steps.env_rewards is None or steps.known_stages is None:
            raise ValueError("the environment's reward needs each step's env_rewards and known_stages")
        rewards = np.asarray(steps.env_rewards, dtype=np.float64)
        stages = np.asarray(steps.known_stages, dtype=int)
        envs, _, ends = steps.rows(len(rewards), self.num_envs)
        switched = np.zeros(len(envs), bool)
        for row, env in enumerate(envs):  # in order: a later row of an environment follows its earlier ones
            switched[row] = stages[row] > self.stages[env]
            self.stages[env] = 0 if ends[row] else stages[row]
        nothing = np.zeros(len(envs))
        subtask = np.minimum(stages, self.num_subtasks - 1)
        embeddings, told = np.zeros((len(envs), 0)), np.ones(len(envs))  # no frames; the stage is told
        return RewardParts(rewards, rewards, nothing, nothing, subtask, stages, switched, embeddings, told)

    def exploration_state(self) -> dict[str, np.ndarray]:
        return {}

    def restore_exploration(self, state: dict[str, np.ndarray]) -> None:
        """Nothing to restore: the environment's reward keeps no memory."""


def learned_reward(config: TrainConfig, num_envs: int, evaluation: bool) -> RewardFunction:
    """The run's learned reward; in evaluations without the intrinsic bonus (its memories belong
    to training). The topic reward is the reward node's: its model's own method."""
    if config.reward == "topic" and not evaluation:
        raise ValueError("the topic reward comes from inest_reward_node: train over the graph (inest-agent-node)")
    if config.reward == "topic" and not config.model:
        raise ValueError(
            "the stage observation over the graph needs `model` (the reward node's model), "
            "so that in-process evaluations track the stage as the reward node does"
        )
    scheme = reward_scheme(config.reward, config.subtasks)
    model = load_model(config.model, view=config.view, scheme=scheme)
    variant = None if config.reward == "topic" else config.reward  # the reward node's default: the model's own
    intrinsic = IntrinsicConfig(mode="none") if evaluation else config.intrinsic
    return RewardScorer(model, scheme, variant, intrinsic, num_envs, config=config.learned_reward)


REWARD_BUILDERS: dict[str, Callable[[TrainConfig, int, bool], RewardFunction]] = {
    "env": lambda config, num_envs, evaluation: EnvironmentReward(num_envs),
    **{name: learned_reward for name in REWARDS if name != "env"},
}


def build_reward(config: TrainConfig, num_envs: int, evaluation: bool = False) -> RewardFunction:
    """The reward `config` scores its steps with. An evaluation whose policy does not observe the
    stage needs no learned reward: the environment's, which renders no frames, will do."""
    if evaluation and config.observation == "state":
        return EnvironmentReward(num_envs)
    return REWARD_BUILDERS[config.reward](config, num_envs, evaluation)
