"""Reward node intake under a flood of malformed frames: valid frames must still be answered, fast.

Starts `inest-reward-node` as its own process on a private ROS domain (reward_node_harness.py)
and publishes, on one image topic, a valid camera at 30 Hz plus a 1 kHz burst of malformed
frames (a wrong encoding, a short step, a data length that does not match, no data, 1x1 and
oversized frames). When the model's stage head reads a scene camera (the default model's), each
valid frame's scene frame goes out beside it, stamped alike, at the same size. Phases: 96x96
rgb8 camera + burst, 640x480 bgr8 camera alone, 640x480 bgr8 camera + burst, with a scene camera
640x480 with 1 in 10 scene frames withheld, and, on a second node with
`image_transport:=compressed`, a 640x480 JPEG camera (quality 80, compressed_image_transport's
default) with its JPEG scene frames, each camera frame a simulator frame enlarged to 640x480
with sensor-like noise (random pixels would make a JPEG several times a camera's size). For
each: valid-frame latency percentiles (publish -> reward), valid frames answered, counted as
dropped or stale in /diagnostics, and uncounted; malformed frames rejected; the pairing's cost
(frames that waited for their scene frame, the p99 of that wait, unpaired frames). Target:
valid-frame p99 <= 15 ms, uncounted 0. Prints one JSON object; a phase with no answers, or with
uncounted frames, ends the run with one line and exit 1. `reward_node_flood.py [MODEL_FOLDER]
[--seconds S]` (default the committed default model, runtime.model.DEFAULT_MODEL); further
arguments go to the node (`-p threads:=2`).
"""

from __future__ import annotations

import argparse
import json
import time

import cv2
import numpy as np
import rclpy
from inest_reward_node.runtime.model import DEFAULT_MODEL
from reward_node_harness import RewardNodeUnderTest, image, simulator_frames

CAMERA_HZ, BURST_HZ = 30.0, 1000.0
BENCHMARK = "reward_node_flood"


def malformed() -> list:
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


def phase(
    under_test: RewardNodeUnderTest,
    name: str,
    frames: tuple[np.ndarray, np.ndarray],
    encoding: str,
    burst: bool,
    seconds: float,
    withhold_every: int = 0,
) -> dict:
    """Publish the camera (with its scene frames, every `withhold_every`-th withheld) and the
    burst for `seconds`; what became of every valid frame."""
    under_test.reset()
    frame, scene = frames
    bad = malformed() if burst else []
    sent: dict[int, float] = {}
    bad_sent = 0
    first_stamp = time.time_ns()
    start = time.perf_counter()
    next_camera = next_bad = start
    withheld = False
    # ends on a paired frame: a frame is known unpaired once a newer scene frame comes
    while (now := time.perf_counter()) - start < seconds or withheld:
        if now >= next_camera:
            stamp = first_stamp + len(sent) * 33_000_000
            withheld = withhold_every > 0 and len(sent) % withhold_every == withhold_every - 1
            camera, scene_msg = image(frame, encoding, stamp), None if withheld else image(scene, encoding, stamp)
            sent[stamp] = time.perf_counter()
            under_test.publish(camera, scene_msg)
            next_camera += 1 / CAMERA_HZ
        while bad and now >= next_bad:  # catch up after a slow step: the burst keeps its rate
            under_test.cameras[0].publish(bad[bad_sent % len(bad)])
            bad_sent += 1
            next_bad += 1 / BURST_HZ
        rclpy.spin_once(under_test.node, timeout_sec=max(0.0, min(next_camera, next_bad if bad else next_camera) - now))
    under_test.spin_for(2.5)  # the last frames' rewards and two diagnostics messages
    rejected = sum(int(d.get("rejected", 0)) - int(d.get("rejected_stale", 0)) for d in under_test.diagnostics)
    return {
        "camera": f"{frame.shape[1]}x{frame.shape[0]} {encoding} at {CAMERA_HZ:g} Hz"
        + (f" + {under_test.stage_camera} camera" if under_test.stage_camera else ""),
        "burst_hz": BURST_HZ if burst else 0,
        **under_test.figures(name, sent),
        "scene_frames_withheld": len(sent) // withhold_every if withhold_every else 0,
        "malformed_sent": bad_sent,
        "malformed_rejected": rejected,
    }


def camera_like(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A simulator frame and its scene frame enlarged to 640x480, with sensor-like noise (sigma 3)."""
    frames = []
    for frame in (view[0] for view in simulator_frames(1)):
        large = cv2.resize(frame, (640, 480), interpolation=cv2.INTER_LINEAR).astype(np.float32)
        frames.append(np.clip(large + rng.normal(0, 3, large.shape), 0, 255).astype(np.uint8))
    return frames[0], frames[1]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("model", nargs="?", default=DEFAULT_MODEL)
    parser.add_argument("--seconds", type=float, default=10.0, help="per phase")
    args, node_args = parser.parse_known_args()
    rng = np.random.default_rng(0)
    small = (rng.integers(0, 256, (96, 96, 3), dtype=np.uint8), rng.integers(0, 256, (96, 96, 3), dtype=np.uint8))
    large = tuple(rng.integers(0, 256, (480, 640, 3), dtype=np.uint8) for _ in range(2))
    under_test = RewardNodeUnderTest(BENCHMARK, args.model, node_args)
    try:
        under_test.wait_until_ready()
        phase(under_test, "warm-up", small, "rgb8", False, 2.0)
        phases = {
            "flood_96": phase(under_test, "flood_96", small, "rgb8", True, args.seconds),
            "camera_640x480": phase(under_test, "camera_640x480", large, "bgr8", False, args.seconds),
            "flood_640x480": phase(under_test, "flood_640x480", large, "bgr8", True, args.seconds),
        }
        if under_test.stage_camera:
            phases["camera_640x480_scene_gaps"] = phase(
                under_test, "camera_640x480_scene_gaps", large, "bgr8", False, args.seconds, withhold_every=10
            )
        lines = under_test.log_lines()
    finally:
        under_test.close()
    compressed = RewardNodeUnderTest(BENCHMARK, args.model, node_args, image_transport="compressed")
    try:
        compressed.wait_until_ready()
        phase(compressed, "warm-up", camera_like(rng), "jpeg", False, 2.0)
        phases["camera_640x480_jpeg"] = phase(
            compressed, "camera_640x480_jpeg", camera_like(rng), "jpeg", False, args.seconds
        )
    finally:
        compressed.close()
    print(
        json.dumps(
            {
                "benchmark": BENCHMARK,
                **phases,
                "node_log_lines_about_rejections": sum("rejected" in line for line in lines),
                "targets": {"latency_p99_ms": 15, "uncounted": 0},
                "model": args.model,
                "stage_camera": under_test.stage_camera,
                "seconds_per_phase": args.seconds,
            }
        )
    )


if __name__ == "__main__":
    main()
