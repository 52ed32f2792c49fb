"""Reward node speed over real topics: a 30 Hz camera stream and a flood, next to the bare networks.

Starts `inest-reward-node` as its own process on a private ROS domain (reward_node_harness.py),
publishes 96 px rgb8 simulator frames from this process, with each frame's scene-camera frame
stamped alike when the model's stage head reads one (the default model's), and times each frame
from publishing to receiving its reward (DDS both ways, decoding, pairing, encoder, stage head,
tracker, novelty). Targets: >= 100 Hz sustained and p99 <= 15 ms with the default model on 2
cores, the node's cost per frame within 1.3x of the bare networks' forward (the encoder, and the
stage head on the scene frame). Prints one JSON object; a stream that gets no answers, or (paced)
loses frames nobody counted, ends the run with one line and exit 1.
`reward_node_speed.py [MODEL_FOLDER]` (default: the committed default model,
runtime.model.DEFAULT_MODEL); further arguments go to the node (`-p threads:=2`).
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np
import rclpy
import torch
from inest_reward_node.runtime.model import DEFAULT_MODEL, load_model
from inest_reward_node.runtime.rewards import RewardScorer
from reward_node_harness import SIMULATOR_SIZE, RewardNodeUnderTest, image, simulator_frames

SECONDS = 10.0
BENCHMARK = "reward_node_speed"


def stream(under_test: RewardNodeUnderTest, frames: tuple[np.ndarray, np.ndarray], rate_hz: float | None) -> dict:
    """Publish for SECONDS, at rate_hz or as fast as possible; latency of every frame that got a reward."""
    ego, scene = frames
    under_test.reset()
    sent: dict[int, float] = {}
    start = time.perf_counter()
    first_stamp = time.time_ns()  # stamps keep increasing from one stream to the next
    while time.perf_counter() - start < SECONDS:
        stamp, index = first_stamp + len(sent) * 1_000_000, len(sent) % len(ego)
        camera, scene_msg = image(ego[index], "rgb8", stamp), image(scene[index], "rgb8", stamp)
        sent[stamp] = time.perf_counter()
        under_test.publish(camera, scene_msg)
        if rate_hz:
            next_time = start + len(sent) / rate_hz
            while (left := next_time - time.perf_counter()) > 0:
                rclpy.spin_once(under_test.node, timeout_sec=left)
        else:
            rclpy.spin_once(under_test.node, timeout_sec=0.0)
    under_test.spin_for(1.5)
    name = f"stream_{rate_hz:g}hz" if rate_hz else "flood"
    figures = under_test.figures(name, sent, every_frame=rate_hz is not None)
    inside = [d for d in under_test.diagnostics if d.get("scored", "0") != "0"]
    return {
        "sent_per_s": round(len(sent) / SECONDS, 1),
        "rewards_per_s": round(figures["answered"] / SECONDS, 1),
        **figures,
        # the node's own view (its diagnostics): arrival -> scored, frames per forward pass
        "in_node_latency_p50_ms": round(float(np.median([float(d["latency_p50_ms"]) for d in inside])), 2),
        "in_node_latency_p99_ms": round(float(np.max([float(d["latency_p99_ms"]) for d in inside])), 2),
        "mean_batch": round(float(np.mean([float(d["mean_batch"]) for d in inside])), 2),
    }


def bare_forward_ms(model_folder: str, frames: tuple[np.ndarray, np.ndarray], rate_hz: float | None) -> float:
    """The encoder (and the stage head on the scene frame, if the model reads one) alone at batch 1
    in this process, median of 300 calls, back to back or paced like the 30 Hz stream (an idle CPU
    between frames makes every call slower: compare like with like)."""
    torch.set_num_threads(1)  # as the node runs it
    model = load_model(model_folder)
    scorer = RewardScorer(model, 3)
    ego, scene = frames
    times = []
    for index in range(300):
        start = time.perf_counter()
        model.embed(ego[index % len(ego)][None])
        if scorer.stage_camera:
            scorer.stage_evidence(scene[index % len(scene)][None])
        times.append(time.perf_counter() - start)
        if rate_hz:
            time.sleep(1 / rate_hz)
    return float(np.median(times) * 1e3)


def main() -> None:
    model = sys.argv[1] if len(sys.argv) > 1 else DEFAULT_MODEL
    torch.set_num_threads(2)
    frames = simulator_frames(200)
    under_test = RewardNodeUnderTest(BENCHMARK, model, sys.argv[2:], diagnostics_period=1.0)
    try:
        under_test.wait_until_ready()
        stream(under_test, frames, 30.0)  # warm-up
        at_30_hz = stream(under_test, frames, 30.0)
        flood = stream(under_test, frames, None)
    finally:
        under_test.close()
    forward = bare_forward_ms(model, frames, None)
    forward_30_hz = bare_forward_ms(model, frames, 30.0)
    print(
        json.dumps(
            {
                "benchmark": BENCHMARK,
                "stream_30hz": at_30_hz,
                "flood": flood,
                "bare_forward_ms": round(forward, 3),
                "bare_forward_at_30hz_ms": round(forward_30_hz, 3),
                "in_node_vs_bare_forward_30hz": round(at_30_hz["in_node_latency_p50_ms"] / forward_30_hz, 2),
                "targets": {"rewards_per_s": 100, "latency_p99_ms": 15, "in_node_vs_bare_forward_30hz": 1.3},
                "model": model,
                "stage_camera": under_test.stage_camera,
                "frame": f"{SIMULATOR_SIZE}x{SIMULATOR_SIZE} rgb8"
                + (f" + {under_test.stage_camera} camera" if under_test.stage_camera else ""),
            }
        )
    )


if __name__ == "__main__":
    main()
