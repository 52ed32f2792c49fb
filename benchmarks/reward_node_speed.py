"""Reward node speed over real topics: a 30 Hz camera stream and a flood, next to the bare encoder.

Starts `inest-reward-node` as its own process on a private ROS domain, publishes 96 px rgb8
frames from this process and times each frame from publishing to receiving its reward
(DDS both ways, decoding, encoder, tracker, novelty). Targets: >= 100 Hz sustained
and p99 <= 15 ms with the default encoder on 2 cores, the node's cost per frame within 1.3x of
the bare encoder forward. Prints one JSON object. `reward_node_speed.py [MODEL_FOLDER]`
(default: the committed default model, runtime.model.DEFAULT_MODEL); further arguments go to
the node (`-p threads:=2`).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rclpy
import torch
from diagnostic_msgs.msg import DiagnosticArray
from inest_bringup.launcher import graph_environment
from inest_interfaces.msg import Reward
from inest_reward_node.runtime.model import DEFAULT_MODEL, load_model
from sensor_msgs.msg import Image

from inest_sim_node import EnvConfig, SweepToTopEnv

SECONDS = 10.0
SIZE = 96


def simulator_frames(count: int) -> np.ndarray:
    env = SweepToTopEnv(config=EnvConfig())
    env.reset(seed=0)
    frames = []
    for _ in range(count):
        env.step(env.action_space.sample())
        frames.append(env.render_camera("ego", SIZE))
    return np.stack(frames)


def stream(
    node, publisher, frames: np.ndarray, rate_hz: float | None, received: dict[int, float], inside: list
) -> dict:
    """Publish for SECONDS, at rate_hz or as fast as possible; latency of every frame that got a reward."""
    sent: dict[int, float] = {}
    received.clear()
    inside.clear()
    start = time.perf_counter()
    first_stamp = time.time_ns()  # stamps keep increasing from one stream to the next
    while time.perf_counter() - start < SECONDS:
        stamp = first_stamp + len(sent) * 1_000_000
        msg = Image(height=SIZE, width=SIZE, encoding="rgb8", step=SIZE * 3)
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 10**9)
        msg.data = frames[len(sent) % len(frames)].tobytes()
        sent[stamp] = time.perf_counter()
        publisher.publish(msg)
        if rate_hz:
            next_time = start + len(sent) / rate_hz
            while (left := next_time - time.perf_counter()) > 0:
                rclpy.spin_once(node, timeout_sec=left)
        else:
            rclpy.spin_once(node, timeout_sec=0.0)
    drain = time.perf_counter() + 1.0
    while time.perf_counter() < drain:
        rclpy.spin_once(node, timeout_sec=0.05)
    latencies = np.array([(received[stamp] - sent[stamp]) * 1e3 for stamp in received if stamp in sent])
    return {
        "sent_per_s": round(len(sent) / SECONDS, 1),
        "rewards_per_s": round(len(latencies) / SECONDS, 1),
        "latency_p50_ms": round(float(np.percentile(latencies, 50)), 2),
        "latency_p99_ms": round(float(np.percentile(latencies, 99)), 2),
        # the node's own view (its diagnostics, once a second): arrival -> scored, frames per forward pass
        "in_node_latency_p50_ms": round(float(np.median([float(d["latency_p50_ms"]) for d in inside] or [np.nan])), 2),
        "in_node_latency_p99_ms": round(float(np.max([float(d["latency_p99_ms"]) for d in inside] or [np.nan])), 2),
        "mean_batch": round(float(np.mean([float(d["mean_batch"]) for d in inside] or [np.nan])), 2),
    }


def bare_forward_ms(model_folder: str, frames: np.ndarray, rate_hz: float | None) -> float:
    """The encoder alone at batch 1 in this process, median of 300 calls, back to back or paced
    like the 30 Hz stream (an idle CPU between frames makes every call slower: compare like with like)."""
    torch.set_num_threads(1)  # as the node runs it
    model = load_model(model_folder)
    times = []
    for index in range(300):
        start = time.perf_counter()
        model.embed(frames[index % len(frames)][None])
        times.append(time.perf_counter() - start)
        if rate_hz:
            time.sleep(1 / rate_hz)
    return float(np.median(times) * 1e3)


def main() -> None:
    model = sys.argv[1] if len(sys.argv) > 1 else DEFAULT_MODEL
    torch.set_num_threads(2)
    frames = simulator_frames(200)
    domain = 150 + os.getpid() % 50
    with tempfile.TemporaryDirectory() as logs:
        env = graph_environment(domain, logs)
        os.environ.update(env)  # this process's own participant joins the same private graph
        node_process = subprocess.Popen(
            [str(Path(sys.executable).parent / "inest-reward-node"), "--ros-args",
             "-p", f"model:={Path(model).resolve()}", "-p", "image_topic:=camera/image_raw", *sys.argv[2:]],
            env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
        )  # fmt: skip
        rclpy.init(domain_id=domain)
        node = rclpy.create_node("reward_speed")
        received: dict[int, float] = {}
        node.create_subscription(
            Reward, "reward", lambda m: received.__setitem__(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec,
                                                             time.perf_counter()), 1000,
        )  # fmt: skip
        publisher = node.create_publisher(Image, "camera/image_raw", 1000)
        inside: list[dict[str, str]] = []

        def on_diagnostics(msg: DiagnosticArray) -> None:
            for status in msg.status:
                values = {item.key: item.value for item in status.values}
                if values.get("scored", "0") != "0":
                    inside.append(values)

        node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
        try:
            deadline = time.monotonic() + 60
            while publisher.get_subscription_count() == 0 or node.count_publishers("reward") == 0:
                rclpy.spin_once(node, timeout_sec=0.1)
                if time.monotonic() > deadline:
                    sys.exit("reward_node_speed: the reward node did not come up (is MODEL_FOLDER right?)")
            stream(node, publisher, frames, 30.0, received, inside)  # warm-up
            at_30_hz = stream(node, publisher, frames, 30.0, received, inside)
            flood = stream(node, publisher, frames, None, received, inside)
        finally:
            node.destroy_node()
            rclpy.shutdown()
            node_process.terminate()
            node_process.wait()
    forward = bare_forward_ms(model, frames, None)
    forward_30_hz = bare_forward_ms(model, frames, 30.0)
    print(
        json.dumps(
            {
                "benchmark": "reward_node_speed",
                "stream_30hz": at_30_hz,
                "flood": flood,
                "bare_forward_ms": round(forward, 3),
                "bare_forward_at_30hz_ms": round(forward_30_hz, 3),
                "in_node_vs_bare_forward_30hz": round(at_30_hz["in_node_latency_p50_ms"] / forward_30_hz, 2),
                "targets": {"rewards_per_s": 100, "latency_p99_ms": 15, "in_node_vs_bare_forward_30hz": 1.3},
                "model": model,
                "frame": f"{SIZE}x{SIZE} rgb8",
            }
        )
    )


if __name__ == "__main__":
    main()
