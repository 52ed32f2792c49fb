"""The reward runtime: task-free imports, one interface for every reward, and a new tracker or
method as one class plus one registry line."""

from __future__ import annotations

import pkgutil
import subprocess
import sys
from typing import ClassVar

import numpy as np
import pytest
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.methods import REWARD_METHODS, Batch, LearnedReward
from inest_reward_node.runtime.model import save_model
from inest_reward_node.runtime.rewards import RewardFunction, RewardScorer
from inest_reward_node.runtime.trackers import TRACKERS, Evidence, StageTracker
from test_scorer import line_model

from inest_reward_node import runtime

RUNTIME_MODULES = tuple(module.name for module in pkgutil.iter_modules(runtime.__path__))  # every one, new ones too


def test_the_runtime_imports_neither_the_simulator_nor_the_training_code():
    # the runtime, and the gymnasium adapter and the reward node over it
    modules = [f"inest_reward_node.runtime.{name}" for name in RUNTIME_MODULES] + ["inest_reward_node.gym_wrapper"]
    try:
        import rclpy  # noqa: F401

        modules.append("inest_reward_node.node")
    except ImportError:
        pass
    script = (
        "import importlib, sys\n"
        f"for name in {modules!r}: importlib.import_module(name)\n"
        "print(' '.join(sorted(sys.modules)))\n"
    )
    loaded = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout.split()
    forbidden = ("pymunk", "inest_sim_node", "inest_agent_node", "inest_reward_node.learning", "stable_baselines3")
    assert [name for name in loaded if name.startswith(forbidden)] == []


def test_the_scorer_is_a_reward_function():
    scorer = RewardScorer(line_model(), 3, num_envs=2)
    assert isinstance(scorer, RewardFunction)
    scorer.reset([1])  # some environments, an index, or all
    scorer.reset(0)
    scorer.reset()


class EvidenceTracker(StageTracker):
    """Stage evidence alone, with hysteresis: up once P(stage >= c + 1) >= 0.5 for `hold_steps`
    frames, down once P(stage >= c) < 0.5 for as many (the docs' example of a new tracker)."""

    reads = frozenset({"at_least"})

    def step(self, evidence: Evidence) -> int:
        c, at_least = self.completed, evidence.at_least
        return self.move(c < self.num_subtasks and at_least[c + 1] >= 0.5, at_least[c] < 0.5)


def test_a_new_tracker_is_one_class_and_one_registry_line(monkeypatch):
    monkeypatch.setitem(TRACKERS, "evidence", EvidenceTracker)
    config = RewardConfig(tracker="evidence")
    scorer = RewardScorer(line_model(hold_steps=2), 3, config=config)
    assert scorer.evidence == "embedding"  # it reads the stage classifier, so the scorer computes it
    # the line model's classifier says stage k + 1 past x = 10 k - 1 (test_scorer.line_model)
    stages = [int(scorer.score_embeddings(np.array([[x, 0.0]])).completed[0]) for x in (0.0, 0.0, 0.0, -5.0, -5.0)]
    assert stages == [0, 1, 1, 1, 0]  # up after two frames, down after two frames back
    monkeypatch.delitem(TRACKERS, "evidence")
    with pytest.raises(ValueError, match="unknown reward tracker"):
        RewardConfig(tracker="evidence")


class DistanceToFinalGoal(LearnedReward):
    """-d to the last goal embedding, no bonus (the docs' example of a new method)."""

    name: ClassVar[str] = "final_goal"

    def shaping(self, batch: Batch) -> np.ndarray:
        return -np.linalg.norm(batch.embeddings - self.goals.goals[-1], axis=1)


def test_a_new_method_is_one_class_and_one_registry_line(monkeypatch):
    monkeypatch.setitem(REWARD_METHODS, DistanceToFinalGoal.name, DistanceToFinalGoal)
    scorer = RewardScorer(line_model(), 3, variant="final_goal", config=RewardConfig(tracker="threshold"))
    parts = scorer.score_embeddings(np.array([[5.0, 0.0]]))
    assert parts.total[0] == pytest.approx(-15.0) and parts.bonus[0] == 0.0


def test_the_gymnasium_wrapper_puts_the_learned_reward_on_an_environment_the_project_did_not_write():
    gymnasium = pytest.importorskip("gymnasium")
    pytest.importorskip("pygame")  # classic control renders with it
    from inest_reward_node.gym_wrapper import LearnedRewardWrapper

    model = line_model()  # a random encoder: the reward means nothing here, its plumbing is checked
    env = LearnedRewardWrapper(gymnasium.make("CartPole-v1", render_mode="rgb_array"), RewardScorer(model, 3))
    env.reset(seed=0)
    frames, rewards = [], []
    for _ in range(6):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        frames.append(env.unwrapped.render())
        rewards.append(reward)
        assert info["env_reward"] == 1.0 and 0 <= info["learned_stage"] <= 3 and not (terminated or truncated)
        parts = (info["shaping_reward"], info["subtask_bonus"], info["intrinsic_reward"])  # the training envs' keys
        assert sum(parts) == pytest.approx(reward)
    fresh = RewardScorer(model, 3)  # the same frames through a fresh scorer: the same rewards
    expected = [float(fresh.score(frame[None]).total[0]) for frame in frames]
    np.testing.assert_allclose(rewards, expected, rtol=1e-6)
    from stable_baselines3 import PPO  # one line for a stable-baselines3 user

    PPO("MlpPolicy", env, n_steps=16, batch_size=16, n_epochs=1, device="cpu").learn(16)
    env.close()


def test_the_gymnasium_wrapper_refuses_what_it_cannot_score(tmp_path):
    gymnasium = pytest.importorskip("gymnasium")
    from inest_reward_node.gym_wrapper import LearnedRewardWrapper

    model = line_model()
    save_model(tmp_path / "model", model.network, model.metadata)
    from_folder = LearnedRewardWrapper(gymnasium.make("CartPole-v1"), tmp_path / "model")  # a model folder will do
    assert (from_folder.reward.variant, from_folder.reward.num_subtasks) == ("inest", 3)
    scene = RewardScorer(line_model(), 3)
    scene.stage_camera = "allo"  # as a model whose stage head reads a scene camera
    with pytest.raises(ValueError, match="second camera"):
        LearnedRewardWrapper(gymnasium.make("CartPole-v1"), scene)
    with pytest.raises(ValueError, match="scores one environment"):
        LearnedRewardWrapper(gymnasium.make("CartPole-v1"), RewardScorer(line_model(), 3, num_envs=2))
    wrapped = LearnedRewardWrapper(gymnasium.make("CartPole-v1"), RewardScorer(line_model(), 3))
    wrapped.reset(seed=0)
    with pytest.raises(ValueError, match="render_mode"):
        wrapped.step(0)
