"""Negatives that need no labels: the agent's own frames that claim a stage the way the
demonstrations never reach it.

A frame whose single-frame stage classifier says "stage c + 1 or more" while the reward's
tracker, reading the stage over time (its confirmation, and the forward filter when
`learned_reward.stage_filter` is on), stays at c for the next CONFIRM_WITHIN frames is a frame
the policy reaches otherwise than the demonstrations reach stage c + 1: it is kept as a
negative labelled c, as PROGRESSOR and Rank2Reward push down the agent's frames where they
claim progress the demonstrations make differently. stage_refit.py fits the classifier on them.
"""

from __future__ import annotations

from collections import deque
from typing import NamedTuple

import numpy as np

from ..runtime.rewards import RewardParts, RewardScorer

CONFIRM_WITHIN = 10  # frames a claim has to be confirmed in before it counts as a negative
CAPACITY = 20_000  # negatives kept, newest first


class Claim(NamedTuple):
    """A frame whose classifier claimed more than the tracker's stage, waiting to be confirmed."""

    frame: int  # its frame of the episode
    embedding: np.ndarray
    stage: int  # what the classifier claimed
    kept: int  # the tracker's stage then: the label if the claim is never confirmed


class SelfNegatives:
    """Collects the agent's unconfirmed claims from every scored step."""

    def __init__(self, scorer: RewardScorer, num_envs: int) -> None:
        self.scorer = scorer  # its classifier is the one claiming (a refit replaces it)
        self.waiting: list[deque[Claim]] = [deque() for _ in range(num_envs)]
        self.frames = [0] * num_envs  # frames seen per environment in its episode
        self.negatives: deque[tuple[np.ndarray, int]] = deque(maxlen=CAPACITY)

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

    def state(self) -> dict[str, np.ndarray]:
        """The negatives so far, for a checkpoint (the claims still waiting are not kept)."""
        if not self.negatives:
            return {"embeddings": np.zeros((0, 0), np.float32), "stages": np.zeros(0, np.int64)}
        return {
            "embeddings": np.stack([embedding for embedding, _ in self.negatives]),
            "stages": np.array([stage for _, stage in self.negatives]),
        }

    def restore(self, state: dict[str, np.ndarray]) -> None:
        self.negatives.extend(zip(state["embeddings"], state["stages"].tolist(), strict=True))
