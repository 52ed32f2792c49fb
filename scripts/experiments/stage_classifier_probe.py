"""Can the stage classifier on the frozen 32-d embedding tell a trained policy's frames apart?

Fits the classifier (inest_reward_node.learning.stage_fitting.fit_stage_classifier) on the training
demonstrations, the calibration's random and wrong-order play and, optionally, a fit clip file
of a policy's own rollouts (inest-record-clips), and measures on a held-out clip file of the
same policy: frame accuracy and, per true stage s, the share of frames the classifier calls "stage >= s + 1" (its false
positives, what lets the confirmed tracker pay for a block that is not placed).

  .venv/bin/python scripts/experiments/stage_classifier_probe.py MODEL DATASET FIT.npz HELD.npz OUT.json
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
from inest_reward_node.learning.clips import load_clips, random_play, wrong_order_play
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.stage_fitting import StageClassifierConfig, fit_stage_classifier
from inest_reward_node.learning.task_stages import demo_stages, true_stages
from inest_reward_node.runtime.model import load_model

SCHEME = 3
SETTINGS = {
    "default, without policy clips": (StageClassifierConfig(), False),
    "default, with policy clips": (StageClassifierConfig(), True),
}


def main(model_dir: str, dataset: str, fit_file: str, held_file: str, out: str) -> None:
    model = load_model(model_dir)
    view, size = model.view, model.image_size

    def embedded(clips):
        return [(model.embed(clip.frames), true_stages(clip.progress, clip.held, SCHEME)) for clip in clips]

    demos = [
        (model.embed(demo.frames), demo_stages(demo.progress, demo.labels[SCHEME], SCHEME))
        for demo in load_demos(dataset, "train", view, size, None, False)
    ]
    others = embedded(random_play(view, size, 50)) + embedded(wrong_order_play(view, size, 20))
    fit, held = embedded(load_clips(fit_file, view, size)), embedded(load_clips(held_file, view, size))
    x_held = np.concatenate([e for e, _ in held])
    y_held = np.concatenate([s for _, s in held])
    results = {}
    for name, (config, with_clips) in SETTINGS.items():
        negatives = others + (fit if with_clips else [])
        start = time.time()
        classifier = fit_stage_classifier(
            [e for e, _ in demos],
            [s for _, s in demos],
            SCHEME + 1,
            [e for e, _ in negatives],
            [s for _, s in negatives],
            config,
        )
        at_least = classifier.at_least(x_held)
        results[name] = {
            "classifier": config.to_dict(),
            "policy_clips_in_fit": with_clips,
            "held_out_frame_accuracy": float((classifier.predict(x_held) == y_held).mean()),
            "held_out_false_positive_by_true_stage": [
                float((at_least[y_held == s, s + 1] >= 0.5).mean()) for s in range(SCHEME)
            ],
            "fit_seconds": time.time() - start,
        }
        print(name, results[name], flush=True)
        report = {"model": model_dir, "fit_clips": fit_file, "held_out_clips": held_file, "results": results}
        with open(out, "w") as handle:  # after every setting: a killed probe keeps what it measured
            json.dump({**report, "held_out_frames": len(y_held)}, handle, indent=2)


if __name__ == "__main__":
    main(*sys.argv[1:6])
