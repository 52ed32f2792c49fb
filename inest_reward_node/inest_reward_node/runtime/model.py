"""Trained reward models on disk and in memory.

A model folder holds `weights.safetensors` (tensors only, nothing executable) and
`model.json`: method, encoder config, the baselines' network settings (`holdr`, `reds`),
input size, camera view, hash of the training dataset, and per subtask scheme the goal
embeddings (REDS: its learned subtask embeddings), XIRL distance scale, completion
thresholds, the raw distance to each goal where its subtask starts (`start_distances`, a
record of the calibration), the mean embedding where each subtask starts (`start_embeddings`,
for segment shaping and the confirmed tracker's reopening), the stage classifier
(`stage_classifier`, see stage_classifier.py) and the pixel stage head's shape (`stage_head`,
see stage_head.py; its weights in `stage_heads.safetensors`). Models calibrated before the last
four existed load without them; a reward that needs them raises a ModelError naming the fix.
Loading checks the caller's expectations (view, size, scheme). `ModelMetadata` is model.json
(less its format header) read into typed fields.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from inest_common.files import read_versioned_json, sha256_of, write_atomic
from safetensors import SafetensorError
from safetensors.torch import load_file, save_file
from torch import nn
from torch.fx.experimental.optimization import fuse

from .encoders import EncoderConfig, build_encoder, frames_to_tensor, resize_frames
from .holdr import HoldR, HoldRConfig
from .reds import Reds, RedsConfig, infer_subtasks
from .shaping import ShapingConfig
from .stage_classifier import StageClassifier
from .stage_head import WEIGHTS_FILE as STAGE_HEADS_FILE
from .stage_head import StageHead
from .stage_support import WEIGHTS_FILE as STAGE_SUPPORT_FILE
from .stage_support import StageSupport
from .stage_window import StageWindow

MODEL_FORMAT = "inest-reward-model"
MODEL_FORMAT_VERSION = 1
WEIGHTS_FILE = "weights.safetensors"
MODEL_FILE = "model.json"
TCC_SCHEMES = (1, 3, 6)  # the subtask schemes a TCC model is calibrated for
# the reward model the product ships, relative to the checkout: its scores, and the trained policy
# that uses it, are in docs/reports/early-models.md
DEFAULT_MODEL = "results/long-horizon/reward-model-scene96-600demos"
CHECKOUT = Path(__file__).resolve().parents[3]  # this source tree's root (an installed copy has no results/)


class ModelError(RuntimeError):
    """A model folder is missing, corrupt, or does not match what the caller needs."""


@dataclass(frozen=True)
class ModelKind:
    """A kind of reward model (model.json's `method`, inest-pretrain --method): how its network is
    built from the encoder settings and its own settings (HOLD-R's and REDS's; None for a kind
    without), the subtask schemes calibration gives it goals for, and the reward methods
    (runtime/methods.py) that score with it by default, for one subtask and for several. A new
    kind is one entry here, its objective in learning/objectives.py and its reward method
    (docs/design.md, "Adding a reward method")."""

    name: str
    build: Callable[[EncoderConfig, Any], nn.Module]
    rewards: tuple[str, str]
    schemes: tuple[int, ...] = (1,)

    def default_reward(self, scheme: int) -> str:
        return self.rewards[scheme > 1]


def build_holdr(encoder: EncoderConfig, settings: HoldRConfig | None) -> nn.Module:
    network = HoldR(settings or HoldRConfig(), encoder.image_size)
    return network.to(memory_format=torch.channels_last) if encoder.channels_last else network


MODEL_KINDS: dict[str, ModelKind] = {
    kind.name: kind
    for kind in (
        ModelKind("tcc", lambda encoder, _: build_encoder(encoder), ("xirl", "inest"), TCC_SCHEMES),
        ModelKind("holdr", build_holdr, ("holdr", "holdr")),
        ModelKind("reds", lambda encoder, settings: Reds(settings or RedsConfig(), encoder), ("reds", "reds")),
    )
}


def model_kind(method: str) -> ModelKind:
    if method not in MODEL_KINDS:
        raise ValueError(f"unknown method {method!r}; expected one of {tuple(MODEL_KINDS)}")
    return MODEL_KINDS[method]


def build_network(
    method: str, encoder: EncoderConfig, holdr: HoldRConfig | None = None, reds: RedsConfig | None = None
) -> nn.Module:
    return model_kind(method).build(encoder, {"holdr": holdr, "reds": reds}.get(method))


RECALIBRATE_HINT = (
    "recalibrate it: `inest-pretrain DATASET --out RUN --resume` (RUN: the run folder holding model/), "
    "or `inest-pretrain DATASET --out NEW_RUN --recalibrate MODEL` for a model folder on its own"
)


@dataclass
class SubtaskGoals:
    goals: np.ndarray  # (subtasks, D)
    thresholds: list[float]  # on the method's per-frame reward, one per subtask
    distance_scale: float  # XIRL: 1 / mean distance from first frames to the final goal
    # mean raw distance to goal k on the frame where subtask k starts (training demos); None: an older model
    start_distances: list[float] | None = None
    stage_classifier: StageClassifier | None = None  # P(true stage | embedding); None: an older model
    start_embeddings: np.ndarray | None = None  # (subtasks, D) mean embedding where each subtask starts
    stage_head: StageHead | None = None  # P(true stage | frame) from pixels; None: an older model
    stage_window: StageWindow | None = None  # P(true stage | a causal window of embeddings); None: not fitted
    stage_support: StageSupport | None = None  # the demonstrations' support of each stage; None: not fitted

    def to_dict(self) -> dict[str, Any]:
        data: dict[str, Any] = {
            "goals": self.goals.tolist(),
            "thresholds": self.thresholds,
            "distance_scale": self.distance_scale,
        }
        if self.start_distances is not None:
            data["start_distances"] = self.start_distances
        if self.start_embeddings is not None:
            data["start_embeddings"] = np.asarray(self.start_embeddings).tolist()
        if self.stage_classifier is not None:
            data["stage_classifier"] = self.stage_classifier.to_dict()
        if self.stage_head is not None:
            data["stage_head"] = self.stage_head.to_dict()
        if self.stage_window is not None:
            data["stage_window"] = self.stage_window.to_dict()
        if self.stage_support is not None:
            data["stage_support"] = self.stage_support.to_dict()
        return data

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> SubtaskGoals:
        starts = data.get("start_distances")
        goals = np.asarray(data["goals"], dtype=np.float32)
        if starts is None and len(goals) == 1:  # derivable: the XIRL scale is 1 / the same mean distance
            starts = [1.0 / float(data["distance_scale"])]
        classifier = data.get("stage_classifier")
        start_embeddings = data.get("start_embeddings")
        head = data.get("stage_head")
        window = data.get("stage_window")
        support = data.get("stage_support")
        return cls(
            goals,
            list(data["thresholds"]),
            float(data["distance_scale"]),
            None if starts is None else [float(value) for value in starts],
            None if classifier is None else StageClassifier.from_dict(classifier),
            None if start_embeddings is None else np.asarray(start_embeddings, dtype=np.float32),
            None if head is None else StageHead.from_dict(head),  # untrained until load_model fills it
            None if window is None else StageWindow.from_dict(window),
            None if support is None else StageSupport.from_dict(support),
        )

    def required(self, value: Any, missing: str) -> Any:
        """`value`, or a ModelError saying what the model lacks for its goals and how to refit it."""
        if value is None:
            raise ModelError(f"this model has no {missing.format(subtasks=len(self.goals))}; {RECALIBRATE_HINT}")
        return value

    def require_start_embeddings(self) -> np.ndarray:
        return self.required(
            self.start_embeddings,
            "per-subtask start embeddings for its {subtasks}-subtask goals "
            "(calibrated before segment shaping and reopening existed)",
        )

    def require_stage_classifier(self) -> StageClassifier:
        return self.required(
            self.stage_classifier,
            "stage classifier for its {subtasks}-subtask goals (calibrated before stage classifiers existed)",
        )

    def require_stage_head(self) -> StageHead:
        return self.required(
            self.stage_head,
            "pixel stage head for its {subtasks}-subtask goals (not fitted: "
            "inest-pretrain --stage-head-subtasks, or calibrated before the head existed)",
        )

    def require_stage_support(self) -> StageSupport:
        return self.required(
            self.stage_support,
            "stage support for its {subtasks}-subtask goals (not fitted: inest-pretrain --stage-support-quantile)",
        )

    def require_stage_window(self) -> StageWindow:
        return self.required(
            self.stage_window,
            "window stage classifier for its {subtasks}-subtask goals "
            "(not fitted: inest-pretrain --stage-window-offsets)",
        )


@dataclass(eq=False)  # holds arrays: compare the to_dict() documents instead
class ModelMetadata:
    """What a model was trained and calibrated with. The training records stay as written (absent
    in hand-built models): `dataset` (path, sha256), `training` (iterations, the pretraining
    config), `calibration` (the calibration config), `supervision` (what the calibration was
    fitted on: demonstrations, labelled negative episodes and their labeller, cameras;
    learning/calibrate.py `supervision`; absent in models calibrated before it was recorded)."""

    method: str
    view: str
    encoder: EncoderConfig
    shaping: ShapingConfig
    subtasks: dict[int, SubtaskGoals]  # per subtask scheme
    holdr: HoldRConfig | None = None
    reds: RedsConfig | None = None
    dataset: dict[str, Any] = field(default_factory=dict)
    training: dict[str, Any] = field(default_factory=dict)
    calibration: dict[str, Any] = field(default_factory=dict)
    supervision: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> ModelMetadata:
        return cls(
            method=data["method"],
            view=data["view"],
            encoder=EncoderConfig(**data["encoder"]),
            shaping=ShapingConfig(**data["shaping"]),
            subtasks={int(scheme): SubtaskGoals.from_dict(goals) for scheme, goals in data["subtasks"].items()},
            holdr=HoldRConfig(**data["holdr"]) if data.get("holdr") else None,
            reds=RedsConfig(**data["reds"]) if data.get("reds") else None,
            dataset=data.get("dataset", {}),
            training=data.get("training", {}),
            calibration=data.get("calibration", {}),
            supervision=data.get("supervision", {}),
        )

    def to_dict(self) -> dict[str, Any]:
        """The document model.json holds after its format header."""
        return {
            "method": self.method,
            "view": self.view,
            "encoder": self.encoder.to_dict(),
            "holdr": None if self.holdr is None else self.holdr.to_dict(),
            "reds": None if self.reds is None else self.reds.to_dict(),
            "dataset": self.dataset,
            "training": self.training,
            "shaping": self.shaping.to_dict(),
            "calibration": self.calibration,
            "supervision": self.supervision,
            "subtasks": {str(scheme): goals.to_dict() for scheme, goals in self.subtasks.items()},
        }


class RewardModel:
    """A frozen network plus what it was calibrated with; embeds frames in batches."""

    def __init__(self, network: nn.Module, metadata: ModelMetadata) -> None:
        self.network = network.eval()
        # batch norm folded into the convolutions (a copy: a training network passed in stays as it is);
        # about a third off the small CNN's forward pass at the batch sizes the reward runs at
        self.inference = fuse(network) if metadata.method == "tcc" else self.network
        self.metadata = metadata
        self.method, self.view, self.encoder_config = metadata.method, metadata.view, metadata.encoder
        self.shaping, self.subtasks = metadata.shaping, metadata.subtasks
        self._steps_at_goal: dict[bytes, float] = {}  # HOLD-R's d(g, g), fixed per goal

    @property
    def image_size(self) -> int:
        return self.encoder_config.image_size

    def goals(self, scheme: int) -> SubtaskGoals:
        if scheme not in self.subtasks:
            raise ModelError(
                f"this {self.method} model has goal embeddings for {sorted(self.subtasks)} subtasks, not {scheme}"
            )
        return self.subtasks[scheme]

    @torch.inference_mode()
    def embed(self, frames: np.ndarray, batch_size: int = 256) -> np.ndarray:
        """uint8 (N, H, W, 3) RGB frames -> (N, D) float32 embeddings. Frames already at
        `image_size` (the reward node's, fitted as they were decoded) are encoded as they are;
        frames of any other size are fitted here (images.fit_square), once."""
        frames = resize_frames(np.asarray(frames), self.image_size)
        outputs = [
            self.inference(frames_to_tensor(frames[start : start + batch_size], self.encoder_config.channels_last))
            for start in range(0, len(frames), batch_size)
        ]
        return torch.cat(outputs).numpy() if outputs else np.zeros((0, self.encoder_config.embedding_dim), np.float32)

    @torch.inference_mode()
    def holdr_steps(self, embeddings: np.ndarray, goal: np.ndarray) -> np.ndarray:
        """HOLD-R's predicted steps from each embedded frame to the embedded goal."""
        if self.method != "holdr":
            raise ModelError(f"predicted steps need a holdr model, this one is {self.method}")
        frames = torch.as_tensor(embeddings, dtype=torch.float32)
        goals = torch.as_tensor(goal, dtype=torch.float32).expand_as(frames)
        return (self.network.gap(frames, goals) * self.network.config.steps_unit).numpy()

    def holdr_steps_at_goal(self, goal: np.ndarray) -> float:
        """d(g, g): computed once per goal, not on every scored frame."""
        key = np.asarray(goal, dtype=np.float32).tobytes()
        if key not in self._steps_at_goal:
            self._steps_at_goal[key] = float(self.holdr_steps(goal[None], goal)[0])
        return self._steps_at_goal[key]

    def require_reds(self, what: str) -> None:
        if self.method != "reds":
            raise ModelError(f"{what} need a reds model, this one is {self.method}")

    @torch.inference_mode()
    def reds_rewards(self, embeddings: np.ndarray, subtask_embeddings: np.ndarray) -> np.ndarray:
        """(N, K): REDS's reward R(frame, z_k) of each embedded frame for every subtask embedding."""
        self.require_reds("REDS rewards")
        frames = torch.as_tensor(np.asarray(embeddings), dtype=torch.float32)
        columns = [
            self.network.reward(frames, torch.as_tensor(z, dtype=torch.float32).expand_as(frames))
            for z in np.asarray(subtask_embeddings)
        ]
        return torch.stack(columns, dim=1).numpy() if len(frames) else np.zeros((0, len(subtask_embeddings)))

    def reds_subtasks(self, embeddings: np.ndarray, subtask_embeddings: np.ndarray) -> np.ndarray:
        """(N,): the subtask each embedded frame is in, as REDS infers it (reds.infer_subtasks)."""
        self.require_reds("REDS subtasks")
        if not len(embeddings):
            return np.zeros(0, dtype=np.int64)
        return infer_subtasks(embeddings, subtask_embeddings, self.network.config.subtask_bias)

    def reds_subtask_embeddings(self) -> np.ndarray:
        """(K, D): REDS's learned subtask embeddings (calibration copies them into the goals)."""
        self.require_reds("REDS subtask embeddings")
        return self.network.subtask_embeddings.detach().cpu().numpy().astype(np.float32)


def save_model(folder: str | Path, network: nn.Module, metadata: ModelMetadata) -> None:
    """Weights first, then the JSON that makes the folder loadable, each by atomic rename."""
    folder = Path(folder)
    tensors = {name: tensor.detach().contiguous().cpu() for name, tensor in network.state_dict().items()}
    write_atomic(folder / WEIGHTS_FILE, lambda path: save_file(tensors, str(path)))
    heads = {
        f"{scheme}.{name}": tensor.detach().contiguous().cpu()
        for scheme, goals in metadata.subtasks.items()
        if goals.stage_head is not None
        for name, tensor in goals.stage_head.network.state_dict().items()
    }
    if heads:
        write_atomic(folder / STAGE_HEADS_FILE, lambda path: save_file(heads, str(path)))
    support = {
        name: torch.from_numpy(np.ascontiguousarray(reference))
        for scheme, goals in metadata.subtasks.items()
        if goals.stage_support is not None
        for name, reference in goals.stage_support.tensors(scheme).items()
    }
    if support:
        write_atomic(folder / STAGE_SUPPORT_FILE, lambda path: save_file(support, str(path)))
    document = {"format": MODEL_FORMAT, "format_version": MODEL_FORMAT_VERSION, **metadata.to_dict()}
    write_atomic(folder / MODEL_FILE, lambda path: path.write_text(json.dumps(document, indent=2) + "\n"))


def read_model_metadata(folder: str | Path) -> ModelMetadata:
    path = Path(folder) / MODEL_FILE
    document = read_versioned_json(path, MODEL_FORMAT, MODEL_FORMAT_VERSION, "reward model", ModelError)
    try:
        return ModelMetadata.from_dict(document)
    except (KeyError, TypeError, ValueError) as error:
        raise ModelError(f"{path} is not a valid reward model description ({type(error).__name__}: {error})") from error


def check_expectations(
    metadata: ModelMetadata, folder: Path, view: str | None, image_size: int | None, scheme: int | None
) -> None:
    trained = f"{folder} was trained on the {metadata.view!r} camera at {metadata.encoder.image_size} px"
    if view is not None and view != metadata.view:
        raise ModelError(f"view mismatch: {trained}, but the caller uses the {view!r} camera")
    if image_size is not None and image_size != metadata.encoder.image_size:
        raise ModelError(f"input size mismatch: {trained}, but the caller asked for {image_size} px")
    if scheme is not None and scheme not in metadata.subtasks:
        raise ModelError(
            f"subtask scheme mismatch: {folder} has goals for {sorted(metadata.subtasks)} "
            f"subtasks, but the caller asked for {scheme}"
        )


def model_folder(folder: str | Path) -> Path:
    """The folder a model path names: a relative one missing from the working folder is the
    checkout's (DEFAULT_MODEL and the committed runs' models are found from anywhere)."""
    folder = Path(folder)
    if not folder.is_absolute() and not folder.exists() and (CHECKOUT / folder).exists():
        return CHECKOUT / folder
    return folder


def encoder_digest(folder: str | Path) -> str:
    """sha256 of the model's encoder weights: two models with the same embed frames alike."""
    return sha256_of(model_folder(folder) / WEIGHTS_FILE)


def load_weights(network: nn.Module, tensors: dict[str, torch.Tensor], source: Path) -> None:
    """`tensors` into `network`; weights made for another architecture than model.json describes
    are one short ModelError saying how they differ (torch's own message lists every tensor)."""
    expected = network.state_dict()
    missing = sorted(set(expected) - set(tensors))
    unexpected = sorted(set(tensors) - set(expected))
    reshaped = sorted(name for name in set(expected) & set(tensors) if expected[name].shape != tensors[name].shape)
    differences = []
    if missing:
        differences.append(f"{len(missing)} tensor(s) missing (first {missing[0]})")
    if unexpected:
        differences.append(f"{len(unexpected)} the network lacks (first {unexpected[0]})")
    if reshaped:
        name = reshaped[0]
        shapes = f"{tuple(tensors[name].shape)} where the network has {tuple(expected[name].shape)}"
        differences.append(f"{len(reshaped)} of another shape (first {name}: {shapes})")
    if differences:
        raise ModelError(
            f"{source} holds weights of another architecture than its {MODEL_FILE} describes: {'; '.join(differences)}"
        )
    network.load_state_dict(tensors)


def load_model(
    folder: str | Path, view: str | None = None, image_size: int | None = None, scheme: int | None = None
) -> RewardModel:
    """Load a model folder; any expectation given (view, input size, subtask scheme) must match it.
    A relative folder missing from the working folder is the checkout's (model_folder)."""
    folder = model_folder(folder)
    metadata = read_model_metadata(folder)
    check_expectations(metadata, folder, view, image_size, scheme)
    if metadata.method == "reds" and metadata.reds is None:
        raise ModelError(f"{folder / MODEL_FILE} is a reds model without its `reds` network settings")
    network = build_network(metadata.method, metadata.encoder, metadata.holdr, metadata.reds)
    try:
        load_weights(network, load_file(str(folder / WEIGHTS_FILE)), folder / WEIGHTS_FILE)
    except (FileNotFoundError, SafetensorError, RuntimeError) as error:
        raise ModelError(f"cannot load weights from {folder / WEIGHTS_FILE}: {error}") from error
    heads = {scheme: goals.stage_head for scheme, goals in metadata.subtasks.items() if goals.stage_head is not None}
    if heads:
        try:
            tensors = load_file(str(folder / STAGE_HEADS_FILE))
            for scheme, head in heads.items():
                prefix = f"{scheme}."
                load_weights(
                    head.network,
                    {name[len(prefix) :]: tensor for name, tensor in tensors.items() if name.startswith(prefix)},
                    folder / STAGE_HEADS_FILE,
                )
        except (FileNotFoundError, SafetensorError, RuntimeError) as error:
            raise ModelError(f"cannot load the stage heads from {folder / STAGE_HEADS_FILE}: {error}") from error
    supports = {scheme: goals.stage_support for scheme, goals in metadata.subtasks.items() if goals.stage_support}
    if supports:
        try:
            tensors = {name: tensor.numpy() for name, tensor in load_file(str(folder / STAGE_SUPPORT_FILE)).items()}
            for scheme, support in supports.items():
                support.fill(scheme, tensors)
        except (FileNotFoundError, SafetensorError, KeyError) as error:
            raise ModelError(f"cannot load the stage support from {folder / STAGE_SUPPORT_FILE}: {error}") from error
    return RewardModel(network, metadata)
