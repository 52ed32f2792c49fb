"""Vectorised training environments whose reward comes from a learned reward model.

The policy sees the state vector; the reward is computed from each environment's camera
frame after the step (the transition's next frame, including the last frame of an episode,
which auto-reset would otherwise replace), all N frames in one encoder forward pass.
"""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
from inest_reward_node.intrinsic import NoveltyMemory
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

    def make() -> gymnasium.Env:
        env = SweepToTopEnv(config=env_config)
        return CameraFrameInInfo(env, *frames) if frames else env

    venv = DummyVecEnv([make] * num_envs)
    venv.seed(seed)  # the first reset of environment i uses seed + i
    return venv


class LearnedRewardVecEnv(VecEnvWrapper):
    """Replaces the environments' reward by the learned one; the oracle stays in info["env_reward"]."""

    def __init__(self, venv: VecEnv, scorer: RewardScorer, record_every: int = 10) -> None:
        super().__init__(venv)
        if scorer.num_envs != venv.num_envs:
            raise ValueError(f"scorer tracks {scorer.num_envs} environments, the vector env has {venv.num_envs}")
        self.scorer = scorer
        self.record_every = record_every
        self.steps = 0
        self.visited: list[np.ndarray] = []  # every `record_every`-th vector step's embeddings, for coverage

    def exploration_state(self) -> dict[str, np.ndarray]:
        """Novelty memories and the coverage record: what a resumed run must not forget."""
        state = {f"memory_{i}": memory.contents() for i, memory in enumerate(self.scorer.memories)}
        if self.visited:
            state["visited"] = np.concatenate(self.visited)
        return state

    def restore_exploration(self, state: dict[str, np.ndarray]) -> None:
        capacity = self.scorer.intrinsic.capacity
        memories = sorted((key for key in state if key.startswith("memory_")), key=lambda key: int(key[7:]))
        self.scorer.memories = [NoveltyMemory.restored(state[key], capacity) for key in memories]
        self.visited = [state["visited"]] if "visited" in state else []

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
        if self.steps % self.record_every == 0:
            self.visited.append(parts.embeddings)
        self.steps += 1
        for index, info in enumerate(infos):
            info["env_reward"] = float(env_rewards[index])
            info["learned_subtask"] = int(parts.subtask[index])
            info["intrinsic_reward"] = float(parts.intrinsic[index])
            if dones[index]:
                self.scorer.reset(index)
        return observations, parts.total.astype(np.float32), dones, infos
