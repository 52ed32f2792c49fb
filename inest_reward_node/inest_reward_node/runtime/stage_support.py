"""The demonstrations' support of each stage: a frame counts as evidence that stage j is reached
only if its embedding lies within the radius of some demonstration frame of stage j.

Why: a stage classifier says something about every frame, also about frames no demonstration
resembles, and a trained policy finds such frames (facing the wall inside the goal reads as "a
block placed"). The frames the reward rightly confirms a block on look like demonstrations of that
stage; the frames it is fooled by do not (docs/reports/exploit-suite.md). The radius of stage j
is a quantile of held-out demonstration frames' distances to the nearest reference frame of
their own stage, so it needs no labelled negative. Numpy at inference: a few thousand distances
per frame.
"""

from __future__ import annotations

from typing import Any

import numpy as np

WEIGHTS_FILE = "stage_support.safetensors"  # in the model folder, keyed <scheme>.stage<j>


class StageSupport:
    """Reference embeddings and a radius per stage j = 1..K (stage 0 is always supported)."""

    def __init__(self, references: list[np.ndarray], radii: list[float], quantile: float) -> None:
        self.references = [np.asarray(ref, np.float32) for ref in references]
        self.radii = np.asarray(radii, np.float64)
        self.quantile = quantile

    @property
    def num_stages(self) -> int:
        return len(self.references) + 1

    def distances(self, embeddings: np.ndarray) -> np.ndarray:
        """(N, K + 1): each frame's distance to the nearest reference frame of stage j (column 0: 0)."""
        x = np.asarray(embeddings, np.float32)
        columns = [np.zeros(len(x))]
        for ref in self.references:
            squared = (x * x).sum(1)[:, None] - 2 * x @ ref.T + (ref * ref).sum(1)[None]
            columns.append(np.sqrt(np.maximum(squared.min(axis=1), 0.0)))
        return np.stack(columns, axis=1)

    def supported(self, embeddings: np.ndarray) -> np.ndarray:
        """(N, K + 1) bool: frame within the support of stage j."""
        return self.distances(embeddings) <= np.concatenate([[np.inf], self.radii])[None]

    def to_dict(self) -> dict[str, Any]:
        """What model.json keeps; the reference embeddings go to WEIGHTS_FILE (tensors)."""
        return {
            "quantile": self.quantile,
            "radii": self.radii.tolist(),
            "references": [len(r) for r in self.references],
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StageSupport:
        """Its radii; the references are empty until load_model fills them from WEIGHTS_FILE."""
        return cls([np.zeros((count, 0), np.float32) for count in data["references"]], data["radii"], data["quantile"])

    def tensors(self, scheme: int) -> dict[str, np.ndarray]:
        return {f"{scheme}.stage{j + 1}": ref for j, ref in enumerate(self.references)}

    def fill(self, scheme: int, tensors: dict[str, np.ndarray]) -> None:
        """The reference embeddings of `scheme` from WEIGHTS_FILE's tensors."""
        self.references = [
            np.asarray(tensors[f"{scheme}.stage{j + 1}"], np.float32) for j in range(len(self.references))
        ]


def gate(at_least: np.ndarray, supported: np.ndarray, completed: int) -> np.ndarray:
    """(K + 1,) P(stage >= j) with no evidence for a stage above the `completed` ones from a frame
    outside that stage's support (stages already completed keep theirs: an odd frame never reopens)."""
    gated = at_least.copy()
    above = np.arange(len(gated)) > completed
    gated[above & ~supported] = 0.0
    return np.minimum.accumulate(gated)
