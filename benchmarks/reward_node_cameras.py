"""How many cameras one reward node serves: N streams at 30 Hz, each with its scene camera.

For N = 1, 2, 4, 8 in turn, starts a fresh `inest-reward-node` in its own process on a private
ROS domain (reward_node_harness.py) serving N streams (`cam0` ... `cam<N-1>`, the node's
`streams`), and publishes from this process, per stream, 96 px rgb8 simulator frames at 30 Hz
with each frame's scene-camera frame stamped alike when the model's stage head reads one (the
default model's). The streams run free of each other, like the cameras of several arms: their
frames are spread evenly over the period, so the node never sees a whole round at once and
batches what has arrived from any stream by the time it gets to it. After a 2 s warm-up, per N:
publish -> reward latency p50/p99 over all frames and per stream, frames answered, dropped as
the node counted them (`/diagnostics` `stream<i>_unanswered`), and uncounted (sent - answered -
counted); the node's frames per forward pass (`mean_batch`), its CPU use (100 = one core) and
this publishing process's. Target: 8 streams with p99 <= 20 ms and no uncounted frame, the
default model on 2 cores; `cameras_served` is the largest N whose every frame was answered
within that p99 (no drop, counted or not). Prints one JSON object; a stream with no answer at
all ends the run with one line and exit 1.
`reward_node_cameras.py [MODEL_FOLDER] [--streams 1 2 4 8] [--seconds S]` (default model: the
committed default, runtime.model.DEFAULT_MODEL); further arguments go to the node (`-p max_batch:=16`).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np
import rclpy
from inest_reward_node.node import RewardNodeConfig
from inest_reward_node.runtime.model import DEFAULT_MODEL
from reward_node_harness import SIMULATOR_SIZE, RewardNodeUnderTest, image, percentiles, simulator_frames

BENCHMARK = "reward_node_cameras"
RATE_HZ = 30.0
WARM_UP_S = 2.0
TARGETS = {"streams": 8, "latency_p99_ms": 20.0, "uncounted": 0}
NODE_SETTINGS = ("max_batch", "max_pending", "round_wait_ms", "threads")  # the node's, that bear on the load


def cpu_seconds(pid: int) -> float:
    """User and system CPU time of process `pid` so far (/proc/<pid>/stat)."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def cpu_model() -> str:
    for line in Path("/proc/cpuinfo").read_text().splitlines():
        if line.startswith("model name"):
            return line.split(":", 1)[1].strip()
    return "unknown"


def publish_streams(
    under_test: RewardNodeUnderTest, frames: tuple[np.ndarray, np.ndarray], seconds: float
) -> list[dict[int, float]]:
    """Every stream at RATE_HZ for `seconds`, stream i a fraction i / N of a period after stream 0;
    returns per stream stamp -> time.perf_counter() sent."""
    ego, scene = frames
    count = len(under_test.streams)
    period_ns = round(1e9 / RATE_HZ)
    sent: list[dict[int, float]] = [{} for _ in range(count)]
    first_stamp, start = time.time_ns(), time.perf_counter()
    ticks = round(seconds * RATE_HZ * count)  # every stream's k-th frame is tick k * count + stream
    for tick in range(ticks):
        due = start + tick / (RATE_HZ * count)
        while (left := due - time.perf_counter()) > 0:
            rclpy.spin_once(under_test.node, timeout_sec=left)
        frame, stream = divmod(tick, count)
        stamp = first_stamp + frame * period_ns + stream * period_ns // count
        index = (frame + stream * 17) % len(ego)  # each stream its own moment of play
        sent[stream][stamp] = time.perf_counter()
        under_test.publish(image(ego[index], "rgb8", stamp), image(scene[index], "rgb8", stamp), stream)
    return sent


def serve(model: str, count: int, frames: tuple[np.ndarray, np.ndarray], seconds: float, node_args: list[str]) -> dict:
    """One node serving `count` streams: warm-up, then the measured `seconds`."""
    streams = tuple(f"cam{index}" for index in range(count))
    under_test = RewardNodeUnderTest(BENCHMARK, model, node_args, diagnostics_period=1.0, streams=streams)
    try:
        under_test.wait_until_ready()
        publish_streams(under_test, frames, WARM_UP_S)
        under_test.spin_for(1.5)  # the warm-up's rewards, and diagnostics that count them, come before the reset
        under_test.reset()
        node_cpu, own_cpu, wall = cpu_seconds(under_test.process.pid), time.process_time(), time.perf_counter()
        sent = publish_streams(under_test, frames, seconds)
        wall = time.perf_counter() - wall
        node_cpu, own_cpu = cpu_seconds(under_test.process.pid) - node_cpu, time.process_time() - own_cpu
        under_test.spin_for(2.5)  # the last frames' rewards and the diagnostics that count them
        per_stream = [
            {"stream": name, **under_test.stream_figures(f"{count} streams: {name}", sent[index], False, index)}
            for index, name in enumerate(streams)
        ]
        latencies = np.concatenate([under_test.latencies_ms(sent[index], index) for index in range(count)])
        inside = [d for d in under_test.diagnostics if d.get("scored", "0") != "0"]
        scored = sum(int(d["scored"]) for d in inside)
        batches = sum(int(d["scored"]) / float(d["mean_batch"]) for d in inside)
        pairing = under_test.pairing()
        stage_camera = under_test.stage_camera
    finally:
        under_test.close()
    totals = {key: sum(entry[key] for entry in per_stream) for key in ("valid_sent", "answered", "counted_drops")}
    uncounted = sum(entry["uncounted"] for entry in per_stream)
    figures = percentiles(latencies)
    return {
        **totals,
        "uncounted": uncounted,
        "rewards_per_s": round(totals["answered"] / seconds, 1),
        **figures,
        "met_target": figures["latency_p99_ms"] <= TARGETS["latency_p99_ms"] and uncounted <= TARGETS["uncounted"],
        "served": figures["latency_p99_ms"] <= TARGETS["latency_p99_ms"] and totals["answered"] == totals["valid_sent"],
        # the node's own view: frames per forward pass (several streams' frames share one), arrival -> scored
        "mean_batch": round(scored / batches, 2) if batches else 0.0,
        "in_node_latency_p99_ms": round(max((float(d["latency_p99_ms"]) for d in inside), default=0.0), 2),
        "node_cpu_percent": round(100 * node_cpu / wall, 1),
        "node_cpu_ms_per_frame": round(1e3 * node_cpu / max(totals["valid_sent"], 1), 2),  # its scene frame included
        "publisher_cpu_percent": round(100 * own_cpu / wall, 1),
        "load_1min_after": round(os.getloadavg()[0], 2),  # the machine's other work shows here
        **pairing,
        "per_stream": per_stream,
        "stage_camera": stage_camera,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", nargs="?", default=DEFAULT_MODEL)
    parser.add_argument("--streams", type=int, nargs="+", default=[1, 2, 4, 8], help="stream counts, in turn")
    parser.add_argument("--seconds", type=float, default=20.0, help="measured, per stream count")
    args, node_args = parser.parse_known_args()
    frames = simulator_frames(200)
    results = {str(count): serve(args.model, count, frames, args.seconds, node_args) for count in args.streams}
    stage_camera = next(iter(results.values()))["stage_camera"]
    for result in results.values():
        del result["stage_camera"]
    served = [int(count) for count, result in results.items() if result["served"]]
    defaults = RewardNodeConfig()
    print(
        json.dumps(
            {
                "benchmark": BENCHMARK,
                "streams": results,
                "cameras_served": max(served, default=0),
                "targets": TARGETS,
                "model": args.model,
                "stage_camera": stage_camera,
                "frame": f"{SIMULATOR_SIZE}x{SIMULATOR_SIZE} rgb8 at {RATE_HZ:g} Hz per stream"
                + (f" + {stage_camera} camera" if stage_camera else "")
                + ", streams spread evenly over the period",
                "seconds_per_count": args.seconds,
                "warm_up_s": WARM_UP_S,
                "node": {
                    "args": node_args,  # these override the defaults below
                    "defaults": {key: getattr(defaults, key) for key in NODE_SETTINGS},
                },
                "cpu": {"model": cpu_model(), "count": os.cpu_count()},
            }
        )
    )


if __name__ == "__main__":
    main()
