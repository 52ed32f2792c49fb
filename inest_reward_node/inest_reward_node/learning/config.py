"""The offline learning settings, one typed place: pretraining (`PretrainConfig`) and calibration
(`CalibrationConfig`), as `inest-pretrain` writes them to RUN/config.json."""

from __future__ import annotations

from dataclasses import asdict, dataclass, field
from typing import Any, Literal

from inest_common.settings import CHOICES, check_choices
from inest_sim_node.config import VIEWS

from ..runtime.encoders import EncoderConfig
from ..runtime.holdr import HoldRConfig
from ..runtime.model import MODEL_KINDS, TCC_SCHEMES
from ..runtime.reds import RedsConfig
from ..runtime.shaping import ShapingConfig
from ..runtime.stage_head import StageHeadConfig
from ..runtime.stage_window import check_offsets
from .data import AugmentConfig
from .stage_fitting import StageClassifierConfig

# PretrainConfig fields each method's objective (objectives.py) never reads: a resumed run may change them freely
UNUSED_SETTINGS: dict[str, frozenset[str]] = {
    "tcc": frozenset({"holdr", "reds", "pairs_per_batch"}),
    "holdr": frozenset({"reds", "videos_per_batch", "frames_per_video", "temperature"}),
    "reds": frozenset({"holdr", "videos_per_batch", "frames_per_video", "pairs_per_batch", "temperature"}),
}


@dataclass(frozen=True)
class CalibrationConfig:
    """Thresholds: for each demonstration, the lowest reward over the last `hold_steps` frames of the
    subtask (all of them must clear the threshold for the tracker to advance); the threshold is
    the `percentile`-th of those over the training demonstrations, so about (100 - percentile) %
    of them would complete the subtask where it really ends.

    Demonstrations alone cannot show what the tracker does on behaviour they never contain: the
    encoder maps unseen frames anywhere, and random play can hold a demonstration threshold
    without the block anywhere near the goal (docs/design.md, "Calibration"). So the threshold
    is then raised, where needed, until at most `false_fire_rate` of `random_episodes`
    random-policy episodes would complete the subtask on frames where it is
    not really complete (negatives) — but never so far that fewer than `demo_pass_rate` of the
    demonstrations would complete it before `late_frames` frames after its end.

    The stage classifier (stage_fitting.py) is fitted on the demonstrations, the same random-policy
    episodes and `wrong_order_episodes` episodes of the scripted expert placing the blocks in a
    wrong order (inest_sim_node.expert.ScriptedExpert(order=...)), every frame labelled with the
    simulator's true ordered progress, and on the labelled `clips` files (clips.py; e.g. a trained
    policy's own rollouts from inest-record-clips, whose frames the classifier must not mistake
    for progress). The pixel stage head (runtime/stage_head.py) is fitted on the same frames (the first
    `stage_head.max_demos` demonstrations). The thresholds use random play only, and the clip files'
    episodes too with `clips_raise_thresholds`: a robot's labelled episodes, which stand in for the
    simulator's random play where there is no simulator."""

    percentile: float = 2.0
    random_episodes: int = 50  # 0: demonstrations only
    false_fire_rate: float = 0.1
    demo_pass_rate: float = 0.98
    late_frames: int = 10
    wrong_order_episodes: int = 20  # for the stage classifier only; 0: none
    clips: tuple[str, ...] = ()  # clip files (clips.save_clips) for the stage classifier ...
    clips_raise_thresholds: bool = False  # ... and, with this, for the thresholds as random play
    classifier: StageClassifierConfig = field(default_factory=StageClassifierConfig)
    stage_head: StageHeadConfig = field(default_factory=StageHeadConfig)  # the pixel one, same frames
    # the subtask schemes that get a pixel stage head (each costs `stage_head.iterations`); a scheme
    # without one reads the embedding's stage classifier (reward.stage_evidence auto)
    stage_head_subtasks: tuple[Literal[TCC_SCHEMES], ...] = TCC_SCHEMES
    # labelled clip files recorded through the pixel stage head's camera (inest-label-clips), for
    # the head alone: a scene-camera head's negatives where the simulator labels none
    stage_head_clips: tuple[str, ...] = ()
    # the window stage classifier (runtime/stage_window.py): the frames back it reads, () for none;
    # fitted on the same frames as the stage classifier and on `demo_negatives` rewound and as many
    # reordered demonstrations (demo_negatives.py), which need no labels of their own
    window_offsets: tuple[int, ...] = ()
    demo_negatives: int = 0
    # the demonstrations' support of each stage (runtime/stage_support.py): the quantile of
    # held-out demonstration frames' distances its radius covers; 0: none fitted
    stage_support_quantile: float = 0.0
    stage_support_references: int = 2000  # reference frames kept per stage, at most

    def __post_init__(self) -> None:
        check_choices(self)
        if not 0.0 <= self.stage_support_quantile <= 1.0 or self.stage_support_references < 1:
            raise ValueError("stage_support_quantile must be in [0, 1] and stage_support_references >= 1")
        if self.window_offsets:
            check_offsets(self.window_offsets)
        if self.demo_negatives < 0:
            raise ValueError(f"demo_negatives must be >= 0, got {self.demo_negatives}")
        if not 0.0 <= self.percentile <= 100.0:
            raise ValueError(f"percentile must be in [0, 100], got {self.percentile}")
        if self.random_episodes < 0 or not 0.0 <= self.false_fire_rate <= 1.0 or not 0.0 < self.demo_pass_rate <= 1.0:
            raise ValueError("random_episodes must be >= 0, false_fire_rate in [0, 1], demo_pass_rate in (0, 1]")
        if self.wrong_order_episodes < 0:
            raise ValueError(f"wrong_order_episodes must be >= 0, got {self.wrong_order_episodes}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True)
class PretrainConfig:
    dataset: str  # the demonstration dataset folder (inest-collect-demos)
    # the representation (runtime/model.py MODEL_KINDS): tcc (XIRL, INEST), holdr or reds
    method: str = field(default="tcc", metadata={CHOICES: lambda: tuple(MODEL_KINDS)})
    view: Literal[VIEWS] = "ego"  # the camera the encoder learns from
    encoder: EncoderConfig = field(default_factory=EncoderConfig)
    holdr: HoldRConfig = field(default_factory=HoldRConfig)
    reds: RedsConfig = field(default_factory=RedsConfig)  # REDS: network, batch and loss settings
    iterations: int = 1500
    videos_per_batch: int = 8  # TCC: videos per batch, all ordered pairs used
    frames_per_video: int = 32
    pairs_per_batch: int = 64  # HOLD-R: (frame, goal) pairs per batch
    learning_rate: float = 3e-4  # XIRL fine-tunes at 1e-5; training from scratch needs more
    weight_decay: float = 1e-5
    temperature: float = 1.0
    augment: AugmentConfig = field(default_factory=AugmentConfig)
    validate_every: int = 100
    validation_batches: int = 4
    checkpoint_every: int = 250
    train_limit: int | None = None  # use only the first N demonstrations of a split (tests, quick runs)
    valid_limit: int | None = None
    seed: int = 0
    threads: int = 2
    device: str = "cpu"  # where the network trains ("cuda" on a GPU machine); calibration runs on the CPU
    shaping: ShapingConfig = field(default_factory=ShapingConfig)
    calibration: CalibrationConfig = field(default_factory=CalibrationConfig)

    def __post_init__(self) -> None:
        check_choices(self)
        if self.calibration.stage_head.view not in (None, *VIEWS):  # the simulator's cameras
            raise ValueError(f"unknown view {self.calibration.stage_head.view!r}; expected one of {VIEWS}")
        for name in ("iterations", "videos_per_batch", "frames_per_video", "pairs_per_batch", "threads"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if self.device != "cpu" and not self.device.startswith("cuda"):
            raise ValueError(f"unknown device {self.device!r}; expected 'cpu' or 'cuda'")
        if self.method == "tcc" and self.videos_per_batch < 2:
            raise ValueError("TCC needs at least 2 videos per batch")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def settings_that_matter(self) -> set[str]:
        """Fields that change what this method trains, which a resumed run must keep. `iterations`
        may grow; shaping and calibration only affect the goals computed at the end."""
        unused = UNUSED_SETTINGS.get(self.method, frozenset({"holdr", "reds"}))  # a kind added since: the others'
        return set(self.to_dict()) - unused - {"iterations", "device", "shaping", "calibration"}
