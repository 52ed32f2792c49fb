"""Refit one subtask scheme's pixel stage head of a reward model with other head settings.

Fitting every scheme's head at calibration takes three times as long as the one a comparison
needs, so this fits only `--scheme`'s (the same frames as calibrate.stage_head_episodes: the first
`max_demos` training demonstrations and the calibration's random and wrong-order play, in the
head's camera) and writes a copy of MODEL with that head replaced, one per variant, to
OUT/<variant>/model; the other schemes keep theirs. Each variant is StageHeadConfig fields over
the source head's own:

  .venv/bin/python scripts/experiments/stage_head_variants.py MODEL DATASET OUT \\
      demos600=max_demos=600,iterations=3000 boundary=boundary_share=0.25 [--scheme 3]
"""

from __future__ import annotations

import argparse
import dataclasses
import json
from pathlib import Path

import torch
from inest_reward_node.learning.clips import random_play, wrong_order_play
from inest_reward_node.learning.config import CalibrationConfig
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.stage_fitting import fit_stage_head
from inest_reward_node.learning.task_stages import demo_stages, true_stages
from inest_reward_node.runtime.model import load_model, save_model


def parse_variant(text: str) -> tuple[str, dict[str, float]]:
    name, _, settings = text.partition("=")
    pairs = (item.split("=", 1) for item in settings.split(",") if item)
    return name, {key: json.loads(value) for key, value in pairs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("model")
    parser.add_argument("dataset")
    parser.add_argument("out")
    parser.add_argument("variants", nargs="+", type=parse_variant, metavar="NAME=KEY=VALUE[,KEY=VALUE]")
    parser.add_argument("--scheme", type=int, default=3)
    parser.add_argument("--threads", type=int, default=1)
    args = parser.parse_args()
    torch.set_num_threads(args.threads)
    source = load_model(args.model)
    base = source.metadata.subtasks[args.scheme].require_stage_head().config
    view = base.view or source.metadata.view
    calibration = CalibrationConfig()
    plays = random_play(view, source.image_size, calibration.random_episodes)
    plays += wrong_order_play(view, source.image_size, calibration.wrong_order_episodes)
    for name, settings in args.variants:
        config = dataclasses.replace(base, **settings)
        demos = load_demos(args.dataset, "train", view, source.image_size, config.max_demos, progress_bar=False)
        head = fit_stage_head(
            [demo.frames for demo in demos] + [clip.frames for clip in plays],
            [demo_stages(demo.progress, demo.labels[args.scheme], args.scheme) for demo in demos]
            + [true_stages(clip.progress, clip.held, args.scheme) for clip in plays],
            args.scheme + 1,
            config,
            progress_bar=True,
        )
        out = Path(args.out) / name
        out.mkdir(parents=True, exist_ok=True)
        model = load_model(args.model)  # a fresh copy: the variants do not share a head
        model.metadata.subtasks[args.scheme].stage_head = head
        save_model(out / "model", model.network, model.metadata)
        (out / "variant.json").write_text(
            json.dumps({"source": args.model, "scheme": args.scheme, "stage_head": config.to_dict()}, indent=2) + "\n"
        )
        print(f"{name}: {out / 'model'}", flush=True)


if __name__ == "__main__":
    main()
