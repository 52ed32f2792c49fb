"""Negatives that need no labels: the agent's own frames that claim a stage the way the
demonstrations never reach it, refitted into the stage classifier during training.

A frame whose single-frame stage classifier says "stage c + 1 or more" while the reward's
tracker, reading the stage over time (its confirmation, and the forward filter when
`learned_reward.stage_filter` is on), stays at c for the next CONFIRM_WITHIN frames is a frame
the policy reaches otherwise than the demonstrations reach stage c + 1: it is kept as a
negative labelled c, as PROGRESSOR and Rank2Reward push down the agent's frames where they
claim progress the demonstrations make differently. Every `refit_every` steps the classifier is
fitted again on a sample of the demonstrations, the labelled negative episodes the model was
calibrated on (its random and wrong-order play, made again from their seeds, and its clip
files: a person's labels are not thrown away) and these frames, and the training and
evaluation rewards read it from the next step on; the model it makes is saved in
RUN/reward-model/, which `inest-evaluate` then scores with. Embedding stage evidence only (the
pixel stage head takes minutes to fit).
"""

from __future__ import annotations

import dataclasses
from collections import deque
from pathlib import Path
from typing import NamedTuple

import numpy as np
from inest_reward_node.learning.clips import Clip, load_clips, random_play, wrong_order_play
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.stage_fitting import StageClassifierConfig, fit_stage_classifier
from inest_reward_node.learning.task_stages import demo_stages, true_stages
from inest_reward_node.runtime.model import RewardModel, save_model
from inest_reward_node.runtime.rewards import RewardParts, RewardScorer
from inest_reward_node.runtime.stage_classifier import StageClassifier

REFIT_MODEL_DIR = "reward-model"
CONFIRM_WITHIN = 10  # frames a claim has to be confirmed in before it counts as a negative
CAPACITY = 20_000  # negatives kept, newest first
DEMOS = 200  # training demonstrations whose frames the refit keeps the classifier anchored to


class Claim(NamedTuple):
    """A frame whose classifier claimed more than the tracker's stage, waiting to be confirmed."""

    frame: int  # its frame of the episode
    embedding: np.ndarray
    stage: int  # what the classifier claimed
    kept: int  # the tracker's stage then: the label if the claim is never confirmed


class SelfNegatives:
    """Collects the agent's unconfirmed claims from every scored step and refits the classifier."""

    def __init__(self, scorer: RewardScorer, dataset: str | Path, num_envs: int) -> None:
        if scorer.classifier is None:
            raise ValueError("self negatives refit the embedding's stage classifier: use stage_evidence embedding")
        self.scorer = scorer
        model, scheme = scorer.model, scorer.num_subtasks
        demos = load_demos(dataset, "train", model.view, model.image_size, DEMOS, progress_bar=False)
        self.demo_embeddings = [model.embed(demo.frames) for demo in demos]
        self.demo_stages = [demo_stages(demo.progress, demo.labels[scheme], scheme) for demo in demos]
        labelled = calibration_negatives(model)
        self.labelled_embeddings = [model.embed(clip.frames) for clip in labelled]
        self.labelled_stages = [true_stages(clip.progress, clip.held, scheme) for clip in labelled]
        self.waiting: list[deque[Claim]] = [deque() for _ in range(num_envs)]
        self.frames = [0] * num_envs  # frames seen per environment in its episode
        self.negatives: deque[tuple[np.ndarray, int]] = deque(maxlen=CAPACITY)
        self.refits = 0

    def observe(self, envs: np.ndarray, parts: RewardParts, episode_ends: np.ndarray) -> None:
        """One scored batch (rows in environment order within each round)."""
        claimed = (self.scorer.classifier.at_least(parts.embeddings) >= 0.5).sum(axis=1) - 1
        for row, env in enumerate(envs):
            self.frames[env] += 1
            frame, stage, waiting = self.frames[env], int(parts.completed[row]), self.waiting[env]
            while waiting and (stage >= waiting[0].stage or frame - waiting[0].frame > CONFIRM_WITHIN):
                claim = waiting.popleft()
                if stage < claim.stage:  # never confirmed in time: the stage the tracker kept is its label
                    self.negatives.append((claim.embedding, claim.kept))
            if claimed[row] > stage:
                waiting.append(Claim(frame, parts.embeddings[row].copy(), int(claimed[row]), stage))
            if episode_ends[row]:
                waiting.clear()
                self.frames[env] = 0

    def refit(self, run_dir: Path, readers: list[RewardScorer]) -> int:
        """Fit the classifier on the demonstrations and the negatives so far, give it to `readers`
        (the training and evaluation rewards) and save the model it makes; the negatives' count."""
        if not self.negatives:
            return 0
        embeddings = np.stack([embedding for embedding, _ in self.negatives])
        stages = np.array([stage for _, stage in self.negatives])
        classifier = fit_stage_classifier(
            self.demo_embeddings,
            self.demo_stages,
            self.scorer.num_subtasks + 1,
            [*self.labelled_embeddings, embeddings],
            [*self.labelled_stages, stages],
            StageClassifierConfig(seed=self.refits),
        )
        for reader in readers:
            reader.classifier = classifier
        self.refits += 1
        save_refitted(self.scorer.model, self.scorer.num_subtasks, classifier, len(stages), run_dir / REFIT_MODEL_DIR)
        return len(stages)


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


def save_refitted(model: RewardModel, scheme: int, classifier: StageClassifier, negatives: int, folder: Path) -> None:
    """The model with `scheme`'s stage classifier replaced, its supervision saying what by."""
    metadata = model.metadata
    goals = {**metadata.subtasks, scheme: dataclasses.replace(metadata.subtasks[scheme], stage_classifier=classifier)}
    supervision = dict(metadata.supervision)
    if supervision:
        supervision["negatives"] = {
            **supervision["negatives"],
            "self_negatives": {"frames": negatives, "labelled_by": "nobody: the stage the tracker kept"},
        }
    save_model(folder, model.network, dataclasses.replace(metadata, subtasks=goals, supervision=supervision))
