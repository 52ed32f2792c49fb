"""Intrinsic novelty bonus (thesis 4.2.3, "Intrinsic Reward Integration").

One FIFO memory of visited vectors per subtask; a frame's novelty is its distance to the
k-th nearest vector already in the memory of the subtask it is in. Memories persist across
episodes (they are the exploration history); only the subtask tracker is reset per episode.
The bonus weight is raised for a few steps after every subtask switch, when the agent has
to find new behaviour.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any, Literal

import numpy as np
import torch
from inest_common.settings import check_choices

INTRINSIC_MODES = ("none", "embedding", "state")


@dataclass(frozen=True)
class IntrinsicConfig:
    # none, embedding (the learned embedding) or state (the raw state vector, thesis 5.2.3)
    mode: Literal[INTRINSIC_MODES] = "embedding"
    capacity: int = 5000  # per subtask, FIFO (thesis)
    k: int = 10  # k-th nearest neighbour (the thesis author's code); capped at the memory's size
    # thesis; inest-train's --intrinsic-weight W also sets boosted_weight to 2 W unless that is given
    weight: float = 0.2
    boosted_weight: float = 0.4  # thesis, for `boost_steps` steps after a subtask switch
    boost_steps: int = 10  # the thesis's n, not given there

    def __post_init__(self) -> None:
        check_choices(self, "intrinsic ")
        for name in ("capacity", "k"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        if self.boost_steps < 0 or min(self.weight, self.boosted_weight) < 0:
            raise ValueError("intrinsic weights and boost_steps must be non-negative")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def weight_after(self, steps_since_switch: np.ndarray | int) -> np.ndarray:
        """Bonus weight for frames `steps_since_switch` steps after the last switch (-1: none yet)."""
        steps = np.asarray(steps_since_switch)
        boosted = (steps >= 0) & (steps < self.boost_steps)
        return np.where(boosted, self.boosted_weight, self.weight)


class NoveltyMemory:
    """A ring buffer of at most `capacity` vectors; the oldest is overwritten first.

    Searched with torch, not numpy: numpy's BLAS starts its own spinning threads once the
    memory is large, and on a small machine they fight the encoder's and SAC's torch threads
    (training slowed once the memories filled). The vectors are stored as columns:
    a few queries times a contiguous (dim, capacity) matrix is faster than times a
    transposed row store.
    """

    def __init__(self, dim: int, capacity: int) -> None:
        self.columns = np.zeros((dim, capacity), dtype=np.float32)
        self.squared_norms = np.zeros(capacity, dtype=np.float32)  # kept with the vectors for fast k-NN
        self._searched = torch.from_numpy(self.columns), torch.from_numpy(self.squared_norms)  # same memory
        self.capacity = capacity
        self.size = 0
        self.next = 0

    def __len__(self) -> int:
        return self.size

    def contents(self) -> np.ndarray:
        """Stored vectors, oldest first."""
        rows = self.columns.T
        if self.size < self.capacity:
            return rows[: self.size].copy()
        return np.concatenate([rows[self.next :], rows[: self.next]])

    @classmethod
    def restored(cls, contents: np.ndarray, capacity: int) -> NoveltyMemory:
        """A memory holding `contents` (oldest first), as `contents()` returned them."""
        memory = cls(contents.shape[1], capacity)
        memory.add(contents)
        return memory

    def add(self, vectors: np.ndarray) -> None:
        vectors = np.asarray(np.atleast_2d(vectors)[-self.capacity :], dtype=np.float32)  # of more, the newest
        slots = (self.next + np.arange(len(vectors))) % self.capacity
        self.columns[:, slots] = vectors.T
        self.squared_norms[slots] = np.square(vectors).sum(1)
        self.next = int((self.next + len(vectors)) % self.capacity)
        self.size = min(self.size + len(vectors), self.capacity)

    def novelty(self, queries: np.ndarray, k: int) -> np.ndarray:
        """Distance of each query to its k-th nearest stored vector (k capped at the size); 0 when empty."""
        queries = torch.as_tensor(np.atleast_2d(queries), dtype=torch.float32)
        if self.size == 0:
            return np.zeros(len(queries))
        # the largest of the k smallest: topk is faster than kthvalue on a full memory
        kth = self._squared_distances(queries).topk(min(k, self.size), dim=1, largest=False, sorted=False).values
        return kth.amax(1).clamp_min(0.0).sqrt().numpy()

    def novelty_in_rounds(self, vectors: np.ndarray, rounds: np.ndarray, k: int) -> np.ndarray:
        """Novelty of each vector against the memory as it stood before its round, each round's
        vectors being added after it (rounds ascending): the same as `novelty` then `add` round by
        round, with one search of the stored vectors instead of one per round."""
        vectors = np.asarray(np.atleast_2d(vectors), dtype=np.float32)
        rounds = np.asarray(rounds)
        if len(rounds) != len(vectors) or np.any(np.diff(rounds) < 0):
            raise ValueError("rounds must give every vector its round, in ascending order")
        if len(vectors) > self.capacity or len(vectors) == 0 or rounds[0] == rounds[-1]:
            return self._novelty_round_by_round(vectors, rounds, k)
        queries = torch.from_numpy(vectors)
        added_before = np.searchsorted(rounds, rounds)  # vectors of earlier rounds, per vector
        # a stored slot is gone once as many vectors were added as there are slots older than it
        age = (np.arange(self.size) - self.next) % self.capacity
        overwritten = torch.from_numpy(age[None, :] < added_before[:, None])
        not_yet_added = torch.from_numpy(rounds[None, :] >= rounds[:, None])
        within = torch.cdist(queries, queries).square_()
        candidates = torch.cat(
            [
                self._squared_distances(queries).masked_fill_(overwritten, np.inf),
                within.masked_fill_(not_yet_added, np.inf),
            ],
            dim=1,
        )
        available = self.size - overwritten.sum(1).numpy() + added_before
        nearest = candidates.topk(min(k, candidates.shape[1]), dim=1, largest=False).values
        kth = nearest[np.arange(len(vectors)), np.clip(np.minimum(k, available) - 1, 0, None)]
        novelty = np.where(available > 0, kth.clamp_min(0.0).sqrt().numpy(), 0.0)
        self.add(vectors)
        return novelty

    def _novelty_round_by_round(self, vectors: np.ndarray, rounds: np.ndarray, k: int) -> np.ndarray:
        novelty = np.zeros(len(vectors))
        for current in np.unique(rounds):
            members = rounds == current
            novelty[members] = self.novelty(vectors[members], k)
            self.add(vectors[members])
        return novelty

    def _squared_distances(self, queries: torch.Tensor) -> torch.Tensor:
        """(queries, size) squared distances to the stored vectors, as |m|^2 - 2 q.m + |q|^2."""
        columns, squared_norms = self._searched
        squared = torch.addmm(squared_norms[: self.size], queries, columns[:, : self.size], alpha=-2.0)
        return squared.add_(queries.square().sum(1, keepdim=True))
