"""The embedding's stage classifier fitted again during training on frames a robot can get: the
agent's own unconfirmed claims (self_negatives.py, no labels) and its own episodes labelled in
the loop (labelled_rollouts.py, a person's labels).

Each refit fits the classifier on a sample of the demonstrations, the labelled negative episodes
the model was calibrated on (its random and wrong-order play, made again from their seeds, and
its clip files: a person's labels are not thrown away) and both sources' frames so far. The
labelled episodes also raise the completion thresholds (unless `label_raise_thresholds` is
off), as calibration raises them against random play (learning/calibrate.py
`raised_threshold`): the embedding alone does not tell a policy's false completions from true
ones, the thresholds do (docs/reports/robot-reward.md). The training and evaluation rewards read the
result from the next step on, and the model it makes is saved in RUN/reward-model/, which
`inest-evaluate` then scores with, its supervision record counting what it was fitted on.
Embedding stage evidence only (the pixel stage head takes minutes to fit).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from ..runtime.model import RewardModel, SubtaskGoals, save_model
from ..runtime.rewards import RewardParts, RewardScorer, Steps
from .calibrate import raised_threshold
from .clips import Clip, load_clips, random_play, wrong_order_play
from .config import CalibrationConfig
from .data import load_demos
from .labelled_rollouts import RolloutLabelling
from .self_negatives import SelfNegatives
from .stage_fitting import StageClassifierConfig, fit_stage_classifier
from .task_stages import demo_stages, true_stages

REFIT_MODEL_DIR = "reward-model"
DEMOS = 200  # training demonstrations whose frames the refit keeps the classifier anchored to
# the calibration settings that raise a threshold against labelled episodes (CalibrationConfig)
RAISING = ("false_fire_rate", "demo_pass_rate", "late_frames")


@dataclasses.dataclass(frozen=True)
class RefitFrames:
    """What one refit read of the agent's own episodes."""

    self_negatives: int  # unlabelled frames
    labelled_episodes: int  # the agent's episodes labelled in the loop


class StageRefit:
    """Feeds every scored step to the sources in use and refits the classifier on them."""

    def __init__(
        self,
        scorer: RewardScorer,
        dataset: str | Path,
        self_negatives: SelfNegatives | None,
        labelling: RolloutLabelling | None,
        raise_thresholds: bool = True,
    ) -> None:
        if scorer.classifier is None:
            raise ValueError("a stage refit fits the embedding's stage classifier: use stage_evidence embedding")
        self.scorer, self.self_negatives, self.labelling = scorer, self_negatives, labelling
        self.raise_thresholds = raise_thresholds  # with the labelled episodes (the loop's)
        model, scheme = scorer.model, scorer.num_subtasks
        demos = load_demos(dataset, "train", model.view, model.image_size, DEMOS, progress_bar=False)
        self.demo_embeddings = [model.embed(demo.frames) for demo in demos]
        self.demo_stages = [demo_stages(demo.progress, demo.labels[scheme], scheme) for demo in demos]
        self.demo_ends = [demo.ends[scheme] for demo in demos]
        labelled = calibration_negatives(model)
        self.labelled_embeddings = [model.embed(clip.frames) for clip in labelled]
        self.labelled_stages = [true_stages(clip.progress, clip.held, scheme) for clip in labelled]
        self.refits = 0

    def observe(self, steps: Steps, parts: RewardParts) -> None:
        """One scored batch (RewardVecEnv.scored_hook)."""
        if self.self_negatives is not None:
            self.self_negatives.observe(steps.envs, parts, steps.episode_ends)
        if self.labelling is not None:
            self.labelling.observe(steps, parts)

    def refit(self, run_dir: Path, readers: list[RewardScorer]) -> RefitFrames:
        """Fit the classifier on the demonstrations, the labelled episodes and the agent's frames
        so far, give it to `readers` (the training and evaluation rewards) and save the model it
        makes; nothing when there are none of the agent's frames yet."""
        negatives = list(self.self_negatives.negatives) if self.self_negatives is not None else []
        episodes = self.labelling.episodes if self.labelling is not None else []
        frames = RefitFrames(len(negatives), len(episodes))
        if not negatives and not episodes:
            return frames
        own_embeddings = [embeddings for embeddings, _ in episodes]
        own_stages = [stages for _, stages in episodes]
        if negatives:
            own_embeddings.append(np.stack([embedding for embedding, _ in negatives]))
            own_stages.append(np.array([stage for _, stage in negatives]))
        classifier = fit_stage_classifier(
            self.demo_embeddings,
            self.demo_stages,
            self.scorer.num_subtasks + 1,
            [*self.labelled_embeddings, *own_embeddings],
            [*self.labelled_stages, *own_stages],
            StageClassifierConfig(seed=self.refits),
        )
        goals = self.scorer.model.goals(self.scorer.num_subtasks)  # as calibrated: each refit starts from it
        goals = dataclasses.replace(
            goals, stage_classifier=classifier, thresholds=self.raised_thresholds(goals, episodes)
        )
        for reader in readers:
            reader.use_goals(goals)
        self.refits += 1
        if self.labelling is not None:
            self.labelling.refitted_with = len(episodes)
            if episodes:
                self.labelling.save(run_dir)
        save_refitted(self.scorer.model, goals, frames, run_dir / REFIT_MODEL_DIR)
        return frames

    def raised_thresholds(self, goals: SubtaskGoals, episodes: list[tuple[np.ndarray, np.ndarray]]) -> list[float]:
        """The calibrated thresholds raised against the labelled episodes of the loop, as the
        model's calibration raised them against its random play (its own settings)."""
        if not episodes or not self.raise_thresholds:
            return list(goals.thresholds)
        model, hold_steps = self.scorer.model, self.scorer.hold_steps
        settings = {name: model.metadata.calibration[name] for name in RAISING if name in model.metadata.calibration}
        calibration = dataclasses.replace(CalibrationConfig(), **settings)
        rewards = [self.scorer.subtask_rewards(embeddings, goals) for embeddings in self.demo_embeddings]
        played = [(self.scorer.subtask_rewards(embeddings, goals), stages) for embeddings, stages in episodes]
        return [
            raised_threshold(
                threshold,
                subtask,
                [(reward[:, subtask], ends) for reward, ends in zip(rewards, self.demo_ends, strict=True)],
                [np.where(stages <= subtask, reward[:, subtask], -np.inf) for reward, stages in played],
                hold_steps,
                calibration,
            )
            for subtask, threshold in enumerate(goals.thresholds)
        ]


def calibration_negatives(model: RewardModel) -> list[Clip]:
    """The labelled negative episodes the model's calibration was fitted on, as it recorded them."""
    calibration, size = model.metadata.calibration, model.image_size
    clips = random_play(model.view, size, calibration.get("random_episodes", 0))
    clips += wrong_order_play(model.view, size, calibration.get("wrong_order_episodes", 0))
    for path in calibration.get("clips", []):
        if not Path(path).is_file():
            raise ValueError(f"the model was calibrated on the clip file {path}, which is not here to refit with")
        clips += load_clips(path, model.view, size)
    return clips


def save_refitted(model: RewardModel, refitted: SubtaskGoals, frames: RefitFrames, folder: Path) -> None:
    """The model with one scheme's goals replaced by their refit, its supervision saying what by."""
    metadata = model.metadata
    goals = {**metadata.subtasks, len(refitted.thresholds): refitted}
    supervision = dict(metadata.supervision)
    if supervision:
        negatives = dict(supervision["negatives"])
        if frames.self_negatives:
            negatives["self_negatives"] = {
                "frames": frames.self_negatives,
                "labelled_by": "nobody: the stage the tracker kept",
            }
        if frames.labelled_episodes:
            negatives["policy_rollouts"] = {"episodes": frames.labelled_episodes, "labelled_by": "simulator"}
            for count in ("labelled_episodes", "simulator_labelled_episodes"):
                supervision[count] = supervision[count] + frames.labelled_episodes
        supervision["negatives"] = negatives
    save_model(folder, model.network, dataclasses.replace(metadata, subtasks=goals, supervision=supervision))
