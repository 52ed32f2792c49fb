"""The learned reward methods (inest, xirl, holdr, reds): what each pays for a frame.

A method is one class in `REWARD_METHODS`, chosen once by name, in the manner of the
`imitation` library's reward functions. The scorer (rewards.py) hands it a `Batch`: each frame's
embedding, its completion-test reward against every subtask goal (`subtask_rewards`, what the
trackers test) and the stage before and after the frame; the method returns each frame's
reward without the subtask bonus (`shaping`), and pays `bonus` per completed subtask. Adding
a method is a class (here or in a module of its own) and one line in `REWARD_METHODS`.
"""

from __future__ import annotations

from typing import ClassVar, NamedTuple

import numpy as np

from .config import RewardConfig
from .model import ModelError, RewardModel, SubtaskGoals, model_kind
from .shaping import distance_reward


def default_variant(model: RewardModel, scheme: int) -> str:
    """The method a model was trained for (its ModelKind's): holdr and reds models their own, TCC
    models xirl with one subtask and inest with more."""
    return model_kind(model.method).default_reward(scheme)


def inest_distance_unit(model: RewardModel, goals: SubtaskGoals) -> float:
    """Factor from raw embedding distance to the units r(d) is applied in (see ShapingConfig.start_distance)."""
    return goals.distance_scale * model.shaping.start_distance


def goal_distances(embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
    """(N, subtasks): raw embedding distance of each frame to every subtask goal."""
    return np.linalg.norm(np.asarray(embeddings)[:, None, :] - goals.goals[None], axis=-1)


class Batch(NamedTuple):
    """A batch as the methods see it, per row, with the tracker's subtask and doneness before and after it."""

    per_subtask: np.ndarray
    embeddings: np.ndarray
    segments: np.ndarray | None
    before: np.ndarray
    was_done: np.ndarray
    after: np.ndarray
    done: np.ndarray


class LearnedReward:
    """One reward method. The scorer calls `subtask_rewards` on a batch of embeddings (what the
    trackers test) and, once the trackers have taken the batch, `shaping`: each frame's reward
    without the subtask bonus, `bonus` per completed subtask."""

    name: ClassVar[str]
    model_kind: ClassVar[str] = "tcc"  # the kind of model the method needs (ModelMetadata.method)
    infers_stage: ClassVar[bool] = False  # the method says which subtask a frame is in (`inferred_stages`)
    single_goal: ClassVar[bool] = False  # scored against the final goal alone: one subtask
    uses_segments = False  # whether `shaping` needs each frame's segment closeness
    bonus = 0.0

    def __init__(self, model: RewardModel, goals: SubtaskGoals, config: RewardConfig) -> None:
        self.model, self.goals, self.config = model, goals, config

    @classmethod
    def check(cls, model: RewardModel, scheme: int) -> None:
        if model.method != cls.model_kind:
            raise ModelError(f"the {cls.name} reward needs a {cls.model_kind} model, not {model.method}")

    @staticmethod
    def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
        """(N, subtasks): each frame's completion-test reward against every subtask goal (TCC: r(d))."""
        return distance_reward(goal_distances(embeddings, goals) * inest_distance_unit(model, goals), model.shaping)

    def shaping(self, batch: Batch) -> np.ndarray:
        raise NotImplementedError

    def inferred_stages(self, embeddings: np.ndarray) -> np.ndarray:
        """(N,) the subtask each frame is in, for a method that `infers_stage`."""
        raise NotImplementedError


class InestReward(LearnedReward):
    """Per `RewardConfig.shaping`: r(d) to the current subtask's goal (d rescaled, see
    ShapingConfig; "thesis") plus the bonus per completed subtask, the bonus alone once the last
    subtask is done; or bonus x (completed + where the frame sits between the current subtask's
    start and its goal) ("segment")."""

    name = "inest"

    def __init__(self, model: RewardModel, goals: SubtaskGoals, config: RewardConfig) -> None:
        super().__init__(model, goals, config)
        self.bonus = model.shaping.subtask_bonus
        self.uses_segments = config.shaping == "segment"

    def shaping(self, batch: Batch) -> np.ndarray:
        if self.uses_segments:  # the stage after this frame: continuous at a switch
            shaped, stage, live = self.bonus * batch.segments, batch.after, ~batch.done
        else:
            shaped, stage, live = batch.per_subtask, batch.before, ~batch.was_done
        shaping = np.zeros(len(stage))
        shaping[live] = shaped[np.flatnonzero(live), stage[live]]
        return shaping


class XirlReward(LearnedReward):
    """-scale * d to the single (final) goal embedding."""

    name = "xirl"
    single_goal = True

    @classmethod
    def check(cls, model: RewardModel, scheme: int) -> None:
        super().check(model, scheme)
        if scheme != 1:
            raise ModelError(f"the xirl reward has one goal embedding; it cannot use {scheme} subtasks")

    def shaping(self, batch: Batch) -> np.ndarray:
        return -self.goals.distance_scale * np.linalg.norm(batch.embeddings - self.goals.goals[-1], axis=1)


class HoldrReward(LearnedReward):
    """-max(0, d(s, g) - d(g, g)) / T with d the predicted steps to the goal, T the horizon."""

    name = "holdr"
    model_kind = "holdr"
    single_goal = True

    @staticmethod
    def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
        horizon = model.network.config.steps_unit
        columns = []
        for goal in goals.goals:
            to_goal = model.holdr_steps(embeddings, goal)
            columns.append(-np.maximum(0.0, to_goal - model.holdr_steps_at_goal(goal)) / horizon)
        return np.stack(columns, axis=1)

    def shaping(self, batch: Batch) -> np.ndarray:
        return batch.per_subtask[:, -1].astype(np.float64)


class RedsReward(LearnedReward):
    """REDS (no CLIP, reds.py): R(frame, z_k) for the subtask k the frame is in, k inferred by REDS
    itself on every frame (the subtask embedding most cosine-similar to the frame's feature, biased
    towards earlier subtasks); no bonus. The trackers of RewardConfig are not used: REDS needs
    "no thresholds or distance calculations" (thesis 5.2.4), so the stage the scorer reports is
    the inferred subtask. With stage_source "privileged" (a diagnostic) the true subtask is used."""

    name = "reds"
    model_kind = "reds"
    infers_stage = True

    @staticmethod
    def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
        return model.reds_rewards(embeddings, goals.goals)

    def shaping(self, batch: Batch) -> np.ndarray:
        return batch.per_subtask[np.arange(len(batch.after)), batch.after].astype(np.float64)

    def inferred_stages(self, embeddings: np.ndarray) -> np.ndarray:
        return self.model.reds_subtasks(embeddings, self.goals.goals)


REWARD_METHODS: dict[str, type[LearnedReward]] = {
    method.name: method for method in (InestReward, XirlReward, HoldrReward, RedsReward)
}


def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
    """(N, subtasks): each frame's completion-test reward against every subtask goal, by the
    model's own method (what calibration sets the thresholds on)."""
    return REWARD_METHODS[default_variant(model, len(goals.goals))].subtask_rewards(model, embeddings, goals)
