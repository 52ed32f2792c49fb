"""Do the pixels carry the stage the 32-d embedding loses? A small CNN trained on labelled frames.

The stage classifier on the frozen embedding calls 41-43 % of a trained policy's true stage-0
frames "red done" (classifier_probe.json). This probe trains the project's SmallCNN from scratch
as a 4-way stage classifier (true stage: ordered blocks in the goal strip now, 3 subtasks) on the
same frames the embedding classifier sees -- training demonstrations, random and wrong-order
play and a fit clip file of a policy's own rollouts -- and measures it on the held-out clip file
of the same policy: frame accuracy and, per true stage s, the share of frames called ">= s + 1".

  .venv/bin/python scripts/experiments/pixel_stage_probe.py DATASET FIT.npz|- HELD.npz OUT.json [SIZE]
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
import torch
from inest_reward_node.learning.clips import load_clips, random_play, wrong_order_play
from inest_reward_node.learning.data import load_demos
from inest_reward_node.learning.task_stages import demo_stages, true_stages
from inest_reward_node.runtime.encoders import EncoderConfig, build_encoder, frames_to_tensor, resize_frames

SCHEME, VIEW, CLIP_SIZE = 3, "ego", 96
DEMOS, ITERATIONS, BATCH = 200, 1500, 128


def main(dataset: str, fit_file: str, held_file: str, out: str, size: int = 48) -> None:
    torch.manual_seed(0)
    torch.set_num_threads(1)
    rng = np.random.default_rng(0)
    start = time.time()
    parts = [
        (demo.frames, demo_stages(demo.progress, demo.labels[SCHEME], SCHEME))
        for demo in load_demos(dataset, "train", VIEW, size, DEMOS, False)
    ]
    plays = random_play(VIEW, CLIP_SIZE, 50) + wrong_order_play(VIEW, CLIP_SIZE, 20)
    plays += load_clips(fit_file, VIEW, CLIP_SIZE) if fit_file != "-" else []  # -: demos and scripted play only
    parts += [(resize_frames(clip.frames, size), true_stages(clip.progress, clip.held, SCHEME)) for clip in plays]
    frames = np.concatenate([f for f, _ in parts])
    stages = np.concatenate([s for _, s in parts]).astype(np.int64)
    held = load_clips(held_file, VIEW, CLIP_SIZE)
    held_frames = np.concatenate([resize_frames(clip.frames, size) for clip in held])
    held_stages = np.concatenate([true_stages(clip.progress, clip.held, SCHEME) for clip in held]).astype(np.int64)
    by_stage = [np.flatnonzero(stages == s) for s in range(SCHEME + 1)]
    network = build_encoder(EncoderConfig(image_size=size, embedding_dim=SCHEME + 1, widths=(16, 32, 32, 32)))
    optimiser = torch.optim.Adam(network.parameters(), lr=1e-3)
    loss_fn = torch.nn.CrossEntropyLoss()
    network.train()
    for iteration in range(ITERATIONS):  # class-balanced batches: stage 3 frames are rare in play
        index = np.concatenate([rng.choice(members, BATCH // len(by_stage)) for members in by_stage])
        loss = loss_fn(network(frames_to_tensor(frames[index])), torch.as_tensor(stages[index]))
        optimiser.zero_grad()
        loss.backward()
        optimiser.step()
        if iteration % 250 == 0:
            print(f"iteration {iteration} loss {loss.item():.3f} ({time.time() - start:.0f} s)", flush=True)
    network.eval()
    with torch.inference_mode():
        batches = [held_frames[i : i + 512] for i in range(0, len(held_frames), 512)]
        logits = torch.cat([network(frames_to_tensor(batch)) for batch in batches])
    probabilities = torch.softmax(logits, 1).numpy()
    predicted = probabilities.argmax(1)
    at_least = np.cumsum(probabilities[:, ::-1], 1)[:, ::-1]  # P(stage >= s)
    report = {
        "fit_clips": fit_file,
        "fit_frames": len(stages),
        "fit_frames_by_stage": [len(members) for members in by_stage],
        "held_out_clips": held_file,
        "held_out_frames": len(held_stages),
        "image_size": size,
        "network": "SmallCNN widths (16, 32, 32, 32), 4-way softmax, trained from scratch",
        "iterations": ITERATIONS,
        "batch": BATCH,
        "held_out_frame_accuracy": float((predicted == held_stages).mean()),
        "held_out_false_positive_by_true_stage": [
            float((at_least[held_stages == s, s + 1] >= 0.5).mean()) for s in range(SCHEME)
        ],
        "held_out_miss_by_true_stage": [
            float((at_least[held_stages == s, s] < 0.5).mean()) for s in range(1, SCHEME + 1)
        ],
        "seconds": time.time() - start,
    }
    print(json.dumps(report, indent=2))
    with open(out, "w") as handle:
        json.dump(report, handle, indent=2)


if __name__ == "__main__":
    main(*sys.argv[1:5], *(int(arg) for arg in sys.argv[5:6]))
