"""A scored frame's reward and its parts, named once: `RewardParts` holds them for a batch, and
`PARTS` says what each part is called outside it.

A served frame (serving.ScoredFrame) carries them under the same names; the reward node
publishes them in the `inest_interfaces/Reward` message (`Part.field`) and a training step
reports them in its gym info dict (`Part.info`), whoever computed the reward: the in-process
environments, the graph's reward node or the gymnasium wrapper. Why one table: each of those
used to map the parts itself, in a vocabulary of its own. Free of ROS: the message is filled
and read by field name.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields

import numpy as np

Scalar = float | int | bool


@dataclass
class RewardParts:
    """One scored batch: per environment, the reward and what it is made of."""

    total: np.ndarray  # (N,) what the agent receives: shaping + bonus + intrinsic
    # (N,) the method's per-frame reward (INEST: the shaping term of the current subtask; 0 once done)
    shaping: np.ndarray
    bonus: np.ndarray  # (N,) subtask bonus (INEST: completed subtasks x bonus)
    intrinsic: np.ndarray  # (N,) weighted novelty bonus
    subtask: np.ndarray  # (N,) current subtask index after this frame
    completed: np.ndarray  # (N,) subtasks completed after this frame: the stage the policy should see (may drop)
    switched: np.ndarray  # (N,) bool, this frame completed a subtask (an upward switch only)
    embeddings: np.ndarray  # (N, D) the frames' embeddings, for coverage analysis
    # (N,) how sure the stage is: P(stage == completed) from the stage evidence the tracker read
    # (filtered, with a stage filter); NaN for a reward that reads none, 1 where the stage is told
    confidence: np.ndarray

    def select(self, rows: slice | np.ndarray) -> RewardParts:
        return RewardParts(*(getattr(self, field.name)[rows] for field in fields(self)))

    def row(self, index: int) -> dict[str, Scalar]:
        """Row `index`'s published parts (`PARTS`) as Python scalars, by name: what a served
        frame, a Reward message and a step's info are made from."""
        return {part.name: part.kind(getattr(self, part.name)[index]) for part in PARTS}


@dataclass(frozen=True)
class Part:
    """One published part of a frame's reward: its `RewardParts` (and ScoredFrame) name, its
    `inest_interfaces/Reward` field, its gym info key (None: not in a step's info) and its type."""

    name: str
    field: str
    info: str | None
    kind: type[Scalar]


LEARNED_STAGE = "learned_stage"  # info key of the reward's stage: subtasks it counts as done (0..num_subtasks)

# diagnostics.RewardDiagnostics reads shaping, bonus and intrinsic by their info keys and writes them
# to results.json under their names (`shaping_per_step`, `shaping_share`): those names are on disk.
PARTS = (
    Part("total", "total", None, float),  # a step's info has it as the step's reward
    Part("shaping", "shaping_reward", "shaping_reward", float),
    Part("bonus", "subtask_bonus", "subtask_bonus", float),
    Part("intrinsic", "intrinsic_bonus", "intrinsic_reward", float),
    Part("completed", "subtask", LEARNED_STAGE, int),  # Reward.subtask: the stage, num_subtasks once all are done
    Part("switched", "subtask_completed", None, bool),
    Part("confidence", "stage_confidence", None, float),
)
INFO_KEYS = {part.name: part.info for part in PARTS if part.info is not None}


def message_fields(parts: Mapping[str, Scalar]) -> dict[str, Scalar]:
    """The Reward message's fields for one frame's parts by name (`RewardParts.row`, a ScoredFrame's)."""
    return {part.field: parts[part.name] for part in PARTS}


def message_parts(message: object) -> dict[str, Scalar]:
    """One frame's parts by name, read from a Reward message."""
    return {part.name: getattr(message, part.field) for part in PARTS}


def info_items(parts: Mapping[str, Scalar]) -> dict[str, Scalar]:
    """A training step's info entries for one frame's parts by name."""
    return {part.info: parts[part.name] for part in PARTS if part.info is not None}
