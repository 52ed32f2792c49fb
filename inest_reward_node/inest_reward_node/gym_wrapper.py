"""A learned reward on any gymnasium environment with camera frames: the adapter a
stable-baselines3 or CleanRL user needs, one line over the runtime.

    env = LearnedRewardWrapper(gymnasium.make("CartPole-v1", render_mode="rgb_array"), "RUN/model")

for a model that reads one camera; a model whose stage head reads a second one also needs
`stage_camera=`.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, SupportsFloat

import gymnasium
import numpy as np

from .runtime.model import load_model
from .runtime.reward_parts import info_items
from .runtime.rewards import RewardFunction, RewardScorer

Camera = Callable[[gymnasium.Env], np.ndarray]


def rendered(env: gymnasium.Env) -> np.ndarray:
    """The environment's own picture: `env.render()` of an environment made with render_mode="rgb_array"."""
    frame = env.render()
    if not isinstance(frame, np.ndarray) or frame.ndim != 3:
        raise ValueError('the environment renders no RGB frame: make it with render_mode="rgb_array" or pass camera=')
    return frame


def reward_of_folder(folder: str | Path, subtasks: int | None = None) -> RewardScorer:
    """The default reward of a model folder: its own method, with `subtasks` subtasks (None: 3 where
    the model has goals for 3, else its only scheme)."""
    model = load_model(folder)
    if subtasks is None:
        subtasks = 3 if 3 in model.subtasks else min(model.subtasks)
    return RewardScorer(model, subtasks)


class LearnedRewardWrapper(gymnasium.Wrapper):
    """Replaces an environment's reward by a learned one (any RewardFunction of one environment, or
    a model folder), scored on the frame after every step: `camera(env)`, by default the
    environment's render, and `stage_camera(env)` when the reward reads a second camera
    (RewardFunction.stage_camera). The environment's own reward stays in info["env_reward"], the
    learned reward's stage and parts go under the info keys the project's own training
    environments use (reward_parts.PARTS: info["learned_stage"], info["shaping_reward"], ...);
    every reset starts the reward's new episode."""

    def __init__(
        self,
        env: gymnasium.Env,
        reward: RewardFunction | str | Path,
        camera: Camera = rendered,
        stage_camera: Camera | None = None,
        subtasks: int | None = None,
    ) -> None:
        super().__init__(env)
        self.reward = reward_of_folder(reward, subtasks) if isinstance(reward, str | Path) else reward
        if self.reward.num_envs != 1:
            raise ValueError(f"the wrapper scores one environment; the reward tracks {self.reward.num_envs}")
        if self.reward.stage_camera is not None and stage_camera is None:
            raise ValueError(
                f"the reward's stage head reads a second camera ({self.reward.stage_camera!r}): pass stage_camera="
            )
        self.camera, self.stage_camera = camera, stage_camera

    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        self.reward.reset()
        return self.env.reset(**kwargs)

    def step(self, action: Any) -> tuple[Any, SupportsFloat, bool, bool, dict[str, Any]]:
        observation, env_reward, terminated, truncated, info = self.env.step(action)
        stage_frames = None if self.reward.stage_camera is None else self.stage_camera(self.env)[None]
        parts = self.reward.score(self.camera(self.env)[None], stage_frames).row(0)
        info["env_reward"] = env_reward
        info.update(info_items(parts))
        return observation, parts["total"], terminated, truncated, info
