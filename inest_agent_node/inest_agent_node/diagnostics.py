"""What the reward paid for during training, per step and per episode: its parts, and how the
learned reward's stage compared with the simulator's true progress.

Why: a whole-episode score cannot tell a reward that pays for false completions (its tracker
counts a block done that is not in the goal) from one the agent simply has not climbed yet.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from inest_sim_node.observation import claimed_blocks

from .envs import BONUS, INTRINSIC, LEARNED_STAGE, SHAPING, TRUE_PROGRESS

PARTS = {"shaping": SHAPING, "bonus": BONUS, "intrinsic": INTRINSIC, "env_reward": "env_reward"}  # info keys


@dataclass
class EpisodeTrace:
    """The running episode of one environment."""

    max_progress: int = 0
    max_claimed: int = 0
    false_completion: bool = False  # the stage claimed a block that was not placed in order
    unearned_completion: bool = False  # ... and that had not been placed at any step before


@dataclass
class RewardDiagnostics:
    """Accumulates every training step's infos (envs.py keys) of N environments.

    Per step: the mean reward and the mean of each of its parts. Per finished episode: the true progress at its end
    and its maximum, a false completion (at some step the learned stage claimed more blocks
    than were placed in order then; this includes a tracker still catching up with a block
    pushed back out), an unearned completion (the stage claimed more blocks than had been
    placed at any step so far: paid for something that never happened), a miss (the true
    progress reached more blocks than the stage ever claimed)."""

    num_envs: int
    num_subtasks: int
    sums: dict[str, float] = field(default_factory=dict)
    counts: dict[str, int] = field(default_factory=dict)
    episodes: list[dict[str, Any]] = field(default_factory=list)
    traces: list[EpisodeTrace] = field(default_factory=list)

    def __post_init__(self) -> None:
        self.traces = [EpisodeTrace() for _ in range(self.num_envs)]

    def update(self, infos: Sequence[dict[str, Any]], dones: np.ndarray, rewards: np.ndarray) -> None:
        """One vector step: its infos, episode ends and the rewards the learner was given."""
        self.add("reward", rewards)
        for index, info in enumerate(infos):
            for name, key in PARTS.items():
                if key in info:
                    self.add(name, [info[key]])
            trace = self.traces[index]
            progress = int(info[TRUE_PROGRESS])
            trace.max_progress = max(trace.max_progress, progress)
            learned = LEARNED_STAGE in info
            if learned:
                claimed = int(claimed_blocks(info[LEARNED_STAGE], self.num_subtasks))
                trace.max_claimed = max(trace.max_claimed, claimed)
                trace.false_completion |= claimed > progress
                trace.unearned_completion |= claimed > trace.max_progress
            if dones[index]:
                episode: dict[str, Any] = {"final_progress": progress, "max_progress": trace.max_progress}
                if learned:
                    episode["false_completion"] = trace.false_completion
                    episode["unearned_completion"] = trace.unearned_completion
                    episode["missed"] = trace.max_progress > trace.max_claimed
                self.episodes.append(episode)
                self.traces[index] = EpisodeTrace()

    def add(self, name: str, values: Sequence[float] | np.ndarray) -> None:
        self.sums[name] = self.sums.get(name, 0.0) + float(np.sum(values))
        self.counts[name] = self.counts.get(name, 0) + len(values)

    def summary(self) -> dict[str, float]:
        """Means since the last summary (then cleared): per-step parts, per-episode rates."""
        result = {f"{name}_per_step": self.sums[name] / self.counts[name] for name in self.sums}
        if self.episodes:
            for key in ("final_progress", "max_progress", "false_completion", "unearned_completion", "missed"):
                values = [episode[key] for episode in self.episodes if key in episode]
                if values:
                    name = f"{key}_rate" if isinstance(values[0], bool) else f"{key}_mean"
                    result[name] = float(np.mean(values))
            result["episodes"] = float(len(self.episodes))
        self.sums, self.counts, self.episodes = {}, {}, []
        return result
