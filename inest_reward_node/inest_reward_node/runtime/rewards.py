"""Scoring frames with a learned reward: the one interface every reward implements
(`RewardFunction`), the learned rewards' scorer (`RewardScorer`) and replaying an episode.

`RewardFunction` is what the training environments, the gymnasium wrapper and the reward node
call, whoever computes the reward: `reset(env_indices)` starts new episodes, `score(frames,
stage_frames, steps)` scores one frame per environment. `RewardScorer` implements it for every method of
methods.py; the stage comes from a tracker of trackers.py, chosen by `RewardConfig`, or, as a
diagnostic only, from the caller (`stage_source="privileged"`: `known_stages`); a method that
infers the subtask itself (reds) tells the tracker its own inference.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np

from .config import RewardConfig
from .intrinsic import IntrinsicConfig, NoveltyMemory
from .methods import REWARD_METHODS, Batch, default_variant, goal_distances, inest_distance_unit
from .model import ModelError, RewardModel, SubtaskGoals
from .reward_parts import RewardParts
from .shaping import segment_closeness
from .stage_classifier import at_least as at_least_of
from .stage_filter import StageFilter, exactly
from .stage_support import gate
from .trackers import TRACKERS, Evidence, StageTracker, ToldStage

THESIS_REWARD = RewardConfig(shaping="thesis", tracker="threshold")  # the reward as the thesis has it


@dataclass
class Steps:
    """What the caller knows of the scored frames besides their pixels; each reward reads what it
    needs and none needs all. Without `envs` the frames are one per environment, in order."""

    envs: np.ndarray | None = None  # row i belongs to environment envs[i]; an environment's rows in order
    rounds: np.ndarray | None = None  # ascending: the vector step of each row (see score_embeddings)
    episode_ends: np.ndarray | None = None  # envs[i] starts a new episode after row i
    states: np.ndarray | None = None  # the environments' state vectors (the state novelty bonus)
    known_stages: np.ndarray | None = None  # the true stage, where someone knows it (needs_known_stages)
    env_rewards: np.ndarray | None = None  # the environment's own reward (the oracle's)

    def rows(self, count: int, num_envs: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(envs, rounds, episode_ends) of `count` scored rows of `num_envs` environments, checked."""
        if self.envs is None and count != num_envs:
            raise ValueError(f"expected one frame per environment ({num_envs}), got {count}")
        envs = np.arange(num_envs) if self.envs is None else np.asarray(self.envs, dtype=int)
        if len(envs) != count or np.any((envs < 0) | (envs >= num_envs)):
            raise ValueError(f"environment indices {envs.tolist()} do not fit {count} frames")
        rounds = np.zeros(count, int) if self.rounds is None else np.asarray(self.rounds)
        if len(rounds) != count or np.any(np.diff(rounds) < 0):
            raise ValueError("rounds must give every frame its round, in ascending order")
        ends = np.zeros(count, bool) if self.episode_ends is None else np.asarray(self.episode_ends, dtype=bool)
        return envs, rounds, ends


@runtime_checkable
class RewardFunction(Protocol):
    """What every reward implements, so that whoever steps environments never asks which reward it
    holds: N environments (streams) at once, one frame each per step.

    `camera` names the camera whose frames `score` takes (None: it reads none), at best rendered
    `image_size` pixels square (frames of any size are resized), `stage_camera` a
    second camera whose frame of the same step it also needs (a scene camera beside the
    policy's), or None; `needs_known_stages` whether each step's true stage must be told
    (`Steps.known_stages`). `reset(env_indices)` starts new episodes in those environments (None:
    all). `score` takes the (N, H, W, 3) uint8 frames in environment order, `stage_frames` of
    `stage_camera` and what else is known of the steps, and returns the reward and its parts.
    `exploration_state` is what a resumed run must give back to `restore_exploration`."""

    num_envs: int
    num_subtasks: int
    camera: str | None
    image_size: int
    stage_camera: str | None
    needs_known_stages: bool

    def reset(self, env_indices: Iterable[int] | int | None = None) -> None: ...

    def score(
        self, frames: np.ndarray | None, stage_frames: np.ndarray | None = None, steps: Steps | None = None
    ) -> RewardParts: ...

    def exploration_state(self) -> dict[str, np.ndarray]: ...

    def restore_exploration(self, state: dict[str, np.ndarray]) -> None: ...


class RewardScorer:
    """A learned reward for N environments at once (a RewardFunction), with per-environment
    stage trackers and per-subtask novelty memories shared by all of them.

    `score(frames)` embeds all N frames in one forward pass. `reset(i)` starts environment i's
    next episode: its tracker restarts, the exploration memories are kept. `variant` names the
    method (methods.REWARD_METHODS; None: the model's own for `scheme`), `config` (None: the
    RewardConfig defaults) chooses shaping, tracker and stage source; THESIS_REWARD is the
    thesis's reward exactly. What a caller may read (the stage refit does): `model`, `goals`,
    `num_subtasks`, `hold_steps` (the frames a tracker's test must hold), `classifier` (the
    embedding's stage classifier, None when the stage evidence is another), `subtask_rewards`.
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
        if self.variant not in REWARD_METHODS:
            raise ValueError(f"unknown reward variant {self.variant!r}; expected one of {tuple(REWARD_METHODS)}")
        method = REWARD_METHODS[self.variant]
        method.check(model, scheme)
        self.goals = model.goals(scheme)
        self.config = config = config or RewardConfig()
        self.intrinsic = intrinsic or IntrinsicConfig(mode="none")
        self.hold_steps = config.hold_steps or model.shaping.hold_steps
        self.reward = method(model, self.goals, config)
        # who tells a ToldStage tracker the stage: the caller (the privileged diagnostic) or the method
        self.stage_teller = (
            "caller" if config.stage_source == "privileged" else "method" if method.infers_stage else None
        )
        self.tracker_class = ToldStage if self.stage_teller else TRACKERS[config.tracker]
        reads = self.tracker_class.reads
        self.start_embeddings = None
        if self.reward.uses_segments or "segments" in reads:
            self.start_embeddings = self.goals.require_start_embeddings()
        self.classifier = self.stage_head = self.window = None
        evidence = config.stage_evidence  # "auto": the pixel stage head if the model has one
        if evidence == "auto":
            evidence = "pixels" if self.goals.stage_head is not None else "embedding"
        if "at_least" in reads and evidence == "pixels":
            self.stage_head = self.goals.require_stage_head()
        elif "at_least" in reads and evidence == "window":
            self.window = self.goals.require_stage_window()
        elif "at_least" in reads:
            self.classifier = self.goals.require_stage_classifier()
        # what the tracker reads its stage from: "pixels", "embedding", "window", or None (no stage evidence)
        self.evidence = evidence if "at_least" in reads else None
        self.camera, self.image_size = model.view, model.image_size
        # the camera the stage head reads when it is not the encoder's (StageHeadConfig.view)
        head_view = self.stage_head.config.view if self.stage_head else None
        self.stage_camera = head_view if head_view not in (None, model.view) else None
        stage_model = self.classifier or self.stage_head or self.window
        if stage_model is not None and stage_model.num_stages != self.num_subtasks + 1:
            raise ModelError(
                f"the stage classifier predicts {stage_model.num_stages} stages, "
                f"not the {self.num_subtasks + 1} of {scheme} subtasks"
            )
        if config.stage_filter != "none" and self.evidence is None:
            raise ValueError(
                f"stage_filter {config.stage_filter!r} filters stage evidence; the {config.tracker} tracker reads none"
            )
        if config.stage_support and self.evidence is None:
            raise ValueError(f"stage_support gates stage evidence; the {config.tracker} tracker reads none")
        self.support = self.goals.require_stage_support() if config.stage_support else None
        if self.support is not None and self.support.num_stages != self.num_subtasks + 1:
            raise ModelError(f"the stage support covers {self.support.num_stages} stages, not {self.num_subtasks + 1}")
        self.trackers: list[StageTracker] = [self.new_tracker() for _ in range(num_envs)]
        self.filters = [self.new_filter() for _ in range(num_envs)]
        self.histories = [self.window.history() if self.window else None for _ in range(num_envs)]
        self.steps_since_switch = np.full(num_envs, -1)
        self.memories: list[NoveltyMemory] = []

    def subtask_rewards(self, embeddings: np.ndarray, goals: SubtaskGoals | None = None) -> np.ndarray:
        """(N, subtasks): the frames' completion-test rewards against `goals` (default: the
        scorer's), what its trackers hold against the thresholds."""
        return self.reward.subtask_rewards(self.model, embeddings, self.goals if goals is None else goals)

    def use_goals(self, goals: SubtaskGoals) -> None:
        """A recalibration of the same subtask goals (refitted stage classifier, raised thresholds),
        read from the next frame on; the trackers keep their episodes' stages."""
        self.goals = self.reward.goals = goals
        if self.classifier is not None:
            self.classifier = goals.require_stage_classifier()
        if self.support is not None:
            self.support = goals.require_stage_support()
        for tracker in self.trackers:
            tracker.use_thresholds(goals.thresholds)

    def new_tracker(self) -> StageTracker:
        return self.tracker_class.from_settings(self.config, self.goals.thresholds, self.hold_steps)

    def new_filter(self) -> StageFilter | None:
        config = self.config
        if config.stage_filter == "none":
            return None
        return StageFilter(
            self.num_subtasks + 1, config.filter_advance, config.filter_regress, config.filter_temperature
        )

    @property
    def num_envs(self) -> int:
        return len(self.trackers)

    @property
    def num_subtasks(self) -> int:
        return len(self.goals.thresholds)

    @property
    def needs_known_stages(self) -> bool:
        """Whether every scored frame needs its true stage from the caller (the privileged diagnostic)."""
        return self.stage_teller == "caller"

    def reset(self, env_indices: Iterable[int] | int | None = None) -> None:
        """Start a new episode in some environments (None: all): trackers only, memories persist."""
        if env_indices is None:
            env_indices = range(self.num_envs)
        for index in [env_indices] if isinstance(env_indices, int | np.integer) else env_indices:
            self.trackers[index].reset()
            if self.filters[index] is not None:
                self.filters[index].reset()
            if self.histories[index] is not None:
                self.histories[index].reset()
            self.steps_since_switch[index] = -1

    def score(
        self, frames: np.ndarray, stage_frames: np.ndarray | None = None, steps: Steps | None = None
    ) -> RewardParts:
        """frames: (N, H, W, 3) uint8, one per environment in environment order, or rows placed by
        `steps.envs` (see score_embeddings); `stage_frames` the same steps seen by `stage_camera`
        when the stage head reads another camera."""
        if self.stage_camera is None:
            stage_frames = frames
        elif stage_frames is None or len(stage_frames) != len(frames):
            raise ValueError(f"the stage head reads the {self.stage_camera!r} camera: pass its frame of every step")
        steps = steps or Steps()
        embeddings, evidence = self.model.embed(frames), self.stage_evidence(stage_frames)
        return self.score_embeddings(
            embeddings, steps.states, steps.envs, steps.rounds, steps.episode_ends, evidence, steps.known_stages
        )

    def continue_episodes(self, earlier: RewardScorer, keep_memories: bool) -> None:
        """Carry on the running episodes of `earlier`, the reward this one replaces (a refitted
        model): each stream's stage, its filter's belief and its steps since a switch; the novelty
        memories only when `keep_memories` (the same encoder: other weights embed elsewhere)."""
        if (earlier.num_envs, earlier.num_subtasks) != (self.num_envs, self.num_subtasks):
            raise ValueError(
                f"the new reward scores {self.num_envs} streams of {self.num_subtasks} subtasks, "
                f"the running one {earlier.num_envs} of {earlier.num_subtasks}"
            )
        for tracker, before in zip(self.trackers, earlier.trackers, strict=True):
            tracker.completed = before.completed
        for stage_filter, before in zip(self.filters, earlier.filters, strict=True):
            if stage_filter is not None and before is not None:
                stage_filter.belief = before.belief.copy()
        self.steps_since_switch = earlier.steps_since_switch.copy()
        if keep_memories:  # the same encoder: the window's embeddings stay valid too
            self.memories = earlier.memories
            for index, history in enumerate(earlier.histories):
                if history is not None and self.histories[index] is not None:
                    self.histories[index].frames.extend(history.frames)

    def exploration_state(self) -> dict[str, np.ndarray]:
        """The novelty memories, which a resumed run must not forget."""
        return {f"memory_{i}": memory.contents() for i, memory in enumerate(self.memories)}

    def restore_exploration(self, state: dict[str, np.ndarray]) -> None:
        memories = sorted((key for key in state if key.startswith("memory_")), key=lambda key: int(key[7:]))
        self.memories = [NoveltyMemory.restored(state[key], self.intrinsic.capacity) for key in memories]

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
        known_stages: np.ndarray | None = None,
    ) -> RewardParts:
        """Score frames already embedded. Without `envs`, one embedding per environment in order.
        With it, row i belongs to environment envs[i] and is taken in order. `rounds` (ascending)
        groups the rows into vector steps: a later round's frames are judged against novelty
        memories holding the earlier rounds' frames, as if scored one call per round, with one
        search for all. `episode_ends[i]`: envs[i] starts a new episode after row i.
        `stage_evidence`: the frames' `stage_evidence`, which a tracker reading the pixel stage
        head needs. `states`: the environments' state vectors, for the state novelty bonus.
        `known_stages`: each frame's true stage (the privileged diagnostic, `needs_known_stages`)."""
        count = len(embeddings)
        envs, rounds, ends = Steps(envs, rounds, episode_ends).rows(count, self.num_envs)
        per_subtask = self.subtask_rewards(embeddings)
        segments = self.segments(embeddings)
        at_least = self.classifier.at_least(embeddings) if self.classifier is not None else None
        if self.stage_head is not None:
            if stage_evidence is None or len(stage_evidence) != count:
                raise ValueError("the pixel stage head's tracker needs every frame's stage_evidence (score)")
            at_least = stage_evidence
        told = self.told_stages(embeddings, known_stages)
        supported = None if self.support is None else self.support.supported(embeddings)
        before, subtask, completed, since_switch = (np.zeros(count, int) for _ in range(4))
        was_done, done, switched = (np.zeros(count, bool) for _ in range(3))
        confidence = np.full(count, np.nan if told is None else 1.0)
        for row, env in enumerate(envs):
            tracker, stage_filter = self.trackers[env], self.filters[env]
            before[row], was_done[row] = tracker.current, tracker.done
            since_switch[row] = self.steps_since_switch[env]
            evidence = None if at_least is None else at_least[row]
            if self.window is not None:
                features = self.histories[env].push(embeddings[row])
                evidence = self.window.classifier.at_least(features[None])[0]
            if supported is not None:
                evidence = gate(evidence, supported[row], tracker.completed)
            if stage_filter is not None:
                evidence = at_least_of(stage_filter.update(exactly(evidence))[None])[0]
            change = tracker.step(
                Evidence(
                    per_subtask[row],
                    None if segments is None else segments[row],
                    evidence,
                    None if told is None else told[row],
                )
            )
            switched[row] = change > 0
            subtask[row], completed[row], done[row] = tracker.current, tracker.completed, tracker.done
            if evidence is not None:
                confidence[row] = exactly(evidence)[tracker.completed]
            if switched[row]:
                self.steps_since_switch[env] = 0
            elif self.steps_since_switch[env] >= 0:
                self.steps_since_switch[env] += 1
            if ends[row]:
                self.reset(env)
        shaping = self.reward.shaping(Batch(per_subtask, embeddings, segments, before, was_done, subtask, done))
        bonus = completed * self.reward.bonus
        # novelty is judged within the subtask the frame was taken in
        intrinsic = self.intrinsic_bonus(embeddings, states, before, since_switch, rounds)
        total = shaping + bonus + intrinsic
        return RewardParts(total, shaping, bonus, intrinsic, subtask, completed, switched, embeddings, confidence)

    def segments(self, embeddings: np.ndarray) -> np.ndarray | None:
        """(N, subtasks) segment closeness of each frame, when the method or the tracker reads it."""
        if self.start_embeddings is None:
            return None
        from_start = np.linalg.norm(np.asarray(embeddings)[:, None, :] - self.start_embeddings[None], axis=-1)
        return segment_closeness(goal_distances(embeddings, self.goals), from_start)

    def told_stages(self, embeddings: np.ndarray, known_stages: np.ndarray | None) -> np.ndarray | None:
        """(N,) the stage a ToldStage tracker is told: the caller's or the method's own inference."""
        if self.stage_teller == "method":
            return self.reward.inferred_stages(embeddings)
        if self.stage_teller == "caller":
            if known_stages is None or len(known_stages) != len(embeddings):
                raise ValueError(
                    "stage_source 'privileged' (a diagnostic) needs every frame's true stage (known_stages)"
                )
            return np.asarray(known_stages, dtype=int)
        return None

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
    def shaping(self) -> np.ndarray:
        """(N,) the shaping term: the reward without subtask bonus and intrinsic bonus."""
        return self.parts.shaping

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

    def claims(self) -> list[list[int]]:
        """completion_events of every subtask, in order."""
        return [self.completion_events(k) for k in range(self.num_subtasks)]

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
    known_stages: np.ndarray | None = None,
) -> Replay:
    """Feed one episode's embeddings, in order, through a fresh scorer: `RewardScorer(model,
    scheme, variant, **scorer_options)` (no intrinsic bonus unless the options ask for one),
    all frames in one `score_embeddings` call as rows of environment 0, one round per frame.
    `frames` (the episode through the stage head's camera: the images the embeddings came from,
    or the scene camera's when the head reads that, `RewardScorer.stage_camera`) give a tracker
    that reads the pixel stage head its evidence; it refuses to replay without them. `known_stages`
    (each frame's true stage) is what the privileged-stage diagnostic is told."""
    scorer = RewardScorer(model, scheme, variant, **(scorer_options or {}))
    count = len(embeddings)
    evidence = None if frames is None else scorer.stage_evidence(np.asarray(frames))
    parts = scorer.score_embeddings(
        np.asarray(embeddings),
        envs=np.zeros(count, dtype=int),
        rounds=np.arange(count),
        stage_evidence=evidence,
        known_stages=known_stages if scorer.needs_known_stages else None,
    )
    return Replay(parts, scorer.num_subtasks)
