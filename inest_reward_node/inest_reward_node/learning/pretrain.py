"""Pretrain a reward model on demonstration videos (`inest-pretrain`).

`--method tcc` trains the frame encoder with Temporal Cycle-Consistency (INEST-IRL and XIRL
share it: they differ only in their goal embeddings); `--method holdr` trains the HOLD-R
baseline, `--method reds` the REDS baseline without CLIP (runtime/reds.py; `--reds-subtasks`, default
3, is the segmentation it conditions on). Afterwards the goal embeddings (REDS: its learned
subtask embeddings), thresholds, start distances and stage classifier for 1, 3 and 6 subtasks
(HOLD-R: 1; REDS: its own segmentation) are computed from the training demonstrations (and
random and wrong-order play) and the model folder is written; `--resume` on a finished run
recalibrates, and `--recalibrate MODEL` calibrates the trained encoder of any model folder anew
with this command line's calibration settings (minutes, not a pretraining), into `--out`/model.
(Each method's loss lives in objectives.py, calibration in calibrate.py; this module holds the
configuration, the training loop and the command line.)

Run folder: config.json (the full configuration), train_state.pt (weights, optimiser, RNG,
history: the `--resume` point, written every `checkpoint_every` iterations), tensorboard/,
loss.png, and model/ (the finished, loadable model).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
from pathlib import Path

import numpy as np
import torch
from inest_common.files import write_atomic
from inest_common.progress import track
from inest_common.settings import OneLineParser, add_setting_flags, build_settings
from inest_sim_node.dataset import DatasetError, DemoDataset

from ..runtime.model import (
    ModelError,
    ModelMetadata,
    RewardModel,
    SubtaskGoals,
    build_network,
    load_model,
    save_model,
)
from .calibrate import calibrate, supervision
from .clips import load_clips
from .config import PretrainConfig
from .data import Demo, load_demos
from .objectives import OBJECTIVES
from .runs import prepare_run_dir

STATE_FILE = "train_state.pt"
MODEL_DIR = "model"


def dataset_hash(root: str | Path) -> str:
    """The demonstrations' content hash (`DemoDataset.content_hash`): the same for the same
    seeded collection on any machine, unlike the bytes of its files."""
    return DemoDataset(root).content_hash()


def model_metadata(
    config: PretrainConfig, iterations_done: int, subtasks: dict[int, SubtaskGoals], demonstrations: int = 0
) -> ModelMetadata:
    """A model's record; `demonstrations`: the training demonstrations it was calibrated on (0:
    not calibrated yet, no supervision record)."""
    dataset = DemoDataset(config.dataset)
    return ModelMetadata(
        method=config.method,
        view=config.view,
        encoder=config.encoder,
        shaping=config.shaping,
        subtasks=subtasks,
        holdr=config.holdr if config.method == "holdr" else None,
        reds=config.reds if config.method == "reds" else None,
        dataset={"path": str(config.dataset), "sha256": dataset.content_hash()},
        training={"iterations": iterations_done, "config": config.to_dict()},
        calibration=config.calibration.to_dict(),
        supervision=supervision(config, demonstrations, sorted(subtasks), dataset.segmented_by())
        if demonstrations
        else {},
    )


def plot_history(history: dict[str, list[list[float]]], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axis = plt.subplots(figsize=(6, 3.5))
    for name, points in history.items():
        if points:
            steps, values = zip(*points, strict=True)
            axis.plot(steps, values, label=name)
    axis.set(xlabel="iteration", ylabel="loss", yscale="log", title="pretraining loss")
    axis.legend()
    figure.tight_layout()
    figure.savefig(path, dpi=100)
    plt.close(figure)


class Pretrainer:
    def __init__(self, config: PretrainConfig, run_dir: str | Path, resume: bool = False) -> None:
        if config.device.startswith("cuda") and not torch.cuda.is_available():
            raise ValueError(f"--device {config.device}: this torch build sees no GPU")
        self.config = config
        self.run_dir = Path(run_dir)
        self.check_run_dir(resume)
        torch.manual_seed(config.seed)
        self.network = build_network(config.method, config.encoder, config.holdr, config.reds).to(config.device)
        self.optimizer = torch.optim.AdamW(
            self.network.parameters(), lr=config.learning_rate, weight_decay=config.weight_decay
        )
        self.objective = OBJECTIVES[config.method](config, self.network)
        self.rng = np.random.default_rng(config.seed)
        self.generator = torch.Generator().manual_seed(config.seed)
        self.iteration = 0
        self.history: dict[str, list[list[float]]] = {"train": [], "valid": []}
        if resume and (self.run_dir / STATE_FILE).exists():
            self.load_state()

    def check_run_dir(self, resume: bool) -> None:
        settings = self.config.to_dict()
        defaults = PretrainConfig(dataset="").to_dict()
        prepare_run_dir(self.run_dir, settings, resume, self.config.settings_that_matter(), defaults)

    def save_state(self) -> None:
        state = {
            "network": self.network.state_dict(),
            "optimizer": self.optimizer.state_dict(),
            "iteration": self.iteration,
            "numpy_rng": json.dumps(self.rng.bit_generator.state),
            "torch_rng": self.generator.get_state(),
            "history": json.dumps(self.history),
        }
        write_atomic(self.run_dir / STATE_FILE, lambda path: torch.save(state, path))

    def load_state(self) -> None:
        state = torch.load(self.run_dir / STATE_FILE, weights_only=True, map_location=self.config.device)
        self.network.load_state_dict(state["network"])
        self.optimizer.load_state_dict(state["optimizer"])
        self.iteration = int(state["iteration"])
        self.rng.bit_generator.state = json.loads(state["numpy_rng"])
        self.generator.set_state(state["torch_rng"])
        self.history = json.loads(state["history"])

    @torch.no_grad()
    def validation_loss(self, demos: list[Demo]) -> float:
        self.network.eval()
        rng, generator = np.random.default_rng(12345), torch.Generator().manual_seed(12345)
        losses = [float(self.objective.loss(demos, rng, generator)) for _ in range(self.config.validation_batches)]
        self.network.train()
        return float(np.mean(losses))

    def train(self, train: list[Demo], valid: list[Demo], progress_bar: bool = True) -> RewardModel:
        from torch.utils.tensorboard import SummaryWriter

        config = self.config
        torch.set_num_threads(config.threads)
        writer = SummaryWriter(str(self.run_dir / "tensorboard"))
        self.network.train()
        bar = track(
            total=config.iterations,
            initial=self.iteration,
            desc=f"pretrain {config.method}",
            unit="it",
            disable=not progress_bar,
        )
        while self.iteration < config.iterations:
            loss = self.objective.loss(train, self.rng, self.generator)
            self.optimizer.zero_grad(set_to_none=True)
            loss.backward()
            self.optimizer.step()
            self.iteration += 1
            value = loss.item()
            writer.add_scalar("loss/train", value, self.iteration)
            self.history["train"].append([self.iteration, value])
            postfix = {"loss": f"{value:.4f}"}
            if valid and (self.iteration % config.validate_every == 0 or self.iteration == config.iterations):
                validation = self.validation_loss(valid)
                writer.add_scalar("loss/valid", validation, self.iteration)
                self.history["valid"].append([self.iteration, validation])
                postfix["valid"] = f"{validation:.4f}"
            bar.set_postfix(postfix, refresh=False)
            bar.update()
            if self.iteration % config.checkpoint_every == 0 or self.iteration == config.iterations:
                self.save_state()
        bar.close()
        writer.close()
        plot_history(self.history, self.run_dir / "loss.png")
        return self.finish(train, progress_bar)

    def finish(self, train: list[Demo], progress_bar: bool = True) -> RewardModel:
        self.network.to("cpu")
        model = RewardModel(self.network, model_metadata(self.config, self.iteration, {}))
        subtasks = calibrate(model, train, self.config, progress_bar)
        metadata = model_metadata(self.config, self.iteration, subtasks, len(train))
        save_model(self.run_dir / MODEL_DIR, self.network, metadata)
        return load_model(self.run_dir / MODEL_DIR)  # exactly the model a later load gives


def refuse_unfit_clips(config: PretrainConfig) -> None:
    """Read every clip file before any work, so that one that does not fit fails first, not after."""
    calibration = config.calibration
    for path in calibration.clips:
        load_clips(path, config.view, config.encoder.image_size)
    for path in calibration.stage_head_clips:
        load_clips(path, calibration.stage_head.view or config.view, config.encoder.image_size)


def load_split(config: PretrainConfig, split: str, progress_bar: bool) -> list[Demo]:
    """One split of `config.dataset` in the encoder's camera and size, within the split's limit."""
    limit = config.train_limit if split == "train" else config.valid_limit
    return load_demos(config.dataset, split, config.view, config.encoder.image_size, limit, progress_bar)


def recalibrate(
    config: PretrainConfig, source: str | Path, run_dir: str | Path, progress_bar: bool = True
) -> RewardModel:
    """The trained network of the model folder `source`, calibrated on `config.dataset` with
    `config`'s shaping and calibration settings; what it was trained with (method, view,
    encoder, the training record) comes from `source`. Written to `run_dir`/model."""
    trained = load_model(source)
    metadata = trained.metadata
    config = dataclasses.replace(
        config,
        method=metadata.method,
        view=metadata.view,
        encoder=metadata.encoder,
        holdr=metadata.holdr or config.holdr,
        reds=metadata.reds or config.reds,
    )
    out = Path(run_dir) / MODEL_DIR
    if (out / "model.json").exists():
        raise FileExistsError(f"{out} already holds a model; choose another --out")
    refuse_unfit_clips(config)
    train = load_split(config, "train", progress_bar)
    subtasks = calibrate(trained, train, config, progress_bar)
    calibrated = dataclasses.replace(
        model_metadata(config, int(metadata.training.get("iterations", 0)), subtasks, len(train)),
        training={**metadata.training, "recalibrated_from": str(source)},
    )
    save_model(out, trained.network, calibrated)
    return load_model(out)


def pretrain(
    config: PretrainConfig, run_dir: str | Path, resume: bool = False, progress_bar: bool = True
) -> RewardModel:
    refuse_unfit_clips(config)
    # a missing, unfinished or unlabelled dataset is refused before the run folder is written
    DemoDataset(config.dataset).require_subtask_ends()
    trainer = Pretrainer(config, run_dir, resume)
    train, valid = load_split(config, "train", progress_bar), load_split(config, "valid", progress_bar)
    if len(train) < 2:
        raise DatasetError(f"{config.dataset} has {len(train)} training demonstrations; pretraining needs at least 2")
    return trainer.train(train, valid, progress_bar)


# the command line's names of settings whose flag is not their dotted path's (add_setting_flags)
PRETRAIN_FLAG_PREFIXES = {
    "encoder": "",
    "shaping": "",
    "calibration": "",
    "calibration.stage_head": "stage-head-",
    "calibration.classifier": "classifier-",
}
PRETRAIN_FLAG_NAMES = {
    "encoder.kind": "encoder",
    "augment.enabled": "augment",
    "augment.max_shift": "augment-shift",
    "calibration.percentile": "threshold-percentile",
    "calibration.window_offsets": "stage-window-offsets",
    "calibration.stage_head.max_demos": "stage-head-demos",
}


def parse_args(argv: list[str] | None) -> tuple[PretrainConfig, argparse.Namespace]:
    parser = OneLineParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataset", help="demonstration dataset folder (inest-collect-demos)")
    parser.add_argument("--out", required=True, help="run folder")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    parser.add_argument(
        "--recalibrate",
        metavar="MODEL",
        help="no training: calibrate the trained encoder of the model folder MODEL anew with the calibration "
        "options given here, into --out/model",
    )
    settings = add_setting_flags(
        parser.add_argument_group("pretraining settings (PretrainConfig)"),
        PretrainConfig,
        prefixes=PRETRAIN_FLAG_PREFIXES,
        flags=PRETRAIN_FLAG_NAMES,
        skip=("dataset",),
    )
    args = parser.parse_args(argv)
    return build_settings(PretrainConfig, {"dataset": args.dataset, **settings.overrides(args)}), args


def main(argv: list[str] | None = None) -> int:
    try:
        config, args = parse_args(argv)
        if args.recalibrate:
            model = recalibrate(config, args.recalibrate, args.out)
        else:
            model = pretrain(config, args.out, resume=args.resume)
    except (DatasetError, FileExistsError, ValueError, ModelError) as error:  # ClipError is a ValueError
        print(f"inest-pretrain: {error}", file=sys.stderr)
        return 2
    schemes = ", ".join(f"{scheme} subtasks" for scheme in sorted(model.subtasks))
    print(f"wrote {Path(args.out) / MODEL_DIR} ({model.method}, {model.view}, goals for {schemes})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
