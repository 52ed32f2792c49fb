"""The reward runtime: task-free imports, one interface for every reward, and a new tracker or
method as one class plus one registry line."""

from __future__ import annotations

import subprocess
import sys
from typing import ClassVar

import numpy as np
import pytest
from inest_reward_node.runtime.config import RewardConfig
from inest_reward_node.runtime.methods import REWARD_METHODS, Batch, LearnedReward
from inest_reward_node.runtime.rewards import RewardFunction, RewardScorer
from inest_reward_node.runtime.trackers import TRACKERS, Evidence, StageTracker
from test_scorer import line_model

RUNTIME_MODULES = (
    "config", "encoders", "holdr", "images", "intrinsic", "methods", "model", "reds", "rewards",
    "serving", "shaping", "stage_classifier", "stage_head", "trackers",
)  # fmt: skip


def test_the_runtime_imports_neither_the_simulator_nor_the_training_code():
    modules = [f"inest_reward_node.runtime.{name}" for name in RUNTIME_MODULES]
    try:
        import rclpy  # noqa: F401

        modules.append("inest_reward_node.node")  # the reward node: an adapter over the runtime alone
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

    def distance(self, batch: Batch) -> np.ndarray:
        return -np.linalg.norm(batch.embeddings - self.goals.goals[-1], axis=1)


def test_a_new_method_is_one_class_and_one_registry_line(monkeypatch):
    monkeypatch.setitem(REWARD_METHODS, DistanceToFinalGoal.name, DistanceToFinalGoal)
    scorer = RewardScorer(line_model(), 3, variant="final_goal", config=RewardConfig(tracker="threshold"))
    parts = scorer.score_embeddings(np.array([[5.0, 0.0]]))
    assert parts.total[0] == pytest.approx(-15.0) and parts.bonus[0] == 0.0
