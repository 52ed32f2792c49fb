"""Vectorised training environments whose reward comes from a learned reward model.

The policy sees the state vector; the reward is computed from each environment's camera
frame after the step (the transition's next frame, including the last frame of an episode,
which auto-reset would otherwise replace), all N frames in one encoder forward pass.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from inest_reward_node.rewards import RewardScorer
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecEnvWrapper

from inest_sim_node import EnvConfig, SweepToTopEnv

FRAME_KEY = "camera_frame"


class CameraFrameInInfo(gymnasium.Wrapper):
    """Puts the camera frame the learned reward scores into `info`, so it survives auto-reset."""

    def __init__(self, env: SweepToTopEnv, view: str, size: int) -> None:
        super().__init__(env)
        self.view, self.size = view, size

    def step(self, action: np.ndarray) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        info[FRAME_KEY] = self.env.unwrapped.render_camera(self.view, self.size)
        return observation, reward, terminated, truncated, info


def make_vec_env(num_envs: int, env_config: EnvConfig, seed: int, frames: tuple[str, int] | None = None) -> VecEnv:
    """N in-process environments on seeds seed, seed + 1, ...; `frames` = (view, size) adds camera frames."""

    def factory(index: int):
        def make() -> gymnasium.Env:
            env = SweepToTopEnv(config=env_config)
            env.reset(seed=seed + index)
            return CameraFrameInInfo(env, *frames) if frames else env

        return make

    venv = DummyVecEnv([factory(index) for index in range(num_envs)])
    venv.seed(seed)
    return venv


class LearnedRewardVecEnv(VecEnvWrapper):
    """Replaces the environments' reward by the learned one; the oracle stays in info["env_reward"]."""

    def __init__(self, venv: VecEnv, scorer: RewardScorer) -> None:
        super().__init__(venv)
        if scorer.num_envs != venv.num_envs:
            raise ValueError(f"scorer tracks {scorer.num_envs} environments, the vector env has {venv.num_envs}")
        self.scorer = scorer

    def reset(self) -> np.ndarray:
        self.scorer.reset()
        return self.venv.reset()

    def step_wait(self):
        observations, env_rewards, dones, infos = self.venv.step_wait()
        frames = np.stack([info.pop(FRAME_KEY) for info in infos])
        states = np.stack(
            [info.get("terminal_observation", obs) for info, obs in zip(infos, observations, strict=True)]
        )
        parts = self.scorer.score(frames, states)
        for index, info in enumerate(infos):
            info["env_reward"] = float(env_rewards[index])
            info["learned_subtask"] = int(parts.subtask[index])
            info["intrinsic_reward"] = float(parts.intrinsic[index])
            if dones[index]:
                self.scorer.reset(index)
        return observations, parts.total.astype(np.float32), dones, infos
