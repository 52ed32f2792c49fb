"""The learned reward's settings (`RewardConfig`): shaping, tracker, stage source and evidence.

One typed place for what the node's `reward.*` parameters, training's `learned_reward` and the
reward-quality report's scorer options set; the trackers take their own parts of it
(trackers.py).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from typing import Any, Literal

from inest_common.settings import CHOICES, check_choices

from .trackers import TRACKERS

SHAPINGS = ("thesis", "segment")
STAGE_SOURCES = ("tracker", "privileged")
STAGE_EVIDENCE = ("auto", "pixels", "embedding", "window")
STAGE_FILTERS = ("none", "forward")


@dataclass(frozen=True)
class RewardConfig:
    """How a learned reward turns frames into a reward (the xirl and holdr rewards only use
    `tracker`/`stage_source` for the subtask they report, and `intrinsic_cap`). Shaping, per
    frame, with c the subtasks completed and B the model's subtask bonus: "thesis" is r(d) of the
    distance to the current goal in the rescaled units (ShapingConfig.start_distance) + B c;
    "segment" is B (c + s / (s + d_c)), s the distance to the mean embedding of the frames where
    subtask c starts and d_c the distance to goal c: it rises from B c towards B (c + 1) within a
    subtask and never dips at a switch, where the distance alone is not monotone (the embedding
    curves round the goal; docs/reports/reward-signal.md)."""

    # thesis: r(d) + B c, the thesis's reward; segment: B (c + closeness to goal c)
    shaping: Literal[SHAPINGS] = "segment"
    # threshold: the thesis's latched counter (r(d) above the threshold for hold_steps frames);
    # confirmed: the threshold test, then the stage evidence's agreement within confirm_window
    # frames, and a subtask reopened when its frames look like its first half again
    tracker: str = field(default="confirmed", metadata={CHOICES: lambda: tuple(TRACKERS)})
    # tracker, or privileged (DIAGNOSTIC ONLY: stage and bonus from the simulator's true ordered progress)
    stage_source: Literal[STAGE_SOURCES] = "tracker"
    # what the confirmed tracker reads P(stage >= j) from: pixels (the pixel stage head,
    # stage_head.py, on the scene camera by default), embedding (the stage classifier on the
    # frame's embedding), window (a classifier over the frame's and earlier frames' embeddings,
    # stage_window.py) or auto (pixels when the model has a pixel stage head for the scheme)
    stage_evidence: Literal[STAGE_EVIDENCE] = "auto"
    # frames a tracker's test must hold to move the stage; 0: the model's (what its thresholds were calibrated for)
    hold_steps: int = 0
    # the stage evidence says "stage >= j" when P(stage >= j) is at least this
    stage_confidence: float = 0.5
    # frames after the threshold test has held within which the stage evidence must agree
    confirm_window: int = 20
    # frames in a row the stage evidence must agree to confirm a completion; 0: hold_steps
    confirm_steps: int = 0
    # P(stage >= j) at which one frame confirms a completion at once, ahead of confirm_steps; 1: off
    instant_confidence: float = 0.9
    # the confirmed tracker takes back the last completed subtask c when its stage evidence says
    # P(stage >= c) < retract_confidence for retract_steps frames in a row: a claim pays only while
    # the evidence still stands behind it; 0: off (a claim stands until its frames look like its first half)
    retract_confidence: float = 0.0
    # frames in a row the stage evidence must deny a completed subtask to take it back; 0: hold_steps
    retract_steps: int = 0
    # the weighted novelty bonus (after the post-switch boost) is clipped to at most this; None: no clip
    intrinsic_cap: float | None = None
    # a frame is evidence of a stage above the completed ones only within the demonstrations'
    # support of that stage (stage_support.py; the model needs one fitted at calibration)
    stage_support: bool = False
    # none: each frame's stage evidence alone; forward: a causal forward filter over the stages (stage_filter.py)
    stage_filter: Literal[STAGE_FILTERS] = "none"
    # the stage filter's chance per frame of one stage up
    filter_advance: float = 0.05
    # the stage filter's chance per frame of one stage back
    filter_regress: float = 0.005
    # the power the stage filter raises each frame's stage probabilities to
    filter_temperature: float = 0.5

    def __post_init__(self) -> None:
        check_choices(self, "reward ")
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
        if not 0.0 <= self.retract_confidence < self.stage_confidence:
            raise ValueError(
                f"retract_confidence must be in [0, stage_confidence) = [0, {self.stage_confidence}) (0: off), "
                f"got {self.retract_confidence}"
            )
        if self.retract_steps < 0:
            raise ValueError(f"retract_steps must be >= 0 (0: hold_steps), got {self.retract_steps}")
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
