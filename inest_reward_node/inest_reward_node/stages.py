"""Reward settings (`RewardConfig`) and the honest ways of knowing which subtask the agent is in.

The counter-based tracker of the thesis (shaping.SubtaskTracker, `tracker="threshold"`) is
latched and trusts one distance test: it completed "push red" in 10 % of random-policy and
55 % of wrong-order (blue first) episodes without the red block in the goal, and pushing a
block back out cost nothing. This module adds
- reopening (`ReopeningTracker`): a completed subtask reopens when the frames look like the
  first half of that subtask again (its goal's test fails and the frame sits nearer the
  subtask's start embedding than its goal, see `segment_closeness`);
- a learned stage classifier (`StageClassifier`), the idea of the stage-aware reward models
  (e.g. SARM): a tiny MLP on the frozen embedding predicting the true ordered progress 0..K
  of a frame, fitted at calibration (`fit_stage_classifier`, seconds) on the training
  demonstrations' frames plus random-policy and wrong-order expert frames labelled with the
  simulator's true progress, stored in model.json next to the goals. On its own
  (`ClassifierTracker`, up when it says >= k + 1 and down when it says < k, each for
  `hold_steps` frames) it is no better than the threshold test: on the default model it
  fired in 55 % of random and all wrong-order episodes (the 32-d embedding does not tell
  these frames apart reliably). As a second opinion it is what makes the tracker honest:
  `ConfirmedTracker` completes a subtask only when the threshold test holds and the
  classifier then agrees, and reopens like ReopeningTracker;
- `PrivilegedStage`: a DIAGNOSTIC, not a learned reward: the stage is the simulator's true
  ordered progress (the state vector's `ordered_progress`), so an experiment can tell what
  the stage and bonus cost a policy apart from the shaping.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch
from inest_sim_node.scoring import NUM_BLOCKS
from inest_sim_node.subtasks import current_subtasks

from inest_sim_node import STATE_FIELDS

from .shaping import StageTracker

SHAPINGS = ("thesis", "raw", "progress", "segment")
TRACKERS = ("threshold", "reopening", "classifier", "confirmed")
STAGE_SOURCES = ("tracker", "privileged")
STAGE_EVIDENCE = ("auto", "pixels", "embedding")
PROGRESS_FIELD = STATE_FIELDS.index("ordered_progress")  # k / 3 in the state vector
REOPEN_BELOW = 0.5  # segment closeness of the reopened subtask: the frame looks like its first half


@dataclass(frozen=True)
class RewardConfig:
    """How the INEST reward turns embeddings into a reward (the xirl and holdr rewards only use
    `tracker`/`stage_source` for the subtask they report, and `intrinsic_cap`).

    shaping (per frame, with c the subtasks completed, B the model's subtask bonus):
    - "thesis": r(d) of the distance to the current goal in the rescaled units
      (ShapingConfig.start_distance), + B c: the thesis reward as this project had it.
    - "raw": r(d) of the raw embedding distance, + B c.
    - "progress": B (c + closeness_c), closeness_c = 1 - min(1, d_c / d_c_start), d_c_start the
      training demonstrations' mean raw distance to goal c on the frame where subtask c starts
      (model.json `start_distances`). Rises from B c towards B (c + 1) within a subtask, never
      dips at a switch; B K once all are done.
    - "segment" (default): the same with closeness_c = s / (s + d_c), s the distance to the mean
      embedding of the frames where subtask c starts (model.json `start_embeddings`): where the
      frame sits between the subtask's start and its goal. The distance to the goal alone is
      not monotone within a subtask (the embedding curves round the goal: within-subtask
      Spearman with time 0.84/0.55/0.66 on the default model's validation demonstrations);
      the position between start and goal is (0.88/0.90/0.91).
    tracker (when the stage comes from the reward itself):
    - "threshold": the thesis's counter: r(d) above the subtask's threshold for `hold_steps`
      frames completes it, for good (latched).
    - "reopening": the same, but the last completed subtask reopens once, for `hold_steps`
      frames, its goal's threshold test fails and the frame's segment closeness for it is below
      one half (it looks like the first half of that subtask again).
    - "classifier": the stage classifier alone, with hysteresis (ClassifierTracker).
    - "confirmed" (default): the threshold test, then the classifier's agreement within
      `confirm_window` frames (ConfirmedTracker); reopens like "reopening".
    stage_source: "tracker", or "privileged" (DIAGNOSTIC ONLY: stage and bonus from the
      simulator's true ordered progress, passed in per frame as the state vector; 1 or 3 subtasks).
    hold_steps: frames a tracker's test must hold to move the stage; 0: the model's
      (ShapingConfig.hold_steps, what its thresholds were calibrated for).
    stage_evidence: where the classifier and confirmed trackers read P(stage >= j) from:
      "pixels" (the pixel stage head on the frame itself, stage_head.py, fitted on the scene
      camera by default; the embedding does not keep "block in the strip"), "embedding" (the
      stage classifier on the frame's embedding), or "auto" (default): pixels when the model
      has a pixel stage head for the scheme, else embedding (models fitted without one).
    stage_confidence: the classifier says "stage >= j" when it gives P(stage >= j) >= this.
    confirm_window: frames after the threshold test has held within which the classifier must agree.
    confirm_steps: frames in a row the classifier must agree to confirm a completion; 0: hold_steps,
      the streak the threshold test needs. 1 confirms on the first frame the classifier agrees,
      which shortens the tracker's lag behind the true completion (docs/reward-signal.md).
    instant_confidence: P(stage >= j) at which one frame of agreement confirms at once, ahead of
      confirm_steps: a two-speed test, strong evidence switches on the frame and weak evidence
      after confirm_steps frames (no lag on clear completions, the streak's honesty on unclear
      ones); 1: off. 0.9 (default) with the 600-demonstration scene heads meets the per-subtask
      reward targets on held-out and selection demonstrations (docs/reward-signal.md).
    intrinsic_cap: the weighted novelty bonus (after the post-switch boost) is clipped to at most
      this; None (or inf) for no clip.
    """

    shaping: str = "segment"
    tracker: str = "confirmed"
    stage_source: str = "tracker"
    stage_evidence: str = "auto"
    hold_steps: int = 0
    stage_confidence: float = 0.5
    confirm_window: int = 20
    confirm_steps: int = 0
    instant_confidence: float = 0.9
    intrinsic_cap: float | None = None

    def __post_init__(self) -> None:
        for name, allowed in (
            ("shaping", SHAPINGS),
            ("tracker", TRACKERS),
            ("stage_source", STAGE_SOURCES),
            ("stage_evidence", STAGE_EVIDENCE),
        ):
            if getattr(self, name) not in allowed:
                raise ValueError(f"unknown reward {name} {getattr(self, name)!r}; expected one of {allowed}")
        if self.hold_steps < 0:
            raise ValueError(f"hold_steps must be >= 0 (0: the model's), got {self.hold_steps}")
        if not 0.0 < self.stage_confidence < 1.0:
            raise ValueError(f"stage_confidence must be in (0, 1), got {self.stage_confidence}")
        if self.confirm_window < 0:
            raise ValueError(f"confirm_window must be >= 0, got {self.confirm_window}")
        if self.confirm_steps < 0:
            raise ValueError(f"confirm_steps must be >= 0 (0: hold_steps), got {self.confirm_steps}")
        if not self.stage_confidence <= self.instant_confidence <= 1.0:
            raise ValueError(
                f"instant_confidence must be in [stage_confidence, 1] = [{self.stage_confidence}, 1] (1: off), "
                f"got {self.instant_confidence}"
            )
        if self.intrinsic_cap is not None and not self.intrinsic_cap > 0:  # also rejects NaN
            raise ValueError(f"intrinsic_cap must be positive (or None for no cap), got {self.intrinsic_cap}")

    @property
    def cap(self) -> float:
        """The intrinsic cap as a number (inf: none)."""
        return math.inf if self.intrinsic_cap is None else float(self.intrinsic_cap)

    @property
    def uses_classifier(self) -> bool:
        return self.stage_source == "tracker" and self.tracker in ("classifier", "confirmed")

    @property
    def reopens(self) -> bool:
        """Whether the tracker reopens subtasks by segment closeness (it needs the start embeddings)."""
        return self.stage_source == "tracker" and self.tracker in ("reopening", "confirmed")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def segment_closeness(distances: np.ndarray, start_distances: np.ndarray) -> np.ndarray:
    """Where a frame sits between a subtask's start embedding and its goal, in [0, 1]: s / (s + d)
    with s the distance to the start, d to the goal (elementwise)."""
    distances, start_distances = np.asarray(distances), np.asarray(start_distances)
    return start_distances / np.maximum(start_distances + distances, 1e-12)


def true_stages(progress: np.ndarray, held: np.ndarray | None, scheme: int) -> np.ndarray:
    """Subtasks done on each frame right now (not latched: pushing a block out undoes its subtask);
    inest_sim_node.subtasks.current_subtasks, the rule the demonstrations' labels latch."""
    return current_subtasks(progress, held, scheme)


def demo_stages(progress: np.ndarray, labels: np.ndarray, scheme: int) -> np.ndarray:
    """A demonstration's true stage per frame. Demonstrations keep no grasp flags, so the
    6-subtask stage is read off the labels (frame t's stage is frame t + 1's label), capped by
    what the block progress allows."""
    if scheme != 6:
        return true_stages(progress, None, scheme)
    progress = np.asarray(progress, dtype=np.int64)
    stages = np.concatenate([np.asarray(labels[1:], dtype=np.int64), [int(labels[-1])]])
    stages = np.clip(stages, 2 * progress, 2 * progress + 1)
    return np.where(progress >= NUM_BLOCKS, 2 * NUM_BLOCKS, stages)


def privileged_stages(states: np.ndarray | None, scheme: int) -> np.ndarray:
    """DIAGNOSTIC: the simulator's true stage from state vectors (`ordered_progress` = k / 3)."""
    if states is None:
        raise ValueError("stage_source 'privileged' needs the environments' state vectors")
    progress = np.rint(np.asarray(states, dtype=np.float64)[:, PROGRESS_FIELD] * NUM_BLOCKS).astype(np.int64)
    return true_stages(progress, None, scheme)


def progress_states(progress: np.ndarray) -> np.ndarray:
    """State vectors that carry only the ordered progress, which is all privileged_stages reads:
    for replaying a recorded episode (the reward-quality report) with the true stage."""
    states = np.zeros((len(progress), len(STATE_FIELDS)), dtype=np.float32)
    states[:, PROGRESS_FIELD] = np.asarray(progress, dtype=np.float32) / NUM_BLOCKS
    return states


class StageClassifier:
    """P(stage = j | embedding), j = 0..K: standardise, one ReLU hidden layer, softmax.
    Numpy at inference (a few microseconds per frame); stored as plain lists in model.json."""

    def __init__(
        self,
        mean: np.ndarray,
        scale: np.ndarray,
        hidden_weight: np.ndarray,
        hidden_bias: np.ndarray,
        out_weight: np.ndarray,
        out_bias: np.ndarray,
    ) -> None:
        self.mean, self.scale = np.asarray(mean, np.float32), np.asarray(scale, np.float32)
        self.hidden_weight = np.asarray(hidden_weight, np.float32)
        self.hidden_bias = np.asarray(hidden_bias, np.float32)
        self.out_weight = np.asarray(out_weight, np.float32)
        self.out_bias = np.asarray(out_bias, np.float32)

    @property
    def num_stages(self) -> int:
        return len(self.out_bias)

    def probabilities(self, embeddings: np.ndarray) -> np.ndarray:
        """(N, D) -> (N, K + 1) stage probabilities."""
        x = (np.asarray(embeddings, np.float32) - self.mean) / self.scale
        hidden = np.maximum(x @ self.hidden_weight + self.hidden_bias, 0.0)
        logits = hidden @ self.out_weight + self.out_bias
        logits -= logits.max(axis=1, keepdims=True)
        odds = np.exp(logits)
        return odds / odds.sum(axis=1, keepdims=True)

    def at_least(self, embeddings: np.ndarray) -> np.ndarray:
        """(N, K + 1): column j = P(stage >= j) (column 0 is 1)."""
        return np.flip(np.cumsum(np.flip(self.probabilities(embeddings), axis=1), axis=1), axis=1)

    def predict(self, embeddings: np.ndarray) -> np.ndarray:
        return self.probabilities(embeddings).argmax(axis=1)

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "mlp",
            "mean": self.mean.tolist(),
            "scale": self.scale.tolist(),
            "hidden_weight": self.hidden_weight.tolist(),
            "hidden_bias": self.hidden_bias.tolist(),
            "out_weight": self.out_weight.tolist(),
            "out_bias": self.out_bias.tolist(),
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StageClassifier:
        if data.get("kind") != "mlp":
            raise ValueError(f"unknown stage classifier kind {data.get('kind')!r}")
        return cls(
            *(
                np.asarray(data[key], np.float32)
                for key in ("mean", "scale", "hidden_weight", "hidden_bias", "out_weight", "out_bias")
            )
        )


@dataclass(frozen=True)
class StageClassifierConfig:
    """Fitting the stage classifier (full-batch Adam; about a second per subtask scheme)."""

    hidden: int = 64
    steps: int = 300
    learning_rate: float = 0.01
    weight_decay: float = 1e-4
    negative_weight: float = 1.0  # total weight of the non-demonstration frames, relative to the demos'
    max_demo_frames: int = 16384  # a uniform sample of the demonstrations' frames, if they have more
    seed: int = 0

    def __post_init__(self) -> None:
        if (
            min(self.hidden, self.steps, self.max_demo_frames) < 1
            or self.learning_rate <= 0
            or self.negative_weight < 0
        ):
            raise ValueError("hidden, steps and max_demo_frames must be >= 1, learning_rate > 0, negative_weight >= 0")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def fit_stage_classifier(
    demo_embeddings: Sequence[np.ndarray],
    demo_stages: Sequence[np.ndarray],
    num_stages: int,
    negative_embeddings: Sequence[np.ndarray] = (),
    negative_stages: Sequence[np.ndarray] = (),
    config: StageClassifierConfig | None = None,
) -> StageClassifier:
    """Fit P(stage | embedding) on demonstration frames and other behaviour (random play, wrong
    order), each frame labelled with its true stage. Every stage's demonstration frames weigh as
    much in total as any other's (a stage is as long as its subtask), and all non-demonstration
    frames together weigh `negative_weight` times the demonstrations."""
    config = config or StageClassifierConfig()
    x_demo, y_demo = np.concatenate(demo_embeddings), np.concatenate(demo_stages).astype(np.int64)
    if len(y_demo) > config.max_demo_frames:
        chosen = np.random.default_rng(config.seed).choice(len(y_demo), config.max_demo_frames, replace=False)
        x_demo, y_demo = x_demo[chosen], y_demo[chosen]
    counts = np.bincount(y_demo, minlength=num_stages).astype(np.float64)
    weights = [1.0 / counts[y_demo] / np.count_nonzero(counts)]
    xs, ys = [x_demo], [y_demo]
    if len(negative_embeddings) and config.negative_weight > 0:
        x_neg, y_neg = np.concatenate(negative_embeddings), np.concatenate(negative_stages).astype(np.int64)
        xs.append(x_neg)
        ys.append(y_neg)
        weights.append(np.full(len(y_neg), config.negative_weight / len(y_neg)))
    x, y, w = np.concatenate(xs).astype(np.float32), np.concatenate(ys), np.concatenate(weights)
    if y.min() < 0 or y.max() >= num_stages:
        raise ValueError(f"stage labels must lie in [0, {num_stages}), got {y.min()}..{y.max()}")
    mean, scale = x.mean(axis=0), x.std(axis=0) + 1e-6
    generator = torch.Generator().manual_seed(config.seed)
    dim = x.shape[1]
    hidden_weight = (torch.randn(dim, config.hidden, generator=generator) * math.sqrt(2.0 / dim)).requires_grad_()
    hidden_bias = torch.zeros(config.hidden, requires_grad=True)
    out_weight = torch.randn(config.hidden, num_stages, generator=generator) / math.sqrt(config.hidden)
    out_weight.requires_grad_()
    out_bias = torch.zeros(num_stages, requires_grad=True)
    parameters = [hidden_weight, hidden_bias, out_weight, out_bias]
    optimizer = torch.optim.Adam(parameters, lr=config.learning_rate, weight_decay=config.weight_decay)
    inputs = torch.from_numpy((x - mean) / scale)
    targets = torch.from_numpy(y)
    frame_weights = torch.from_numpy((w / w.sum()).astype(np.float32))
    for _ in range(config.steps):
        logits = torch.relu(inputs @ hidden_weight + hidden_bias) @ out_weight + out_bias
        loss = (torch.nn.functional.cross_entropy(logits, targets, reduction="none") * frame_weights).sum()
        optimizer.zero_grad(set_to_none=True)
        loss.backward()
        optimizer.step()
    return StageClassifier(mean, scale, *(p.detach().numpy() for p in parameters))


class ClassifierTracker(StageTracker):
    """Stage c moves to c + 1 once P(stage >= c + 1) >= confidence for `hold_steps` frames in a
    row, and back to c - 1 once P(stage >= c) < confidence for as many (hysteresis: in between
    it stays). Feed it rows of StageClassifier.at_least."""

    def __init__(self, num_subtasks: int, hold_steps: int, confidence: float = 0.5) -> None:
        super().__init__(num_subtasks, hold_steps)
        self.confidence = confidence

    def step(self, at_least: np.ndarray) -> int:
        c = self.completed
        up = c < self.num_subtasks and at_least[c + 1] >= self.confidence
        return self.move(up, at_least[c] < self.confidence)


class PrivilegedStage(StageTracker):
    """DIAGNOSTIC: the stage is the simulator's true ordered progress on every frame (no hold)."""

    def __init__(self, num_subtasks: int) -> None:
        super().__init__(num_subtasks, 1)

    def step(self, stage: int) -> int:
        stage = int(np.clip(stage, 0, self.num_subtasks))
        change = int(np.sign(stage - self.completed))
        self.completed = stage
        return change


class InferredStage(PrivilegedStage):
    """The stage the reward infers on each frame by itself (REDS: the subtask most similar to the
    frame, reds.infer_subtasks), no hold and no latch: its frames are in subtask k = `completed`."""


class ReopeningTracker(StageTracker):
    """The thesis's threshold test for completing (r(d) to the current goal >= its threshold for
    `hold_steps` frames), plus reopening: the last completed subtask c - 1 counts as undone once,
    for `hold_steps` frames, the frame no longer passes its goal's test and sits nearer that
    subtask's start than its goal (segment closeness below REOPEN_BELOW): it looks like the first
    half of subtask c - 1 again. On the default model it reopened a subtask in 1 of 100 validation
    demonstrations (which never undo one) and every synthetic undo (demonstration frames past a
    completion, followed by that subtask's early frames again) within 2 frames."""

    def __init__(self, thresholds: Sequence[float], hold_steps: int) -> None:
        super().__init__(len(thresholds), hold_steps)
        self.thresholds = [float(value) for value in thresholds]

    def passes(self, rewards: np.ndarray) -> bool:
        """The threshold test of the subtask being worked on."""
        c = self.completed
        return c < self.num_subtasks and rewards[c] >= self.thresholds[c]

    def undone(self, rewards: np.ndarray, segments: np.ndarray) -> bool:
        c = self.completed
        return c > 0 and rewards[c - 1] < self.thresholds[c - 1] and segments[c - 1] < REOPEN_BELOW

    def step(self, rewards: np.ndarray, segments: np.ndarray) -> int:
        return self.move(self.passes(rewards), self.undone(rewards, segments))


class ConfirmedTracker(ReopeningTracker):
    """Completes subtask c when the threshold test has held for `hold_steps` frames and, within
    `window` frames of that, the stage classifier says P(stage >= c + 1) >= confidence for
    `agree_steps` frames in a row (default `hold_steps`; the classifier lags the distance test by a
    frame or two, and each frame of agreement asked for adds to the lag), or for one frame with
    P >= `instant` (below 1: a two-speed test that confirms clear completions without lag);
    reopens like ReopeningTracker. Each test alone is fooled by different frames (on the
    default model the threshold test by 10 % of random and 55 % of wrong-order episodes, the
    classifier by 55 % and 100 %); together they completed a subtask falsely in 0 % and 5 %,
    and missed 1-4 % of the demonstrations' completions."""

    def __init__(
        self,
        thresholds: Sequence[float],
        hold_steps: int,
        confidence: float,
        window: int,
        agree_steps: int = 0,
        instant: float = 1.0,
    ) -> None:
        self.confidence, self.window = confidence, window
        self.instant = instant if instant < 1.0 else math.inf
        self.agree_steps = agree_steps or hold_steps
        super().__init__(thresholds, hold_steps)

    def reset(self) -> None:
        super().reset()
        self.waited = -1  # frames since the threshold test held (-1: it has not)
        self.agreed = 0

    def step(self, rewards: np.ndarray, segments: np.ndarray, at_least: np.ndarray) -> int:
        c = self.completed
        self.up_streak = self.up_streak + 1 if self.passes(rewards) else 0
        if self.waited < 0 and self.up_streak >= self.hold_steps:
            self.waited = 0
        elif self.waited >= 0:
            self.waited += 1
        certain = False
        if self.waited >= 0 and c < self.num_subtasks:
            self.agreed = self.agreed + 1 if at_least[c + 1] >= self.confidence else 0
            certain = at_least[c + 1] >= self.instant
        self.down_streak = self.down_streak + 1 if self.undone(rewards, segments) else 0
        change = 0
        if self.waited >= 0 and (self.agreed >= self.agree_steps or certain):
            self.completed, change = c + 1, 1
        elif self.down_streak >= self.hold_steps:
            self.completed, change = c - 1, -1
        elif self.waited > self.window:
            self.waited, self.agreed = -1, 0  # not confirmed in time: wait for the test to hold again
            return 0
        if change:
            self.up_streak = self.down_streak = self.agreed = 0
            self.waited = -1
        return change
