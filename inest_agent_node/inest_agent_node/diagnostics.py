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
from inest_reward_node.runtime.reward_parts import INFO_KEYS, LEARNED_STAGE
from inest_sim_node.observation import claimed_blocks

from .envs import TRUE_PROGRESS

SHARED_PARTS = ("shaping", "bonus", "intrinsic")  # what the learned reward is the sum of (RewardParts names)
# name in results.json (`shaping_per_step`, `shaping_share`) -> info key
PARTS = {name: INFO_KEYS[name] for name in SHARED_PARTS} | {"env_reward": "env_reward"}
# a claim this many steps or fewer ahead of its block's placement counts as early, not unplaced
EARLY_CLAIM_STEPS = 3


@dataclass
class EpisodeTrace:
    """The running episode of one environment."""

    max_progress: int = 0
    max_claimed: int = 0
    false_completion: bool = False  # the stage claimed a block that was not placed in order
    unearned_completion: bool = False  # ... and that had not been placed at any step before
    steps: int = 0
    # blocks claimed ahead of their placement -> the step of the first such claim (-1: judged unplaced)
    pending: dict[int, int] = field(default_factory=dict)
    early_claim: bool = False  # a claim its block then earned within EARLY_CLAIM_STEPS
    unplaced_claim: bool = False  # a claim its block did not earn within EARLY_CLAIM_STEPS
    never_placed_claim: bool = False  # a claim its block did not earn before the episode ended

    def claim(self, claimed: int, progress: int) -> None:
        """One step's claimed blocks against the blocks placed in order."""
        self.steps += 1
        self.max_progress = max(self.max_progress, progress)
        self.false_completion |= claimed > progress
        self.unearned_completion |= claimed > self.max_progress
        for blocks in range(self.max_progress + 1, claimed + 1):
            self.pending.setdefault(blocks, self.steps)
        for blocks, since in list(self.pending.items()):
            if blocks <= self.max_progress:
                self.early_claim |= since >= 0
                del self.pending[blocks]
            elif since >= 0 and self.steps - since >= EARLY_CLAIM_STEPS:
                self.unplaced_claim = True
                self.pending[blocks] = -1

    def end(self) -> None:
        """The episode ended: a claim still waiting for its block was never earned."""
        self.unplaced_claim |= bool(self.pending)
        self.never_placed_claim = bool(self.pending)


@dataclass
class RewardDiagnostics:
    """Accumulates every training step's infos (envs.py keys) of N environments.

    Per step: the mean reward and the mean of each of its parts. Per finished episode: the true progress at its end
    and its maximum, a false completion (at some step the learned stage claimed more blocks
    than were placed in order then; this includes a tracker still catching up with a block
    pushed back out), an unearned completion (the stage claimed more blocks than had been
    placed at any step so far: paid for something that never happened), split into an early
    claim (the block was then placed within EARLY_CLAIM_STEPS: the tracker was a frame or two
    ahead) and an unplaced claim (it was not: the reward paid for a block not placed), among these
    a never-placed claim (its block was not placed before the episode ended either: the exploit
    suite's unplaced claim, exploit_suite.claims), a miss (the
    true progress reached more blocks than the stage ever claimed), and an episode that ends
    overclaimed (its last step paid for a block not in the goal then). Each part's share of the
    learned reward: its per-step mean's size over the sum of all three's. Per step also the
    share of steps spent in a stage claimed before its blocks were placed (`unearned_step`), or
    paid for more blocks than the goal then holds (`overpaid_step`, the exploit suite's pay), and
    the intrinsic bonus paid on those steps and on the others (`intrinsic_unearned`,
    `intrinsic_earned`): whether the novelty bonus pays for a falsely claimed stage."""

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
            learned = LEARNED_STAGE in info
            claimed = int(claimed_blocks(info[LEARNED_STAGE], self.num_subtasks)) if learned else progress
            trace.max_claimed = max(trace.max_claimed, claimed)
            trace.claim(claimed, progress)
            if learned:  # where the novelty bonus pays: in a stage the blocks earned, or in one claimed early
                unearned = claimed > trace.max_progress
                self.add("unearned_step", [float(unearned)])
                self.add("overpaid_step", [float(claimed > progress)])
                if PARTS["intrinsic"] in info:
                    self.add(f"intrinsic_{'unearned' if unearned else 'earned'}", [info[PARTS["intrinsic"]]])
            if dones[index]:
                trace.end()
                episode: dict[str, Any] = {"final_progress": progress, "max_progress": trace.max_progress}
                if learned:
                    episode["false_completion"] = trace.false_completion
                    episode["unearned_completion"] = trace.unearned_completion
                    episode["early_claim"] = trace.early_claim
                    episode["unplaced_claim"] = trace.unplaced_claim
                    episode["never_placed_claim"] = trace.never_placed_claim
                    episode["missed"] = trace.max_progress > trace.max_claimed
                    episode["ends_overclaimed"] = claimed > progress
                self.episodes.append(episode)
                self.traces[index] = EpisodeTrace()

    def add(self, name: str, values: Sequence[float] | np.ndarray) -> None:
        self.sums[name] = self.sums.get(name, 0.0) + float(np.sum(values))
        self.counts[name] = self.counts.get(name, 0) + len(values)

    def summary(self) -> dict[str, float]:
        """Means since the last summary (then cleared): per-step parts, per-episode rates."""
        result = {f"{name}_per_step": self.sums[name] / self.counts[name] for name in self.sums}
        sizes = {name: abs(result.get(f"{name}_per_step", 0.0)) for name in SHARED_PARTS}
        if sum(sizes.values()) > 0:
            result.update({f"{name}_share": size / sum(sizes.values()) for name, size in sizes.items()})
        if self.episodes:
            keys = ("final_progress", "max_progress", "false_completion", "unearned_completion")
            for key in (*keys, "early_claim", "unplaced_claim", "never_placed_claim", "missed", "ends_overclaimed"):
                values = [episode[key] for episode in self.episodes if key in episode]
                if values:
                    name = f"{key}_rate" if isinstance(values[0], bool) else f"{key}_mean"
                    result[name] = float(np.mean(values))
            result["episodes"] = float(len(self.episodes))
        self.sums, self.counts, self.episodes = {}, {}, []
        return result
