"""Reward node intake under a flood of malformed frames: valid frames must still be answered, fast.

Starts `inest-reward-node` as its own process on a private ROS domain and publishes, on one
image topic, a valid camera at 30 Hz plus a 1 kHz burst of malformed frames (a wrong encoding,
a short step, a data length that does not match, no data, 1x1 and oversized frames). Phases:
96x96 rgb8 camera + burst, 640x480 bgr8 camera alone, 640x480 bgr8 camera + burst. For each:
valid-frame latency percentiles (publish -> reward), valid frames answered, uncounted (neither
answered nor counted as dropped or stale in /diagnostics), malformed frames rejected, and the
node's log lines about rejections. Target: valid-frame p99 <= 15 ms, uncounted 0. Prints one
JSON object. `reward_node_flood.py [MODEL_FOLDER] [--seconds S]` (default
the committed default model, runtime.model.DEFAULT_MODEL); further arguments go to the node (`-p threads:=2`).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from inest_bringup.launcher import graph_environment
from inest_interfaces.msg import Reward
from inest_reward_node.runtime.images import encode_rgb
from inest_reward_node.runtime.model import DEFAULT_MODEL
from sensor_msgs.msg import Image

CAMERA_HZ, BURST_HZ = 30.0, 1000.0


def image(frame: np.ndarray, encoding: str, stamp: int) -> Image:
    data, step = encode_rgb(frame, encoding)
    msg = Image(height=frame.shape[0], width=frame.shape[1], encoding=encoding, step=step)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 10**9)
    msg.data = data
    return msg


def malformed() -> list[Image]:
    """One of each kind the node must refuse; the stamps are far in the future, so a frame that
    slipped through would also make every valid frame after it look stale."""
    future = 4_000_000_000 * 10**9
    frame = np.zeros((96, 96, 3), np.uint8)
    wrong_encoding, short_step, short_data, no_data, tiny, huge = (image(frame, "rgb8", future) for _ in range(6))
    wrong_encoding.encoding = "mono16"
    short_step.step -= 1
    short_data.data = bytes(len(frame.tobytes()) - 5)
    no_data.data = b""
    tiny.height = tiny.width = 1
    tiny.step, tiny.data = 3, bytes(3)
    huge.height = huge.width = 100_000  # claims 30 GB, carries 27 kB
    return [wrong_encoding, short_step, short_data, no_data, tiny, huge]


def phase(node, publisher, frame: np.ndarray, encoding: str, burst: bool, seconds: float, seen) -> dict:
    """Publish the camera (and the burst) for `seconds`; what became of every valid frame."""
    received, diagnostics = seen
    received.clear()
    diagnostics.clear()
    bad = malformed() if burst else []
    sent: dict[int, float] = {}
    bad_sent = 0
    first_stamp = time.time_ns()
    start = time.perf_counter()
    next_camera = next_bad = start
    while (now := time.perf_counter()) - start < seconds:
        if now >= next_camera:
            stamp = first_stamp + len(sent) * 33_000_000
            msg = image(frame, encoding, stamp)
            sent[stamp] = time.perf_counter()
            publisher.publish(msg)
            next_camera += 1 / CAMERA_HZ
        while bad and now >= next_bad:  # catch up after a slow step: the burst keeps its rate
            publisher.publish(bad[bad_sent % len(bad)])
            bad_sent += 1
            next_bad += 1 / BURST_HZ
        rclpy.spin_once(node, timeout_sec=max(0.0, min(next_camera, next_bad if bad else next_camera) - now))
    drain = time.perf_counter() + 2.5  # the last frames' rewards and two diagnostics messages
    while time.perf_counter() < drain:
        rclpy.spin_once(node, timeout_sec=0.05)
    answered = [stamp for stamp in sent if stamp in received]
    latencies = np.array([(received[stamp] - sent[stamp]) * 1e3 for stamp in answered] or [np.nan])
    counted = sum(int(d.get("dropped", 0)) + int(d.get("rejected_stale", 0)) for d in diagnostics)
    rejected = sum(int(d.get("rejected", 0)) - int(d.get("rejected_stale", 0)) for d in diagnostics)
    return {
        "camera": f"{frame.shape[1]}x{frame.shape[0]} {encoding} at {CAMERA_HZ:g} Hz",
        "burst_hz": BURST_HZ if burst else 0,
        "valid_sent": len(sent),
        "answered": len(answered),
        "counted_drops": counted,
        "uncounted": len(sent) - len(answered) - counted,
        "latency_p50_ms": round(float(np.percentile(latencies, 50)), 2),
        "latency_p99_ms": round(float(np.percentile(latencies, 99)), 2),
        "latency_max_ms": round(float(np.max(latencies)), 2),
        "malformed_sent": bad_sent,
        "malformed_rejected": rejected,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", nargs="?", default=DEFAULT_MODEL)
    parser.add_argument("--seconds", type=float, default=10.0, help="per phase")
    args, node_args = parser.parse_known_args()
    rng = np.random.default_rng(0)
    small = rng.integers(0, 256, (96, 96, 3), dtype=np.uint8)
    large = rng.integers(0, 256, (480, 640, 3), dtype=np.uint8)
    domain = 150 + os.getpid() % 50
    with tempfile.TemporaryDirectory() as logs:
        env = graph_environment(domain, logs)
        os.environ.update(env)  # this process's own participant joins the same private graph
        node_log = Path(logs) / "reward_node.log"
        with open(node_log, "w") as log:
            node_process = subprocess.Popen(
                [str(Path(sys.executable).parent / "inest-reward-node"), "--ros-args",
                 "-p", f"model:={Path(args.model).resolve()}", "-p", "image_topic:=camera/image_raw",
                 "-p", "diagnostics_period:=0.5", *node_args],
                env=env, stdout=log, stderr=subprocess.STDOUT,
            )  # fmt: skip
        rclpy.init(domain_id=domain)
        node = rclpy.create_node("reward_flood")
        received: dict[int, float] = {}
        diagnostics: list[dict[str, str]] = []
        node.create_subscription(
            Reward, "reward", lambda m: received.__setitem__(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec,
                                                             time.perf_counter()), 1000,
        )  # fmt: skip
        node.create_subscription(
            DiagnosticArray, "/diagnostics",
            lambda msg: diagnostics.extend({kv.key: kv.value for kv in s.values} for s in msg.status), 100,
        )  # fmt: skip
        publisher = node.create_publisher(Image, "camera/image_raw", 1000)
        seen = (received, diagnostics)
        try:
            deadline = time.monotonic() + 60
            while publisher.get_subscription_count() == 0 or node.count_publishers("reward") == 0:
                rclpy.spin_once(node, timeout_sec=0.1)
                if time.monotonic() > deadline or node_process.poll() is not None:
                    sys.exit("reward_node_flood: the reward node did not come up:\n" + node_log.read_text())
            phase(node, publisher, small, "rgb8", False, 2.0, seen)  # warm-up
            phases = {
                "flood_96": phase(node, publisher, small, "rgb8", True, args.seconds, seen),
                "camera_640x480": phase(node, publisher, large, "bgr8", False, args.seconds, seen),
                "flood_640x480": phase(node, publisher, large, "bgr8", True, args.seconds, seen),
            }
        finally:
            node.destroy_node()
            rclpy.shutdown()
            node_process.terminate()
            node_process.wait()
        lines = node_log.read_text().splitlines()
    print(
        json.dumps(
            {
                "benchmark": "reward_node_flood",
                **phases,
                "node_log_lines_about_rejections": sum("rejected" in line for line in lines),
                "targets": {"latency_p99_ms": 15, "uncounted": 0},
                "model": args.model,
                "seconds_per_phase": args.seconds,
            }
        )
    )


if __name__ == "__main__":
    main()
