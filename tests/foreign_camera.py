"""A camera that is not the simulator: a plain rclpy script publishing recorded frames (bgr8).

Publishes each frame of a .npy file (N, H, W, 3 RGB) on `camera/image_raw` and waits for the
reward carrying its stamp before the next, so every frame is scored. Optionally first sends
malformed images, and at the end calls `reset_reward` and sends the first frame once more.
`--scene FILE` publishes a second camera's frames, stamped alike, on `camera/allo/image_raw`
(the scene camera a stage head reads), `--withhold I` all but frame I's, which is then expected
to get no reward; `--scene-delay S` sends each scene frame S seconds after its frame;
`--jump-back I` sends, before frame I, one scene frame alone (its frame lost) and then starts
the clock over: frame I is stamped like frame 0. `--compressed jpeg|png` publishes
sensor_msgs/CompressedImage on `<topic>/compressed` instead, as image_transport's compressed
transport does (its malformed frames: an unknown format, a JPEG without a frame header, no
data). Writes what it received as JSON. Used by tests/test_graph.py and tests/test_scene_stage.py.
"""

from __future__ import annotations

import argparse
import json
import sys
import time

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from inest_interfaces.msg import Reward
from inest_reward_node.runtime.images import encode_compressed
from sensor_msgs.msg import CompressedImage, Image
from std_srvs.srv import Trigger

PERIOD_NS = 125_000_000


def raw_image(frame: np.ndarray, stamp_ns: int) -> Image:
    bgr = np.ascontiguousarray(frame[..., ::-1])
    msg = Image(height=frame.shape[0], width=frame.shape[1], encoding="bgr8", step=frame.shape[1] * 3)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    msg.header.frame_id = "foreign_camera"
    msg.data = bgr.tobytes()
    return msg


def compressed_image(frame: np.ndarray, stamp_ns: int, compression: str) -> CompressedImage:
    msg = CompressedImage(format=f"rgb8; {compression} compressed bgr8", data=encode_compressed(frame, compression))
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    msg.header.frame_id = "foreign_camera"
    return msg


def malformed_compressed(frame: np.ndarray, compression: str) -> list[CompressedImage]:
    unknown_format = compressed_image(frame, 1, compression)
    unknown_format.format = "tiff"
    no_frame_header = compressed_image(frame, 2, compression)
    no_frame_header.format, no_frame_header.data = "jpeg", b"\xff\xd8" + bytes(64)
    empty = compressed_image(frame, 3, compression)
    empty.data = b""
    return [unknown_format, no_frame_header, empty]


def malformed(frame: np.ndarray) -> list[Image]:
    wrong_encoding = raw_image(frame, 1)
    wrong_encoding.encoding = "mono16"
    short_step = raw_image(frame, 2)
    short_step.step = frame.shape[1] * 3 - 1
    empty = raw_image(frame, 3)
    empty.data = b""
    return [wrong_encoding, short_step, empty]


def spin_until(node, condition, timeout: float, what: str) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() > deadline:
            sys.exit(f"foreign_camera: timed out waiting for {what}")


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("frames")
    parser.add_argument("out")
    parser.add_argument("--malformed", action="store_true")
    parser.add_argument("--reset", action="store_true")
    parser.add_argument("--scene", help=".npy of the scene camera's frames, one per frame")
    parser.add_argument("--withhold", type=int, help="the index of a scene frame not to send")
    parser.add_argument("--scene-delay", type=float, default=0.0, help="seconds between a frame and its scene frame")
    parser.add_argument("--jump-back", type=int, help="the index of the first frame after the clock starts over")
    parser.add_argument("--compressed", choices=("jpeg", "png"), help="publish CompressedImage on <topic>/compressed")
    args = parser.parse_args()
    frames = np.load(args.frames)
    scene = None if args.scene is None else np.load(args.scene)
    rclpy.init()
    node = rclpy.create_node("foreign_camera")
    message, suffix = (CompressedImage, "/compressed") if args.compressed else (Image, "")
    publisher = node.create_publisher(message, "camera/image_raw" + suffix, 10)
    scene_publisher = node.create_publisher(message, "camera/allo/image_raw" + suffix, 10)

    def image(frame: np.ndarray, stamp_ns: int) -> Image | CompressedImage:
        return compressed_image(frame, stamp_ns, args.compressed) if args.compressed else raw_image(frame, stamp_ns)

    rewards: dict[int, Reward] = {}
    rejected, rejected_total, reasons = [0], [0], []
    unpaired_total, stage_unpaired_total = [0], [0]

    def on_diagnostics(msg: DiagnosticArray) -> None:
        for status in msg.status:
            values = {item.key: item.value for item in status.values}
            rejected[0] += int(values.get("rejected", 0))
            rejected_total[0] = max(rejected_total[0], int(values.get("total_rejected", 0)))
            unpaired_total[0] = max(unpaired_total[0], int(values.get("total_dropped_unpaired", 0)))
            stage_unpaired_total[0] = max(stage_unpaired_total[0], int(values.get("total_dropped_stage_unpaired", 0)))
            if values.get("last_rejection"):
                reasons.append(values["last_rejection"])

    node.create_subscription(
        Reward, "reward", lambda m: rewards.__setitem__(m.header.stamp.sec * 10**9 + m.header.stamp.nanosec, m), 10
    )
    node.create_subscription(DiagnosticArray, "/diagnostics", on_diagnostics, 10)
    reset = node.create_client(Trigger, "reset_reward")
    spin_until(node, lambda: publisher.get_subscription_count() > 0, 60, "the reward node's subscription")
    if scene is not None:
        spin_until(node, lambda: scene_publisher.get_subscription_count() > 0, 60, "the scene subscription")
    if args.malformed:
        for msg in malformed_compressed(frames[0], args.compressed) if args.compressed else malformed(frames[0]):
            publisher.publish(msg)
    received = []

    def send(frame: np.ndarray, stamp: int, scene_frame: np.ndarray | None = None) -> None:
        publisher.publish(image(frame, stamp))
        if scene_frame is not None:
            time.sleep(args.scene_delay)
            scene_publisher.publish(image(scene_frame, stamp))
        elif scene is not None:
            return  # withheld: no reward is expected, and the next frame must not wait for one
        spin_until(node, lambda: stamp in rewards, 30, f"the reward for stamp {stamp}")
        msg = rewards[stamp]
        received.append(
            {
                "stamp": stamp,
                "frame_id": msg.header.frame_id,
                "total": msg.total,
                "shaping": msg.shaping_reward,
                "bonus": msg.subtask_bonus,
                "intrinsic": msg.intrinsic_bonus,
                "subtask": msg.subtask,
                "num_subtasks": msg.num_subtasks,
                "confidence": msg.stage_confidence,
            }
        )

    first = 0  # the index stamped PERIOD_NS: the clock starts over at --jump-back
    for index, frame in enumerate(frames):
        if index == args.jump_back:
            scene_publisher.publish(image(scene[index], (index + 1) * PERIOD_NS))  # its frame is lost
            time.sleep(0.1)  # ... and it arrives before the clock goes back
            first = index
            rewards.clear()  # the stamps come again: only the new clock's rewards answer them
        stamp = (index - first + 1) * PERIOD_NS
        send(frame, stamp, None if scene is None or index == args.withhold else scene[index])
    after_reset = None
    if args.reset:
        spin_until(node, reset.service_is_ready, 30, "the reset_reward service")
        future = reset.call_async(Trigger.Request())
        spin_until(node, future.done, 30, "the reset_reward answer")
        send(frames[0], (len(frames) + 1) * PERIOD_NS, None if scene is None else scene[0])
        after_reset = received.pop()
    spin_until(node, lambda: rejected[0] >= 3 or not args.malformed, 10, "diagnostics counting the rejections")
    if args.withhold is not None:
        spin_until(node, lambda: unpaired_total[0] >= 1, 10, "diagnostics counting the unpaired frame")
    if args.jump_back is not None:
        spin_until(node, lambda: stage_unpaired_total[0] >= 1, 10, "diagnostics counting the lone scene frame")
    with open(args.out, "w") as handle:
        json.dump(
            {
                "rewards": received,
                "after_reset": after_reset,
                "rejected": rejected[0],
                "rejected_total": rejected_total[0],
                "unpaired_total": unpaired_total[0],
                "stage_unpaired_total": stage_unpaired_total[0],
                "stamps": sorted(rewards),
                "reasons": reasons,
            },
            handle,
        )
    node.destroy_node()
    rclpy.shutdown()


if __name__ == "__main__":
    main()
