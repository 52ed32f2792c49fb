"""The stage classifier: P(stage | embedding), a tiny MLP on the frozen embedding, the idea of
the stage-aware reward models (e.g. SARM). Fitted at calibration (learning/stage_fitting.py)
and stored in model.json next to the goals; numpy at inference.
"""

from __future__ import annotations

from typing import Any

import numpy as np


def at_least(probabilities: np.ndarray) -> np.ndarray:
    """(N, K + 1) P(stage = j) -> (N, K + 1) P(stage >= j) (column 0 is 1)."""
    return np.flip(np.cumsum(np.flip(probabilities, axis=1), axis=1), axis=1)


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
        return at_least(self.probabilities(embeddings))

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
