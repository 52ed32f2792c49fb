"""A stand-in for the reward node and simulators: publishes known messages on the topics
`inest-record` records, once its subscriptions are matched, and waits until they are acknowledged.

`expected_messages` is what it publishes, so tests/test_recording.py can compare the recording
with it. Exits non-zero (with the reason) if the recorder never subscribes or never acknowledges.
"""

from __future__ import annotations

import argparse
import sys
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from inest_interfaces.msg import EpisodeStatus, Reward
from rclpy.duration import Duration
from sensor_msgs.msg import Image
from std_msgs.msg import Float32, Int32

STEPS = 6
PERIOD_NS = 125_000_000


def expected_messages(namespaces: list[str], images: bool) -> dict[str, list]:
    """Topic -> the messages published on it, in order: rewards 0.25 apart, subtasks 0, 1, 2, 3, 0, ..."""
    topics: dict[str, list] = {"/diagnostics": []}
    for stream, namespace in enumerate(namespaces):
        for name in (
            "reward",
            "reward/total",
            "reward/subtask",
            "episode_status",
            *(("camera/ego/image_raw",) * images),
        ):
            topics[f"/{namespace}/{name}"] = []
        for step in range(STEPS):
            stamp_ns = (step + 1) * PERIOD_NS
            total, subtask = 0.25 * step - stream, step % 4
            reward = Reward(total=total, shaping_reward=-0.5, subtask=subtask, num_subtasks=3)
            reward.subtask_completed = step % 4 == 1
            status = EpisodeStatus(episode=stream, step=step, seed=7 + stream, score=0.5 * step, truncated=step == 5)
            for msg in (reward, status):
                msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
                msg.header.frame_id = f"camera_{namespace}"
            topics[f"/{namespace}/reward"].append(reward)
            topics[f"/{namespace}/reward/total"].append(Float32(data=total))
            topics[f"/{namespace}/reward/subtask"].append(Int32(data=subtask))
            topics[f"/{namespace}/episode_status"].append(status)
            if images:
                pixels = bytes(range(step, step + 12))  # 2 x 2 rgb8
                image = Image(height=2, width=2, encoding="rgb8", step=6, data=pixels)
                topics[f"/{namespace}/camera/ego/image_raw"].append(image)
    for index in range(2):
        status = DiagnosticStatus(
            name="inest_reward_node: scoring", level=(DiagnosticStatus.OK, DiagnosticStatus.WARN)[index]
        )
        status.values = [KeyValue(key="rate_hz", value=f"{8.0 * (index + 1):.3f}"), KeyValue(key="dropped", value="0")]
        topics["/diagnostics"].append(DiagnosticArray(status=[status]))
    return topics


def main() -> int | str:
    parser = argparse.ArgumentParser()
    parser.add_argument("--namespaces", nargs="+", default=["sim0"])
    parser.add_argument("--images", action="store_true")
    args = parser.parse_args()
    rclpy.init()
    node = rclpy.create_node("reward_publisher")
    topics = expected_messages(args.namespaces, args.images)
    publishers = {topic: node.create_publisher(type(messages[0]), topic, 100) for topic, messages in topics.items()}
    deadline = time.monotonic() + 60
    while not all(publisher.get_subscription_count() for publisher in publishers.values()):
        rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() > deadline:
            silent = [topic for topic, publisher in publishers.items() if not publisher.get_subscription_count()]
            return f"reward_publisher: no subscriber on {silent}"
    for topic, messages in topics.items():
        for msg in messages:
            publishers[topic].publish(msg)
    for topic, publisher in publishers.items():
        if not publisher.wait_for_all_acked(Duration(seconds=60)):
            return f"reward_publisher: {topic} was not acknowledged"
    node.destroy_node()
    rclpy.shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
