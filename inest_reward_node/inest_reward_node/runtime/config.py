"""The learned reward's settings (`RewardConfig`): shaping, tracker, stage source and evidence.

One typed place for what the node's `reward.*` parameters, training's `learned_reward` and the
reward-quality report's scorer options set; the trackers take their own parts of it
(trackers.py).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass
from typing import Any

from .trackers import TRACKERS

SHAPINGS = ("thesis", "segment")
STAGE_SOURCES = ("tracker", "privileged")
STAGE_EVIDENCE = ("auto", "pixels", "embedding", "window")
STAGE_FILTERS = ("none", "forward")


@dataclass(frozen=True)
class RewardConfig:
    """How a learned reward turns frames into a reward (the xirl and holdr rewards only use
    `tracker`/`stage_source` for the subtask they report, and `intrinsic_cap`).

    shaping (per frame, with c the subtasks completed, B the model's subtask bonus):
    - "thesis": r(d) of the distance to the current goal in the rescaled units
      (ShapingConfig.start_distance), + B c: the thesis's reward.
    - "segment" (default): B (c + closeness_c), closeness_c = s / (s + d_c), s the distance to
      the mean embedding of the frames where subtask c starts (model.json `start_embeddings`),
      d_c the distance to goal c: where the frame sits between the subtask's start and its
      goal. Rises from B c towards B (c + 1) within a subtask, never dips at a switch; B K once
      all are done. The distance to the goal alone is not monotone within a subtask (the
      embedding curves round the goal; docs/reward-signal.md).
    tracker (when the stage comes from the reward itself):
    - "threshold": the thesis's counter: r(d) above the subtask's threshold for `hold_steps`
      frames completes it, for good (latched).
    - "confirmed" (default): the threshold test, then the classifier's agreement within
      `confirm_window` frames (ConfirmedTracker), and reopening a subtask whose frames look like its
      first half again.
    stage_source: "tracker", or "privileged" (DIAGNOSTIC ONLY: stage and bonus from the
      simulator's true ordered progress, which the caller tells the scorer per frame).
    hold_steps: frames a tracker's test must hold to move the stage; 0: the model's
      (ShapingConfig.hold_steps, what its thresholds were calibrated for).
    stage_evidence: where the confirmed tracker reads P(stage >= j) from:
      "pixels" (the pixel stage head on the frame itself, stage_head.py, fitted on the scene
      camera by default; the embedding does not keep "block in the strip"), "embedding" (the
      stage classifier on the frame's embedding), "window" (a classifier on the embeddings of the
      frame and of frames before it, stage_window.py: causal evidence one frame cannot fool), or
      "auto" (default): pixels when the model has a pixel stage head for the scheme, else embedding.
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
    stage_filter: "none" (each frame's stage evidence alone) or "forward": the confirmed tracker
      reads a causal forward filter over the stages instead (stage_filter.py), whose belief moves
      up one stage with probability `filter_advance` per frame, back with `filter_regress`, and
      weighs each frame's stage probabilities raised to `filter_temperature`.
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
    stage_filter: str = "none"
    filter_advance: float = 0.05
    filter_regress: float = 0.005
    filter_temperature: float = 0.5

    def __post_init__(self) -> None:
        for name, allowed in (
            ("shaping", SHAPINGS),
            ("tracker", tuple(TRACKERS)),  # read at each check: a tracker registered later counts
            ("stage_source", STAGE_SOURCES),
            ("stage_evidence", STAGE_EVIDENCE),
            ("stage_filter", STAGE_FILTERS),
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
        if not (self.filter_advance > 0 and self.filter_regress >= 0 and self.filter_advance + self.filter_regress < 1):
            raise ValueError(
                "need 0 < filter_advance, 0 <= filter_regress and filter_advance + filter_regress < 1, "
                f"got {self.filter_advance} and {self.filter_regress}"
            )
        if not 0 < self.filter_temperature <= 1:
            raise ValueError(f"filter_temperature must be in (0, 1], got {self.filter_temperature}")
        if self.intrinsic_cap is not None and not self.intrinsic_cap > 0:  # also rejects NaN
            raise ValueError(f"intrinsic_cap must be positive (or None for no cap), got {self.intrinsic_cap}")

    @property
    def cap(self) -> float:
        """The intrinsic cap as a number (inf: none)."""
        return math.inf if self.intrinsic_cap is None else float(self.intrinsic_cap)

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)
