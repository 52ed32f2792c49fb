"""Per-frame learned rewards of the three methods, and replaying a frame sequence through the tracker.

- inest: r(d) to the current subtask's goal (d rescaled, see ShapingConfig), plus the bonus
  per completed subtask; the bonus alone once the last subtask is done.
- xirl: -scale * d to the single (final) goal embedding.
- holdr: -max(0, d(s, g) - d(g, g)) / T with d the predicted steps to the goal, T the horizon.
Completion thresholds live on each method's own per-subtask reward: r(d) for TCC models,
the HOLD-R reward for HOLD-R models.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from .intrinsic import IntrinsicConfig, NoveltyMemory
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


def inest_distance_unit(model: RewardModel, goals: SubtaskGoals) -> float:
    """Factor from raw embedding distance to the units r(d) is applied in (see ShapingConfig.start_distance)."""
    return goals.distance_scale * model.shaping.start_distance


def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
    """(N, subtasks): each frame's completion-test reward against every subtask goal."""
    if model.method == "holdr":
        horizon = model.network.config.steps_unit
        columns = []
        for goal in goals.goals:
            to_goal = model.holdr_steps(embeddings, goal)
            columns.append(-np.maximum(0.0, to_goal - model.holdr_steps_at_goal(goal)) / horizon)
        return np.stack(columns, axis=1)
    distances = np.linalg.norm(embeddings[:, None, :] - goals.goals[None], axis=-1)
    return distance_reward(distances * inest_distance_unit(model, goals), model.shaping)


@dataclass
class RewardParts:
    """One scored batch: per environment, the reward and what it is made of."""

    total: np.ndarray  # (N,) what the agent receives
    distance: np.ndarray  # (N,) the method's per-frame reward (INEST: r(d) to the current goal; 0 once done)
    bonus: np.ndarray  # (N,) subtask bonus (INEST: completed subtasks x bonus)
    intrinsic: np.ndarray  # (N,) weighted novelty bonus
    subtask: np.ndarray  # (N,) current subtask index after this frame
    completed: np.ndarray  # (N,) subtasks completed after this frame
    switched: np.ndarray  # (N,) bool, this frame completed a subtask
    embeddings: np.ndarray  # (N, D) the frames' embeddings, for coverage analysis

    def select(self, rows: slice | np.ndarray) -> RewardParts:
        return RewardParts(*(getattr(self, field.name)[rows] for field in fields(self)))


class RewardScorer:
    """The learned reward for N environments at once, with per-environment subtask trackers and
    per-subtask novelty memories shared by all of them.

    `score(frames)` embeds all N frames in one forward pass. `reset(i)` starts environment i's
    next episode: its tracker restarts, the exploration memories are kept.
    """

    def __init__(
        self,
        model: RewardModel,
        scheme: int,
        variant: str | None = None,
        intrinsic: IntrinsicConfig | None = None,
        num_envs: int = 1,
    ) -> None:
        self.model = model
        self.variant = variant or default_variant(model, scheme)
        check_variant(model, self.variant, scheme)
        self.goals = model.goals(scheme)
        self.intrinsic = intrinsic or IntrinsicConfig(mode="none")
        self.trackers = [SubtaskTracker(self.goals.thresholds, model.shaping.hold_steps) for _ in range(num_envs)]
        self.steps_since_switch = np.full(num_envs, -1)
        self.memories: list[NoveltyMemory] = []

    @property
    def num_envs(self) -> int:
        return len(self.trackers)

    @property
    def num_subtasks(self) -> int:
        return len(self.goals.thresholds)

    def reset(self, env_index: int | None = None) -> None:
        """Start a new episode in one environment (or all): tracker only, memories persist."""
        for index in range(self.num_envs) if env_index is None else [env_index]:
            self.trackers[index].reset()
            self.steps_since_switch[index] = -1

    def score(self, frames: np.ndarray, states: np.ndarray | None = None) -> RewardParts:
        """frames: (N, H, W, 3) uint8, one per environment, in environment order."""
        return self.score_embeddings(self.model.embed(frames), states)

    def score_embeddings(
        self,
        embeddings: np.ndarray,
        states: np.ndarray | None = None,
        envs: np.ndarray | None = None,
        rounds: np.ndarray | None = None,
        episode_ends: np.ndarray | None = None,
    ) -> RewardParts:
        """Without `envs`, one embedding per environment in order. With it, row i belongs to
        environment envs[i] and is taken in order. `rounds` (ascending) groups the rows into
        vector steps: a later round's frames are judged against novelty memories holding the
        earlier rounds' frames, as if scored one call per round, with one search for all.
        `episode_ends[i]`: envs[i] starts a new episode after row i."""
        return self.advance(
            subtask_rewards(self.model, embeddings, self.goals), embeddings, states, envs, rounds, episode_ends
        )

    def advance(
        self,
        per_subtask: np.ndarray,
        embeddings: np.ndarray,
        states: np.ndarray | None,
        envs: np.ndarray | None = None,
        rounds: np.ndarray | None = None,
        episode_ends: np.ndarray | None = None,
    ) -> RewardParts:
        """Move the frames' trackers on, given each frame's reward against every subtask goal."""
        if envs is None:
            if len(per_subtask) != self.num_envs:
                raise ValueError(f"expected one frame per environment ({self.num_envs}), got {len(per_subtask)}")
            envs = np.arange(self.num_envs)
        envs = np.asarray(envs, dtype=int)
        if len(envs) != len(per_subtask) or np.any((envs < 0) | (envs >= self.num_envs)):
            raise ValueError(f"environment indices {envs.tolist()} do not fit {len(per_subtask)} frames")
        rounds = np.zeros(len(envs), int) if rounds is None else np.asarray(rounds)
        if len(rounds) != len(envs) or np.any(np.diff(rounds) < 0):
            raise ValueError("rounds must give every frame its round, in ascending order")
        ends = np.zeros(len(envs), bool) if episode_ends is None else np.asarray(episode_ends, dtype=bool)
        count = len(envs)
        distance, bonus, subtask, completed = (
            np.zeros(count),
            np.zeros(count),
            np.zeros(count, int),
            np.zeros(count, int),
        )
        switched = np.zeros(count, bool)
        novelty_subtask, since_switch = np.zeros(count, int), np.zeros(count, int)
        for row, (env, rewards) in enumerate(zip(envs, per_subtask, strict=True)):
            tracker = self.trackers[env]
            novelty_subtask[row] = tracker.current  # novelty is judged within the subtask the frame was taken in
            since_switch[row] = self.steps_since_switch[env]
            was_done = tracker.done
            reward_now = rewards[tracker.current]
            switched[row] = tracker.update(reward_now)
            if self.variant == "inest":
                distance[row] = 0.0 if was_done else reward_now
                bonus[row] = tracker.completed * self.model.shaping.subtask_bonus
            else:
                distance[row] = rewards[-1]
            subtask[row], completed[row] = tracker.current, tracker.completed
            if switched[row]:
                self.steps_since_switch[env] = 0
            elif self.steps_since_switch[env] >= 0:
                self.steps_since_switch[env] += 1
            if ends[row]:
                self.reset(env)
        if self.variant == "xirl":
            distance = -self.goals.distance_scale * np.linalg.norm(embeddings - self.goals.goals[-1], axis=1)
        intrinsic = self.intrinsic_bonus(embeddings, states, novelty_subtask, since_switch, rounds)
        total = distance + bonus + intrinsic
        return RewardParts(total, distance, bonus, intrinsic, subtask, completed, switched, embeddings)

    def intrinsic_bonus(
        self,
        embeddings: np.ndarray,
        states: np.ndarray | None,
        subtasks: np.ndarray,
        since_switch: np.ndarray,
        rounds: np.ndarray,
    ) -> np.ndarray:
        """Weighted novelty of each frame in its subtask's memory; frames of a later round (step)
        are judged against a memory holding the earlier rounds' frames."""
        config = self.intrinsic
        if config.mode == "none":
            return np.zeros(len(subtasks))
        if config.mode == "state":
            if states is None:
                raise ValueError("the state intrinsic bonus needs the environments' state vectors")
            vectors = np.asarray(states, dtype=np.float32)
        else:  # embedding distances in the same units as the INEST reward's d
            vectors = embeddings * inest_distance_unit(self.model, self.goals)
        if not self.memories:
            self.memories = [NoveltyMemory(vectors.shape[1], config.capacity) for _ in range(self.num_subtasks)]
        novelty = np.zeros(len(subtasks))
        for subtask in np.unique(subtasks):
            members = subtasks == subtask
            novelty[members] = self.memories[subtask].novelty_in_rounds(vectors[members], rounds[members], config.k)
        return config.weight_after(since_switch) * novelty


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
    """Feed one episode's embeddings, in order, through a fresh scorer (no intrinsic bonus)."""
    scorer = RewardScorer(model, scheme, variant)
    per_subtask = subtask_rewards(model, embeddings, scorer.goals)
    steps = [
        scorer.advance(row[None], embedding[None], None) for row, embedding in zip(per_subtask, embeddings, strict=True)
    ]
    return Replay(
        np.array([step.total[0] for step in steps]),
        np.array([step.subtask[0] for step in steps]),
        np.array([step.completed[0] for step in steps]),
        [frame for frame, step in enumerate(steps) if step.switched[0]],
        scorer.num_subtasks,
    )
