"""Per-frame learned rewards of the three methods, and replaying a frame sequence through the tracker.

- inest: r(d) to the current subtask's goal (d rescaled, see ShapingConfig), plus the bonus
  per completed subtask; the bonus alone once the last subtask is done.
- xirl: -scale * d to the single (final) goal embedding.
- holdr: -max(0, d(s, g) - d(g, g)) / T with d the predicted steps to the goal, T the horizon.
Completion thresholds live on each method's own per-subtask reward: r(d) for TCC models,
the HOLD-R reward for HOLD-R models.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import ModelError, RewardModel, SubtaskGoals
from .shaping import SubtaskTracker, distance_reward

REWARD_VARIANTS = ("inest", "xirl", "holdr")


def default_variant(model: RewardModel, scheme: int) -> str:
    if model.method == "holdr":
        return "holdr"
    return "xirl" if scheme == 1 else "inest"


def check_variant(model: RewardModel, variant: str, scheme: int) -> None:
    if variant not in REWARD_VARIANTS:
        raise ValueError(f"unknown reward variant {variant!r}; expected one of {REWARD_VARIANTS}")
    if (variant == "holdr") != (model.method == "holdr"):
        raise ModelError(
            f"the {variant} reward needs a {'holdr' if variant == 'holdr' else 'tcc'} model, not {model.method}"
        )
    if variant == "xirl" and scheme != 1:
        raise ModelError(f"the xirl reward has one goal embedding; it cannot use {scheme} subtasks")


def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
    """(N, subtasks): each frame's completion-test reward against every subtask goal."""
    if model.method == "holdr":
        horizon = model.network.config.steps_unit
        columns = []
        for goal in goals.goals:
            to_goal = model.holdr_steps(embeddings, goal)
            at_goal = model.holdr_steps(goal[None], goal)[0]
            columns.append(-np.maximum(0.0, to_goal - at_goal) / horizon)
        return np.stack(columns, axis=1)
    distances = np.linalg.norm(embeddings[:, None, :] - goals.goals[None], axis=-1)
    return distance_reward(distances * goals.distance_scale * model.shaping.start_distance, model.shaping)


@dataclass
class Replay:
    rewards: np.ndarray  # (N,) the reward the agent would receive on each frame
    subtask: np.ndarray  # (N,) the tracker's current subtask on each frame (after the update)
    completed: np.ndarray  # (N,) subtasks completed so far
    completion_frames: list[int]  # frame on which each completed subtask completed
    num_subtasks: int

    @property
    def all_completed(self) -> bool:
        return len(self.completion_frames) == self.num_subtasks


def replay(model: RewardModel, embeddings: np.ndarray, scheme: int, variant: str | None = None) -> Replay:
    """Feed one episode's embeddings, in order, through a fresh tracker."""
    variant = variant or default_variant(model, scheme)
    check_variant(model, variant, scheme)
    goals = model.goals(scheme)
    per_subtask = subtask_rewards(model, embeddings, goals)
    tracker = SubtaskTracker(goals.thresholds, model.shaping.hold_steps)
    bonus = model.shaping.subtask_bonus
    rewards, current, completed, completions = [], [], [], []
    for frame, row in enumerate(per_subtask):
        was_done = tracker.done
        reward_now = row[tracker.current]
        if tracker.update(reward_now):
            completions.append(frame)
        if variant == "xirl":
            distance = np.linalg.norm(embeddings[frame] - goals.goals[-1])
            rewards.append(-goals.distance_scale * distance)
        elif variant == "holdr":
            rewards.append(row[-1])
        else:
            rewards.append(tracker.completed * bonus if was_done else reward_now + tracker.completed * bonus)
        current.append(tracker.current)
        completed.append(tracker.completed)
    return Replay(
        np.asarray(rewards, dtype=np.float64),
        np.asarray(current),
        np.asarray(completed),
        completions,
        len(goals.thresholds),
    )
