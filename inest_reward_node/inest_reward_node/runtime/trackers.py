"""Which subtask a stream is in: stage trackers, one class per way of knowing, behind one `step`.

Every tracker takes one frame's `Evidence` at a time and moves the stage by +1, 0 or -1. What
it reads from the evidence it names in `reads`, so the scorer computes only that. A tracker
is chosen by name from `TRACKERS` and built from the reward's settings by `from_settings`;
adding one is a class here (or in a module of its own) and one line in `TRACKERS`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import ClassVar, NamedTuple, Protocol

import numpy as np

REOPEN_BELOW = 0.5  # segment closeness of the reopened subtask: the frame looks like its first half


class TrackerSettings(Protocol):
    """The reward settings trackers read (config.RewardConfig has them all)."""

    stage_confidence: float
    confirm_window: int
    confirm_steps: int
    instant_confidence: float
    retract_confidence: float
    retract_steps: int


class Evidence(NamedTuple):
    """One frame's evidence; a field a tracker does not read may be None."""

    rewards: np.ndarray  # (subtasks,) the method's completion-test reward against every goal
    segments: np.ndarray | None  # (subtasks,) where the frame sits between each subtask's start and goal
    at_least: np.ndarray | None  # (subtasks + 1,) P(stage >= j) from a stage classifier or head
    stage: int | None  # the stage told by someone else: the simulator (a diagnostic) or the method itself


class StageTracker:
    """The stage a policy should see, moved one subtask at a time; `completed` may go down.
    Subclasses decide from each frame's evidence whether the stage moves (`step`: +1, 0, -1)."""

    reads: ClassVar[frozenset[str]] = frozenset()  # the Evidence fields `step` needs

    def __init__(self, num_subtasks: int, hold_steps: int) -> None:
        if num_subtasks < 1:
            raise ValueError("a tracker needs at least one subtask")
        if hold_steps < 1:
            raise ValueError(f"hold_steps must be at least 1, got {hold_steps}")
        self._num_subtasks = num_subtasks
        self.hold_steps = hold_steps
        self.reset()

    @classmethod
    def from_settings(cls, config: TrackerSettings, thresholds: Sequence[float], hold_steps: int) -> StageTracker:
        """The tracker a reward's settings describe, for goals with these completion thresholds."""
        return cls(len(thresholds), hold_steps)

    def reset(self) -> None:
        self.completed = 0
        self.up_streak = 0
        self.down_streak = 0

    def use_thresholds(self, thresholds: Sequence[float]) -> None:
        """Recalibrated completion thresholds, from the next frame on (a tracker without any ignores them)."""

    def step(self, evidence: Evidence) -> int:
        raise NotImplementedError

    @property
    def num_subtasks(self) -> int:
        return self._num_subtasks

    @property
    def done(self) -> bool:
        return self.completed >= self.num_subtasks

    @property
    def current(self) -> int:
        return min(self.completed, self.num_subtasks - 1)

    def move(self, up: bool, down: bool) -> int:
        """One frame's verdicts: `up` the next stage looks reached, `down` the current one looks undone."""
        self.up_streak = self.up_streak + 1 if up and not self.done else 0
        self.down_streak = self.down_streak + 1 if down and self.completed > 0 else 0
        if self.up_streak >= self.hold_steps:
            self.completed += 1
            self.up_streak = self.down_streak = 0
            return 1
        if self.down_streak >= self.hold_steps:
            self.completed -= 1
            self.up_streak = self.down_streak = 0
            return -1
        return 0


class ThresholdTracker(StageTracker):
    """The thesis's counter: advances to the next subtask once the method's reward has stayed
    above the current subtask's threshold for `hold_steps` consecutive frames (a frame below it
    restarts the count), and never goes back."""

    reads = frozenset({"rewards"})

    def __init__(self, thresholds: Sequence[float], hold_steps: int) -> None:
        if not thresholds:
            raise ValueError("a tracker needs at least one subtask threshold")
        self.thresholds = [float(value) for value in thresholds]
        super().__init__(len(self.thresholds), hold_steps)

    @classmethod
    def from_settings(cls, config: TrackerSettings, thresholds: Sequence[float], hold_steps: int) -> StageTracker:
        return cls(thresholds, hold_steps)

    def use_thresholds(self, thresholds: Sequence[float]) -> None:
        if len(thresholds) != self.num_subtasks:
            raise ValueError(f"expected {self.num_subtasks} thresholds, got {len(thresholds)}")
        self.thresholds = [float(value) for value in thresholds]

    def passes(self, rewards: np.ndarray) -> bool:
        """The threshold test of the subtask being worked on."""
        c = self.completed
        return c < self.num_subtasks and rewards[c] >= self.thresholds[c]

    def step(self, evidence: Evidence) -> int:
        return self.move(self.passes(evidence.rewards), down=False)


@dataclass(frozen=True)
class ConfirmSettings:
    """The confirmed tracker's own settings (RewardConfig's stage_confidence, confirm_window,
    confirm_steps, instant_confidence, retract_confidence and retract_steps; see there)."""

    confidence: float
    window: int
    agree_steps: int  # 0: hold_steps
    instant: float  # 1: off
    retract: float = 0.0  # 0: off
    retract_steps: int = 0  # 0: hold_steps

    @classmethod
    def of(cls, config: TrackerSettings) -> ConfirmSettings:
        return cls(
            config.stage_confidence,
            config.confirm_window,
            config.confirm_steps,
            config.instant_confidence,
            config.retract_confidence,
            config.retract_steps,
        )


class ConfirmedTracker(ThresholdTracker):
    """Completes subtask c when the threshold test has held for `hold_steps` frames and, within
    `window` frames of that, the stage evidence says P(stage >= c + 1) >= confidence for
    `agree_steps` frames in a row (default `hold_steps`; the classifier lags the distance test by a
    frame or two, and each frame of agreement asked for adds to the lag), or for one frame with
    P >= `instant` (below 1: a two-speed test that confirms clear completions without lag).
    Reopens: the last completed subtask c - 1 counts as undone once, for `hold_steps` frames,
    the frame no longer passes its goal's test and sits nearer that subtask's start than its
    goal (segment closeness below REOPEN_BELOW): it looks like the first half of subtask c - 1
    again; or, with `retract` above 0, once the stage evidence has said P(stage >= c) < retract
    for `retract_steps` frames in a row (default `hold_steps`): a claim the evidence no longer
    backs stops paying, so a policy gains from a fooled frame only while it keeps fooling. Each
    test alone is fooled by different frames; together they are what makes the
    tracker honest (measured in docs/reports/reward-signal.md)."""

    reads = frozenset({"rewards", "segments", "at_least"})

    def __init__(self, thresholds: Sequence[float], hold_steps: int, settings: ConfirmSettings) -> None:
        self.confidence, self.window = settings.confidence, settings.window
        self.instant = settings.instant if settings.instant < 1.0 else math.inf
        self.agree_steps = settings.agree_steps or hold_steps
        self.retract, self.retract_steps = settings.retract, settings.retract_steps or hold_steps
        super().__init__(thresholds, hold_steps)

    @classmethod
    def from_settings(cls, config: TrackerSettings, thresholds: Sequence[float], hold_steps: int) -> StageTracker:
        return cls(thresholds, hold_steps, ConfirmSettings.of(config))

    def reset(self) -> None:
        super().reset()
        self.waited = -1  # frames since the threshold test held (-1: it has not)
        self.agreed = 0
        self.denied = 0  # frames in a row the stage evidence has denied the last completed subtask

    def undone(self, rewards: np.ndarray, segments: np.ndarray) -> bool:
        c = self.completed
        return c > 0 and rewards[c - 1] < self.thresholds[c - 1] and segments[c - 1] < REOPEN_BELOW

    def step(self, evidence: Evidence) -> int:
        rewards, at_least = evidence.rewards, evidence.at_least
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
        self.down_streak = self.down_streak + 1 if self.undone(rewards, evidence.segments) else 0
        self.denied = self.denied + 1 if c > 0 and at_least[c] < self.retract else 0
        change = 0
        if self.waited >= 0 and (self.agreed >= self.agree_steps or certain):
            self.completed, change = c + 1, 1
        elif self.down_streak >= self.hold_steps or self.denied >= self.retract_steps:
            self.completed, change = c - 1, -1
        elif self.waited > self.window:
            self.waited, self.agreed = -1, 0  # not confirmed in time: wait for the test to hold again
            return 0
        if change:
            self.up_streak = self.down_streak = self.agreed = self.denied = 0
            self.waited = -1
        return change


class ToldStage(StageTracker):
    """The stage is told on every frame (`Evidence.stage`), no hold and no latch: by the
    simulator's true ordered progress (a DIAGNOSTIC, `stage_source="privileged"`), or by a
    method that infers it itself (REDS: the subtask most similar to the frame)."""

    reads = frozenset({"stage"})

    def __init__(self, num_subtasks: int, hold_steps: int = 1) -> None:
        super().__init__(num_subtasks, 1)

    def step(self, evidence: Evidence) -> int:
        stage = int(np.clip(evidence.stage, 0, self.num_subtasks))
        change = int(np.sign(stage - self.completed))
        self.completed = stage
        return change


# RewardConfig.tracker -> its class; "told" is chosen by the scorer, not by name
TRACKERS: dict[str, type[StageTracker]] = {"threshold": ThresholdTracker, "confirmed": ConfirmedTracker}
