"""Encoder speed on 2 threads: inference latency at batch 1 (p50/p99), throughput at batch 8 and 32,
and the time of one pretraining iteration (forward + backward + step on a full batch).

Prints one JSON object. Pass encoder kinds to limit the run: `encoder_speed.py small_cnn`.
The pretraining budget is 20 minutes on 2 cores for the default configuration.
"""

from __future__ import annotations

import json
import platform
import sys
import time

import numpy as np
import torch
from inest_reward_node.learning.config import PretrainConfig
from inest_reward_node.learning.losses import tcc_loss
from inest_reward_node.runtime.encoders import EncoderConfig, build_encoder, frames_to_tensor
from inest_reward_node.runtime.holdr import HoldR, HoldRConfig

IMAGE_SIZE = 96


def latency_ms(model: torch.nn.Module, frames: np.ndarray, repeats: int) -> np.ndarray:
    times = []
    with torch.inference_mode():
        for _ in range(repeats):
            start = time.perf_counter()
            model(frames_to_tensor(frames))
            times.append(time.perf_counter() - start)
    return np.array(times) * 1e3


def training_iteration_s(kind: str, iterations: int = 5) -> float:
    defaults = PretrainConfig(dataset="")
    frames = defaults.videos_per_batch * defaults.frames_per_video
    if kind == "holdr":
        model: torch.nn.Module = HoldR(HoldRConfig(), IMAGE_SIZE)
        frames = 2 * defaults.pairs_per_batch
    else:
        model = build_encoder(EncoderConfig(kind=kind, image_size=IMAGE_SIZE))
    optimizer = torch.optim.AdamW(model.parameters(), lr=1e-4)
    batch = frames_to_tensor(np.random.default_rng(0).integers(0, 256, (frames, IMAGE_SIZE, IMAGE_SIZE, 3), np.uint8))
    positions = torch.linspace(0, 1, defaults.frames_per_video).repeat(defaults.videos_per_batch, 1)
    times = []
    for _ in range(iterations + 1):
        start = time.perf_counter()
        embeddings = model(batch)
        if kind == "holdr":
            pairs = embeddings.view(-1, 2, embeddings.shape[-1])
            loss = model.gap(pairs[:, 0], pairs[:, 1]).square().mean()
        else:
            loss = tcc_loss(embeddings.view(defaults.videos_per_batch, defaults.frames_per_video, -1), positions)
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        times.append(time.perf_counter() - start)
    return float(np.median(times[1:]))


def encoder_figures(kind: str) -> dict[str, float]:
    model = build_encoder(EncoderConfig(kind=kind, image_size=IMAGE_SIZE)).eval()
    rng = np.random.default_rng(0)
    single = rng.integers(0, 256, (1, IMAGE_SIZE, IMAGE_SIZE, 3), np.uint8)
    latency_ms(model, single, 10)  # warm-up
    batch1 = latency_ms(model, single, 300)
    figures = {
        "batch1_p50_ms": round(float(np.percentile(batch1, 50)), 2),
        "batch1_p99_ms": round(float(np.percentile(batch1, 99)), 2),
    }
    for size in (8, 32):
        frames = rng.integers(0, 256, (size, IMAGE_SIZE, IMAGE_SIZE, 3), np.uint8)
        times = latency_ms(model, frames, 30)
        figures[f"batch{size}_frames_per_s"] = round(size / float(np.median(times) / 1e3))
    iteration = training_iteration_s(kind)
    defaults = PretrainConfig(dataset="")
    figures["pretrain_iteration_s"] = round(iteration, 3)
    figures["pretrain_default_iterations_min"] = round(iteration * defaults.iterations / 60, 1)
    return figures


def main() -> None:
    torch.set_num_threads(2)
    kinds = sys.argv[1:] or ["small_cnn", "resnet18"]
    result = {"benchmark": "encoder_speed", "image_size": IMAGE_SIZE, "threads": 2}
    for kind in kinds:
        result[kind] = encoder_figures(kind)
    result["holdr_pretrain_iteration_s"] = round(training_iteration_s("holdr"), 3)
    result["python"] = platform.python_version()
    result["torch"] = torch.__version__
    print(json.dumps(result))


if __name__ == "__main__":
    main()
