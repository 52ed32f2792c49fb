"""The pixel stage head: P(stage >= s) read straight off the camera frame by a small CNN.

The stage classifier (stage_classifier.py) sees only the frozen embedding, and that embedding
does not keep "this block is inside the goal strip"; the same small CNN trained from scratch
as a stage classifier on the same labelled frames does (measured in docs/reports/reward-signal.md,
"A stage detector that sees the pixels"). It is fitted at calibration (learning/stage_fitting.py),
class-balanced, and stored next to the encoder (`stage_heads.safetensors`).
`RewardConfig.stage_evidence = "pixels"` makes the confirmed tracker use it.

A head may read another camera than the encoder (`view`): an egocentric frame facing the wall
shows no block, so no detector can tell from it which blocks are placed, while a scene camera
always sees the goal strip and every block. The shaping still comes from the encoder's camera;
scoring then needs both frames of every step.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import torch

from .encoders import EncoderConfig, build_encoder, frames_to_tensor, resize_frames
from .stage_classifier import at_least

WEIGHTS_FILE = "stage_heads.safetensors"
# what a head stored without these settings was fitted with: the encoder's camera, 48 px
STORED_BEFORE: dict[str, Any] = {"view": None, "image_size": 48}


@dataclass(frozen=True)
class StageHeadConfig:
    """Fitting the pixel stage head (Adam on class-balanced batches; minutes per scheme at 96 px)."""

    # frames are downscaled to this (the encoders' size: no downscaling; docs/reports/reward-signal.md
    # measures 48 against 96 px)
    image_size: int = EncoderConfig.image_size
    widths: tuple[int, ...] = (16, 32, 32, 32)
    # training iterations, 0: no head (this and max_demos chosen in docs/reports/reward-signal.md)
    iterations: int = 3000
    batch_size: int = 128
    learning_rate: float = 1e-3
    max_demos: int = 600  # the first demonstrations of the training split
    # the share of every batch drawn from frames within BOUNDARY_FRAMES of a stage change, where a
    # block has just crossed into the strip (or not yet): the frames a tracker's completion turns on
    boundary_share: float = 0.0
    seed: int = 0
    # the camera it reads; None: the encoder's. The scene camera by default: it always sees the
    # strip and every block (docs/reports/reward-signal.md, "A stage detector on the scene camera")
    view: str | None = "allo"

    def __post_init__(self) -> None:
        object.__setattr__(self, "widths", tuple(self.widths))  # JSON gives a list
        if self.view is not None and not self.view:
            raise ValueError("stage head: view must name a camera (None: the encoder's)")
        if self.iterations < 0 or min(self.batch_size, self.max_demos) < 1 or self.learning_rate <= 0:
            raise ValueError("stage head: iterations >= 0, batch_size and max_demos >= 1, learning_rate > 0")
        if not 0.0 <= self.boundary_share < 1.0:
            raise ValueError(f"stage head: boundary_share must be in [0, 1), got {self.boundary_share}")
        if self.image_size < 16:
            raise ValueError(f"stage head: image_size must be at least 16 pixels, got {self.image_size}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


class StageHead:
    """A frame classifier over the stages 0..K of one subtask scheme; `at_least` as StageClassifier's."""

    def __init__(self, config: StageHeadConfig, num_stages: int) -> None:
        self.config, self.num_stages = config, num_stages
        encoder = EncoderConfig(image_size=config.image_size, embedding_dim=num_stages, widths=config.widths)
        self.network = build_encoder(encoder).eval()

    @torch.inference_mode()
    def probabilities(self, frames: np.ndarray, batch_size: int = 256) -> np.ndarray:
        """uint8 (N, H, W, 3) frames of any size -> (N, K + 1) P(stage = j)."""
        frames = resize_frames(np.asarray(frames), self.config.image_size)
        logits = [
            self.network(frames_to_tensor(frames[start : start + batch_size]))
            for start in range(0, len(frames), batch_size)
        ]
        if not logits:
            return np.zeros((0, self.num_stages), np.float32)
        return torch.softmax(torch.cat(logits), dim=1).numpy()

    def at_least(self, frames: np.ndarray) -> np.ndarray:
        """(N, K + 1): column j = P(stage >= j) (column 0 is 1)."""
        return at_least(self.probabilities(frames))

    def to_dict(self) -> dict[str, Any]:
        """What model.json keeps; the weights go to WEIGHTS_FILE."""
        return {"num_stages": self.num_stages, "config": self.config.to_dict()}

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> StageHead:
        """An untrained head of the described shape, for the weights to be loaded into. A head
        stored before a setting existed gets the value it was fitted with, not today's default."""
        config = {**STORED_BEFORE, **data["config"]}
        return cls(StageHeadConfig(**config), int(data["num_stages"]))
