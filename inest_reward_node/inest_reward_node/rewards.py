"""Per-frame learned rewards of the three methods, and replaying a frame sequence through the tracker.

Each reward variant (inest, xirl, holdr, reds) is one class in `REWARDS`, chosen once by name: what the
scorer calls per batch of embeddings, in the manner of the `imitation` library's reward functions.
Which subtask a frame is in comes from `RewardConfig.tracker` (the thesis's threshold counter,
the same with reopening, or the learned stage classifier) or, as a diagnostic only, from the
simulator's true progress (`stage_source="privileged"`); a variant that infers the subtask itself
(reds: `infers_stage`) replaces the tracker with its own inference. Completion thresholds live on
each method's own per-subtask reward: r(d) for TCC models, the HOLD-R reward for HOLD-R models,
R(frame, z_k) for REDS models (calibrated like the others, used only by a tracker on request).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from typing import NamedTuple

import numpy as np

from .intrinsic import IntrinsicConfig, NoveltyMemory
from .model import ModelError, RewardModel, SubtaskGoals
from .shaping import SubtaskTracker, distance_reward
from .stages import (
    ClassifierTracker,
    ConfirmedTracker,
    InferredStage,
    PrivilegedStage,
    ReopeningTracker,
    RewardConfig,
    StageTracker,
    privileged_stages,
    progress_states,
    segment_closeness,
)

THESIS_REWARD = RewardConfig(shaping="thesis", tracker="threshold")  # the reward as the thesis has it


def default_variant(model: RewardModel, scheme: int) -> str:
    if model.method in ("holdr", "reds"):
        return model.method
    return "xirl" if scheme == 1 else "inest"


def inest_distance_unit(model: RewardModel, goals: SubtaskGoals) -> float:
    """Factor from raw embedding distance to the units r(d) is applied in (see ShapingConfig.start_distance)."""
    return goals.distance_scale * model.shaping.start_distance


def goal_distances(embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
    """(N, subtasks): raw embedding distance of each frame to every subtask goal."""
    return np.linalg.norm(np.asarray(embeddings)[:, None, :] - goals.goals[None], axis=-1)


def closeness(distances: np.ndarray, start_distances: np.ndarray) -> np.ndarray:
    """Per-subtask progress in [0, 1]: 1 - min(1, d_k / d_k_start)."""
    return 1.0 - np.minimum(1.0, np.asarray(distances) / np.asarray(start_distances))


class Batch(NamedTuple):
    """A batch as the variants see it, per row, with the tracker's subtask and doneness before and after it."""

    per_subtask: np.ndarray
    embeddings: np.ndarray
    segments: np.ndarray | None
    before: np.ndarray
    was_done: np.ndarray
    after: np.ndarray
    done: np.ndarray


class LearnedReward:
    """One reward variant. The scorer calls `subtask_rewards` on a batch of embeddings (what the trackers
    test) and, once the trackers have taken the batch, `distance`: each frame's reward without the
    subtask bonus, `bonus` per completed subtask."""

    name: str
    method = "tcc"  # the kind of model the variant needs
    uses_segments = False  # whether `distance` needs each frame's segment closeness
    infers_stage = False  # whether the variant says which subtask a frame is in (`inferred_stages`)
    bonus = 0.0

    def __init__(self, model: RewardModel, goals: SubtaskGoals, config: RewardConfig) -> None:
        self.model, self.goals, self.config = model, goals, config

    @classmethod
    def check(cls, model: RewardModel, scheme: int) -> None:
        if model.method != cls.method:
            raise ModelError(f"the {cls.name} reward needs a {cls.method} model, not {model.method}")

    @staticmethod
    def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
        """(N, subtasks): each frame's completion-test reward against every subtask goal (TCC: r(d))."""
        return distance_reward(goal_distances(embeddings, goals) * inest_distance_unit(model, goals), model.shaping)

    def distance(self, batch: Batch) -> np.ndarray:
        raise NotImplementedError

    def inferred_stages(self, embeddings: np.ndarray) -> np.ndarray:
        """(N,) the subtask each frame is in, for a variant that `infers_stage`."""
        raise NotImplementedError


class InestReward(LearnedReward):
    """Per `RewardConfig.shaping` (stages.py): r(d) to the current subtask's goal (d rescaled, see
    ShapingConfig; "thesis") or raw ("raw"), plus the bonus per completed subtask, the bonus alone once
    the last subtask is done; or per-subtask progress, bonus x (completed + closeness to the current
    goal) ("progress": by the distance to the goal; "segment": by where the frame sits between the
    subtask's start and its goal)."""

    name = "inest"

    def __init__(self, model: RewardModel, goals: SubtaskGoals, config: RewardConfig) -> None:
        super().__init__(model, goals, config)
        self.bonus = model.shaping.subtask_bonus
        self.uses_segments = config.shaping == "segment"
        self.start_distances = None
        if config.shaping == "progress":
            self.start_distances = np.asarray(goals.require_start_distances(), dtype=np.float64)

    def distance(self, batch: Batch) -> np.ndarray:
        shaping = self.config.shaping
        if shaping == "thesis":
            shaped = batch.per_subtask
        elif shaping == "segment":
            shaped = self.bonus * batch.segments
        elif shaping == "raw":
            shaped = distance_reward(goal_distances(batch.embeddings, self.goals), self.model.shaping)
        else:
            shaped = self.bonus * closeness(goal_distances(batch.embeddings, self.goals), self.start_distances)
        if shaping in ("progress", "segment"):  # the stage after this frame: continuous at a switch
            stage, live = batch.after, ~batch.done
        else:
            stage, live = batch.before, ~batch.was_done
        distance = np.zeros(len(stage))
        distance[live] = shaped[np.flatnonzero(live), stage[live]]
        return distance


class XirlReward(LearnedReward):
    """-scale * d to the single (final) goal embedding."""

    name = "xirl"

    @classmethod
    def check(cls, model: RewardModel, scheme: int) -> None:
        super().check(model, scheme)
        if scheme != 1:
            raise ModelError(f"the xirl reward has one goal embedding; it cannot use {scheme} subtasks")

    def distance(self, batch: Batch) -> np.ndarray:
        return -self.goals.distance_scale * np.linalg.norm(batch.embeddings - self.goals.goals[-1], axis=1)


class HoldrReward(LearnedReward):
    """-max(0, d(s, g) - d(g, g)) / T with d the predicted steps to the goal, T the horizon."""

    name = "holdr"
    method = "holdr"

    @staticmethod
    def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
        horizon = model.network.config.steps_unit
        columns = []
        for goal in goals.goals:
            to_goal = model.holdr_steps(embeddings, goal)
            columns.append(-np.maximum(0.0, to_goal - model.holdr_steps_at_goal(goal)) / horizon)
        return np.stack(columns, axis=1)

    def distance(self, batch: Batch) -> np.ndarray:
        return batch.per_subtask[:, -1].astype(np.float64)


class RedsReward(LearnedReward):
    """REDS (no CLIP, reds.py): R(frame, z_k) for the subtask k the frame is in, k inferred by REDS
    itself on every frame (the subtask embedding most cosine-similar to the frame's feature, biased
    towards earlier subtasks); no bonus. The trackers of RewardConfig are not used: REDS needs
    "no thresholds or distance calculations" (thesis 5.2.4), so the stage the scorer reports is
    the inferred subtask. With stage_source "privileged" (a diagnostic) the true subtask is used."""

    name = "reds"
    method = "reds"
    infers_stage = True

    @staticmethod
    def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
        return model.reds_rewards(embeddings, goals.goals)

    def distance(self, batch: Batch) -> np.ndarray:
        return batch.per_subtask[np.arange(len(batch.after)), batch.after].astype(np.float64)

    def inferred_stages(self, embeddings: np.ndarray) -> np.ndarray:
        return self.model.reds_subtasks(embeddings, self.goals.goals)


REWARDS: dict[str, type[LearnedReward]] = {
    reward.name: reward for reward in (InestReward, XirlReward, HoldrReward, RedsReward)
}


def subtask_rewards(model: RewardModel, embeddings: np.ndarray, goals: SubtaskGoals) -> np.ndarray:
    """(N, subtasks): each frame's completion-test reward against every subtask goal."""
    return REWARDS[default_variant(model, len(goals.goals))].subtask_rewards(model, embeddings, goals)


@dataclass
class RewardParts:
    """One scored batch: per environment, the reward and what it is made of."""

    total: np.ndarray  # (N,) what the agent receives
    distance: np.ndarray  # (N,) the method's per-frame reward (INEST: shaping term of the current goal; 0 once done)
    bonus: np.ndarray  # (N,) subtask bonus (INEST: completed subtasks x bonus)
    intrinsic: np.ndarray  # (N,) weighted novelty bonus
    subtask: np.ndarray  # (N,) current subtask index after this frame
    completed: np.ndarray  # (N,) subtasks completed after this frame: the stage the policy should see (may drop)
    switched: np.ndarray  # (N,) bool, this frame completed a subtask (an upward switch only)
    embeddings: np.ndarray  # (N, D) the frames' embeddings, for coverage analysis

    def select(self, rows: slice | np.ndarray) -> RewardParts:
        return RewardParts(*(getattr(self, field.name)[rows] for field in fields(self)))


class RewardScorer:
    """The learned reward for N environments at once, with per-environment subtask trackers and
    per-subtask novelty memories shared by all of them.

    `score(frames)` embeds all N frames in one forward pass. `reset(i)` starts environment i's
    next episode: its tracker restarts, the exploration memories are kept. `config` (None: the
    RewardConfig defaults) chooses shaping, tracker and stage source; THESIS_REWARD is the
    thesis's reward exactly. With `stage_source="privileged"` (a diagnostic) every scored frame
    needs its state vector.
    """

    def __init__(
        self,
        model: RewardModel,
        scheme: int,
        variant: str | None = None,
        intrinsic: IntrinsicConfig | None = None,
        num_envs: int = 1,
        config: RewardConfig | None = None,
    ) -> None:
        self.model = model
        self.variant = variant or default_variant(model, scheme)
        if self.variant not in REWARDS:
            raise ValueError(f"unknown reward variant {self.variant!r}; expected one of {tuple(REWARDS)}")
        REWARDS[self.variant].check(model, scheme)
        self.goals = model.goals(scheme)
        self.scheme = scheme
        self.config = config = config or RewardConfig()
        self.intrinsic = intrinsic or IntrinsicConfig(mode="none")
        self.hold_steps = config.hold_steps or model.shaping.hold_steps
        if config.stage_source == "privileged" and scheme not in (1, 3):
            raise ValueError(
                f"stage_source 'privileged' (a diagnostic) knows the true stage of the 1- and 3-subtask "
                f"schemes only, not {scheme}"
            )
        self.reward = REWARDS[self.variant](model, self.goals, config)
        # the variant's own subtask inference replaces the tracker (not the privileged diagnostic)
        self.infers_stage = self.reward.infers_stage and config.stage_source == "tracker"
        tracks = not self.infers_stage
        self.start_embeddings = None
        if self.reward.uses_segments or (config.reopens and tracks):
            self.start_embeddings = self.goals.require_start_embeddings()
        self.classifier = self.stage_head = None
        evidence = config.stage_evidence  # "auto": the pixel stage head if the model has one
        if evidence == "auto":
            evidence = "pixels" if self.goals.stage_head is not None else "embedding"
        if tracks and config.uses_classifier and evidence == "pixels":
            self.stage_head = self.goals.require_stage_head()
        elif tracks and config.uses_classifier:
            self.classifier = self.goals.require_stage_classifier()
        # what the tracker reads its stage from: "pixels", "embedding", or None (no classifier)
        self.evidence = "pixels" if self.stage_head else "embedding" if self.classifier else None
        # the camera the stage head reads when it is not the encoder's (StageHeadConfig.view)
        head_view = self.stage_head.config.view if self.stage_head else None
        self.stage_camera = head_view if head_view not in (None, model.view) else None
        stage_model = self.classifier or self.stage_head
        if stage_model is not None and stage_model.num_stages != self.num_subtasks + 1:
            raise ModelError(
                f"the stage classifier predicts {stage_model.num_stages} stages, "
                f"not the {self.num_subtasks + 1} of {scheme} subtasks"
            )
        self.trackers: list[SubtaskTracker | StageTracker] = [self.new_tracker() for _ in range(num_envs)]
        self.steps_since_switch = np.full(num_envs, -1)
        self.memories: list[NoveltyMemory] = []

    def new_tracker(self) -> SubtaskTracker | StageTracker:
        config, thresholds = self.config, self.goals.thresholds
        if config.stage_source == "privileged":
            return PrivilegedStage(len(thresholds))
        if self.infers_stage:
            return InferredStage(len(thresholds))
        if config.tracker == "classifier":
            return ClassifierTracker(len(thresholds), self.hold_steps, config.stage_confidence)
        if config.tracker == "confirmed":
            return ConfirmedTracker(
                thresholds,
                self.hold_steps,
                config.stage_confidence,
                config.confirm_window,
                config.confirm_steps,
                config.instant_confidence,
            )
        if config.tracker == "reopening":
            return ReopeningTracker(thresholds, self.hold_steps)
        return SubtaskTracker(thresholds, self.hold_steps)

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

    def score(
        self, frames: np.ndarray, states: np.ndarray | None = None, stage_frames: np.ndarray | None = None
    ) -> RewardParts:
        """frames: (N, H, W, 3) uint8, one per environment, in environment order; `stage_frames`
        the same steps seen by `stage_camera` when the stage head reads another camera."""
        return self.score_frames(frames, states, stage_frames=stage_frames)

    def score_frames(
        self,
        frames: np.ndarray,
        states: np.ndarray | None = None,
        envs: np.ndarray | None = None,
        rounds: np.ndarray | None = None,
        episode_ends: np.ndarray | None = None,
        stage_frames: np.ndarray | None = None,
    ) -> RewardParts:
        """`score_embeddings` of the frames' embeddings, with the pixel stage head's evidence when
        the tracker reads it (RewardConfig.stage_evidence). `stage_frames`: the same steps seen by
        the stage head's camera, needed when it is not the encoder's (`stage_camera`)."""
        if self.stage_camera is None:
            stage_frames = frames
        elif stage_frames is None or len(stage_frames) != len(frames):
            raise ValueError(f"the stage head reads the {self.stage_camera!r} camera: pass its frame of every step")
        evidence = self.stage_evidence(stage_frames)
        return self.score_embeddings(self.model.embed(frames), states, envs, rounds, episode_ends, evidence)

    def stage_evidence(self, frames: np.ndarray) -> np.ndarray | None:
        """(N, K + 1) P(stage >= j) of each frame (of the head's camera) from the pixel stage
        head; None when not used."""
        return None if self.stage_head is None else self.stage_head.at_least(frames)

    def score_embeddings(
        self,
        embeddings: np.ndarray,
        states: np.ndarray | None = None,
        envs: np.ndarray | None = None,
        rounds: np.ndarray | None = None,
        episode_ends: np.ndarray | None = None,
        stage_evidence: np.ndarray | None = None,
    ) -> RewardParts:
        """Without `envs`, one embedding per environment in order. With it, row i belongs to
        environment envs[i] and is taken in order. `rounds` (ascending) groups the rows into
        vector steps: a later round's frames are judged against novelty memories holding the
        earlier rounds' frames, as if scored one call per round, with one search for all.
        `episode_ends[i]`: envs[i] starts a new episode after row i. `stage_evidence`: the
        frames' `stage_evidence`, which a tracker reading the pixel stage head needs."""
        per_subtask = self.reward.subtask_rewards(self.model, embeddings, self.goals)
        return self.advance(per_subtask, embeddings, states, envs, rounds, episode_ends, stage_evidence)

    def advance(
        self,
        per_subtask: np.ndarray,
        embeddings: np.ndarray,
        states: np.ndarray | None,
        envs: np.ndarray | None = None,
        rounds: np.ndarray | None = None,
        episode_ends: np.ndarray | None = None,
        stage_evidence: np.ndarray | None = None,
    ) -> RewardParts:
        """Move the frames' trackers on, given each frame's reward against every subtask goal
        (subtask_rewards: what the threshold tests and the thesis shaping use)."""
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
        config = self.config
        # the whole batch's evidence at once; the trackers then take it row by row, in order
        segments = None
        if self.start_embeddings is not None:
            from_start = np.linalg.norm(np.asarray(embeddings)[:, None, :] - self.start_embeddings[None], axis=-1)
            segments = segment_closeness(goal_distances(embeddings, self.goals), from_start)
        at_least = self.classifier.at_least(embeddings) if self.classifier is not None else None
        if self.stage_head is not None:
            if stage_evidence is None or len(stage_evidence) != len(envs):
                raise ValueError("the pixel stage head's tracker needs every frame's stage_evidence (score_frames)")
            at_least = stage_evidence
        true_stage = privileged_stages(states, self.scheme) if config.stage_source == "privileged" else None
        if self.infers_stage:
            true_stage = self.reward.inferred_stages(embeddings)  # what the variant's InferredStage trackers take
        if true_stage is not None and len(true_stage) != len(envs):
            raise ValueError(f"expected one state vector per frame ({len(envs)}), got {len(true_stage)}")
        count = len(envs)
        before, subtask, completed, since_switch = (np.zeros(count, int) for _ in range(4))
        was_done, done, switched = (np.zeros(count, bool) for _ in range(3))
        for row, (env, rewards) in enumerate(zip(envs, per_subtask, strict=True)):
            tracker = self.trackers[env]
            before[row], was_done[row] = tracker.current, tracker.done
            since_switch[row] = self.steps_since_switch[env]
            if isinstance(tracker, SubtaskTracker):
                change = int(tracker.update(rewards[before[row]]))
            elif isinstance(tracker, ConfirmedTracker):
                change = tracker.step(rewards, segments[row], at_least[row])
            elif isinstance(tracker, ReopeningTracker):
                change = tracker.step(rewards, segments[row])
            elif isinstance(tracker, ClassifierTracker):
                change = tracker.step(at_least[row])
            else:
                change = tracker.step(true_stage[row])
            switched[row] = change > 0
            subtask[row], completed[row], done[row] = tracker.current, tracker.completed, tracker.done
            if switched[row]:
                self.steps_since_switch[env] = 0
            elif self.steps_since_switch[env] >= 0:
                self.steps_since_switch[env] += 1
            if ends[row]:
                self.reset(env)
        distance = self.reward.distance(Batch(per_subtask, embeddings, segments, before, was_done, subtask, done))
        bonus = completed * self.reward.bonus
        # novelty is judged within the subtask the frame was taken in
        intrinsic = self.intrinsic_bonus(embeddings, states, before, since_switch, rounds)
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
        """Weighted novelty of each frame in its subtask's memory, clipped at RewardConfig.intrinsic_cap;
        frames of a later round (step) are judged against a memory holding the earlier rounds' frames."""
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
        return np.minimum(config.weight_after(since_switch) * novelty, self.config.cap)


@dataclass
class Replay:
    """One episode fed, frame by frame in order, through a fresh `RewardScorer`: what its scorer
    returned for every frame (`parts`), with the views the reports read."""

    parts: RewardParts  # every frame's reward and what it is made of, in frame order
    num_subtasks: int

    @property
    def rewards(self) -> np.ndarray:
        """(N,) the reward the agent would receive on each frame (RewardParts.total)."""
        return self.parts.total

    @property
    def distance(self) -> np.ndarray:
        """(N,) the shaping term: the reward without subtask bonus and intrinsic bonus."""
        return self.parts.distance

    @property
    def bonus(self) -> np.ndarray:
        """(N,) the subtask bonus (INEST: completed subtasks x bonus)."""
        return self.parts.bonus

    @property
    def subtask(self) -> np.ndarray:
        """(N,) the tracker's current subtask on each frame (after the update)."""
        return self.parts.subtask

    @property
    def completed(self) -> np.ndarray:
        """(N,) subtasks completed so far."""
        return self.parts.completed

    def completion_events(self, subtask: int) -> list[int]:
        """Every frame on which the tracker marked `subtask` done: `completed` rose past it there.
        One frame for a latched tracker; a tracker that reopens subtasks may mark one done again."""
        done = self.parts.completed > subtask
        return np.flatnonzero(done & ~np.concatenate([[False], done[:-1]])).tolist()

    @property
    def completion_frames(self) -> list[int]:
        """For each subtask in order, the frame on which the tracker first marked it done (for a latched
        tracker: its switches), up to the first subtask it never completed."""
        frames = []
        for subtask in range(self.num_subtasks):
            events = self.completion_events(subtask)
            if not events:
                break
            frames.append(events[0])
        return frames

    @property
    def all_completed(self) -> bool:
        """The tracker marked every subtask done at some frame."""
        return len(self.completion_frames) == self.num_subtasks


def replay(
    model: RewardModel,
    embeddings: np.ndarray,
    scheme: int,
    variant: str | None = None,
    scorer_options: dict[str, object] | None = None,
    frames: np.ndarray | None = None,
    progress: np.ndarray | None = None,
) -> Replay:
    """Feed one episode's embeddings, in order, through a fresh scorer: `RewardScorer(model,
    scheme, variant, **scorer_options)` (no intrinsic bonus unless the options ask for one),
    all frames in one `score_embeddings` call as rows of environment 0, one round per frame.
    `frames` (the episode through the stage head's camera: the images the embeddings came from,
    or the scene camera's when the head reads that, `RewardScorer.stage_camera`) give a tracker
    that reads the pixel stage head its evidence; it refuses to replay without them. `progress`
    (ordered blocks placed, per frame) gives the privileged-stage diagnostic its true stage."""
    scorer = RewardScorer(model, scheme, variant, **(scorer_options or {}))
    count = len(embeddings)
    evidence = None if frames is None else scorer.stage_evidence(np.asarray(frames))
    privileged = progress is not None and scorer.config.stage_source == "privileged"
    parts = scorer.score_embeddings(
        np.asarray(embeddings),
        progress_states(progress) if privileged else None,
        envs=np.zeros(count, dtype=int),
        rounds=np.arange(count),
        stage_evidence=evidence,
    )
    return Replay(parts, scorer.num_subtasks)
