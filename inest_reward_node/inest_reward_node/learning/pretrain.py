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
from inest_sim_node.dataset import DatasetError, DemoDataset

from ..runtime.encoders import ENCODER_KINDS, EncoderConfig
from ..runtime.model import (
    METHODS,
    TCC_SCHEMES,
    ModelError,
    ModelMetadata,
    RewardModel,
    SubtaskGoals,
    build_network,
    load_model,
    save_model,
)
from ..runtime.stage_window import DEFAULT_OFFSETS
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
    return ModelMetadata(
        method=config.method,
        view=config.view,
        encoder=config.encoder,
        shaping=config.shaping,
        subtasks=subtasks,
        holdr=config.holdr if config.method == "holdr" else None,
        reds=config.reds if config.method == "reds" else None,
        dataset={"path": str(config.dataset), "sha256": dataset_hash(config.dataset)},
        training={"iterations": iterations_done, "config": config.to_dict()},
        calibration=config.calibration.to_dict(),
        supervision=supervision(config, demonstrations) if demonstrations else {},
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
    for path in config.calibration.clips:
        load_clips(path, config.view, config.encoder.image_size)


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
    DemoDataset(config.dataset)  # a missing or unfinished dataset is refused before the run folder is written
    trainer = Pretrainer(config, run_dir, resume)
    train, valid = load_split(config, "train", progress_bar), load_split(config, "valid", progress_bar)
    if len(train) < 2:
        raise DatasetError(f"{config.dataset} has {len(train)} training demonstrations; pretraining needs at least 2")
    return trainer.train(train, valid, progress_bar)


INTEGER_OPTIONS = (
    "iterations",
    "videos_per_batch",
    "frames_per_video",
    "pairs_per_batch",
    "validate_every",
    "checkpoint_every",
    "train_limit",
    "valid_limit",
    "seed",
    "threads",
)

# --stage-head-OPTION: (StageHeadConfig field, type, help)
STAGE_HEAD_OPTIONS: dict[str, tuple[str, type, str]] = {
    "iterations": ("iterations", int, "training iterations of the pixel stage head (runtime/stage_head.py); 0: none"),
    "demos": (
        "max_demos",
        int,
        "training demonstrations the pixel stage head is fitted on, with the calibration's play",
    ),
    "boundary-share": (
        "boundary_share",
        float,
        "share of the pixel stage head's batches drawn from frames next to a stage change",
    ),
    "image-size": ("image_size", int, "pixels a side the pixel stage head sees its frames at"),
}


def parse_args(argv: list[str] | None) -> tuple[PretrainConfig, argparse.Namespace]:
    defaults = PretrainConfig(dataset="")
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("dataset", help="demonstration dataset folder (inest-collect-demos)")
    parser.add_argument("--out", required=True, help="run folder")
    parser.add_argument("--resume", action="store_true", help="continue the run in --out from its last checkpoint")
    parser.add_argument(
        "--recalibrate",
        metavar="MODEL",
        help="no training: calibrate the trained encoder of the model folder MODEL anew with the calibration "
        "options given here, into --out/model",
    )
    parser.add_argument("--method", choices=METHODS, default=defaults.method)
    parser.add_argument("--view", choices=("ego", "allo"), default=defaults.view)
    parser.add_argument("--encoder", choices=ENCODER_KINDS, default=defaults.encoder.kind)
    parser.add_argument("--image-size", type=int, default=defaults.encoder.image_size)
    parser.add_argument("--embedding-dim", type=int, default=defaults.encoder.embedding_dim)
    parser.add_argument(
        "--widths",
        type=lambda text: tuple(int(width) for width in text.split(",")),
        default=defaults.encoder.widths,
        help="small_cnn: channels of its convolutions, comma-separated (default %(default)s)",
    )
    for name in INTEGER_OPTIONS:
        parser.add_argument(f"--{name.replace('_', '-')}", type=int, default=getattr(defaults, name))
    parser.add_argument("--learning-rate", type=float, default=defaults.learning_rate)
    parser.add_argument("--hold-steps", type=int, default=defaults.shaping.hold_steps)
    parser.add_argument("--threshold-percentile", type=float, default=defaults.calibration.percentile)
    parser.add_argument("--random-episodes", type=int, default=defaults.calibration.random_episodes)
    parser.add_argument("--false-fire-rate", type=float, default=defaults.calibration.false_fire_rate)
    parser.add_argument("--demo-pass-rate", type=float, default=defaults.calibration.demo_pass_rate)
    parser.add_argument(
        "--wrong-order-episodes",
        type=int,
        default=defaults.calibration.wrong_order_episodes,
        help="wrong-order expert episodes for the stage classifier (default %(default)s)",
    )
    parser.add_argument(
        "--clips",
        nargs="+",
        default=list(defaults.calibration.clips),
        metavar="FILE",
        help="labelled clip files (inest-record-clips, inest-label-clips) the stage classifier is also fitted on",
    )
    parser.add_argument(
        "--stage-window-offsets",
        type=int,
        nargs="+",
        default=list(defaults.calibration.window_offsets),
        metavar="FRAMES",
        help="fit a window stage classifier on the frames this many steps back, 0 first "
        f"(e.g. {' '.join(map(str, DEFAULT_OFFSETS))}; reward.stage_evidence window reads it)",
    )
    parser.add_argument(
        "--demo-negatives",
        type=int,
        default=defaults.calibration.demo_negatives,
        help="rewound and as many reordered demonstrations the window classifier is also fitted on "
        "(no labels needed; default %(default)s)",
    )
    parser.add_argument(
        "--clips-raise-thresholds",
        action="store_true",
        help="the clip files' episodes also raise the completion thresholds, as random play does "
        "(a robot's labelled episodes standing in for the simulator's)",
    )
    head_defaults = defaults.calibration.stage_head
    for option, (setting, kind, text) in STAGE_HEAD_OPTIONS.items():
        parser.add_argument(
            f"--stage-head-{option}",
            type=kind,
            default=getattr(head_defaults, setting),
            help=f"{text} (default %(default)s)",
        )
    parser.add_argument(
        "--stage-head-subtasks",
        type=int,
        nargs="+",
        choices=TCC_SCHEMES,
        default=list(defaults.calibration.stage_head_subtasks),
        help="the subtask schemes that get a pixel stage head (default: all); the others read the embedding",
    )
    parser.add_argument(
        "--stage-head-view",
        choices=("ego", "allo"),
        default=defaults.calibration.stage_head.view,
        help="the camera the pixel stage head reads (default %(default)s: the scene camera, which always "
        "sees the goal strip and every block; ego for a dataset or robot with the wrist camera only)",
    )
    parser.add_argument(
        "--reds-subtasks",
        type=int,
        choices=(1, 3, 6),
        default=defaults.reds.subtasks,
        help="reds: the subtask segmentation it is trained on and conditions on (default %(default)s)",
    )
    parser.add_argument(
        "--reds-frames-per-batch",
        type=int,
        default=defaults.reds.frames_per_batch,
        help="reds: anchor frames per batch, each with its later frame and canonicalisation frames",
    )
    parser.add_argument(
        "--reds-canonical-samples",
        type=int,
        default=defaults.reds.canonical_samples,
        help="reds: EPIC canonicalisation frames per anchor (default %(default)s)",
    )
    parser.add_argument("--no-augment", action="store_true")
    parser.add_argument(
        "--augment-shift", type=int, default=defaults.augment.max_shift, help="largest random shift, pixels"
    )
    parser.add_argument(
        "--augment-brightness",
        type=float,
        default=defaults.augment.brightness,
        help="brightness factor drawn from [1 - b, 1 + b] (default %(default)s)",
    )
    parser.add_argument(
        "--augment-contrast", type=float, default=defaults.augment.contrast, help="contrast jitter, like brightness"
    )
    parser.add_argument("--device", default=defaults.device, help="torch device of the training: cpu (default) or cuda")
    args = parser.parse_args(argv)
    config = dataclasses.replace(
        defaults,
        dataset=args.dataset,
        method=args.method,
        view=args.view,
        encoder=EncoderConfig(
            kind=args.encoder, image_size=args.image_size, embedding_dim=args.embedding_dim, widths=args.widths
        ),
        learning_rate=args.learning_rate,
        reds=dataclasses.replace(
            defaults.reds,
            subtasks=args.reds_subtasks,
            frames_per_batch=args.reds_frames_per_batch,
            canonical_samples=args.reds_canonical_samples,
        ),
        augment=dataclasses.replace(
            defaults.augment,
            enabled=not args.no_augment,
            max_shift=args.augment_shift,
            brightness=args.augment_brightness,
            contrast=args.augment_contrast,
        ),
        device=args.device,
        shaping=dataclasses.replace(defaults.shaping, hold_steps=args.hold_steps),
        calibration=dataclasses.replace(
            defaults.calibration,
            percentile=args.threshold_percentile,
            random_episodes=args.random_episodes,
            false_fire_rate=args.false_fire_rate,
            demo_pass_rate=args.demo_pass_rate,
            wrong_order_episodes=args.wrong_order_episodes,
            clips=tuple(args.clips),
            clips_raise_thresholds=args.clips_raise_thresholds,
            window_offsets=tuple(args.stage_window_offsets),
            demo_negatives=args.demo_negatives,
            stage_head_subtasks=tuple(args.stage_head_subtasks),
            stage_head=dataclasses.replace(
                defaults.calibration.stage_head,
                view=args.stage_head_view,
                **{
                    setting: getattr(args, f"stage_head_{option.replace('-', '_')}")
                    for option, (setting, _, _) in STAGE_HEAD_OPTIONS.items()
                },
            ),
        ),
        **{name: getattr(args, name) for name in INTEGER_OPTIONS},
    )
    return config, args


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
