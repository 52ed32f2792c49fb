"""What the reward-node benchmarks share: a reward node of their own on a private ROS domain,
publishers for the camera it scores and, when the model's stage head reads a second camera (the
default model's scene camera), for that camera too, each pair stamped alike; the rewards and
/diagnostics that come back; and a run that got no answers, or lost frames nobody counted,
ending with one line naming why and exit status 1, never a result with NaN figures."""

from __future__ import annotations

import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import NoReturn

import numpy as np
import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from inest_bringup.launcher import graph_environment
from inest_interfaces.msg import Reward
from inest_reward_node.runtime.images import encode_rgb
from inest_reward_node.runtime.model import ModelError, load_model
from inest_reward_node.runtime.rewards import RewardScorer
from sensor_msgs.msg import Image

IMAGE_TOPIC = "camera/image_raw"
SCENE_TOPIC = "camera/scene/image_raw"


def fail(benchmark: str, why: str) -> NoReturn:
    print(f"{benchmark}: {why}", file=sys.stderr)
    sys.exit(1)


def image(frame: np.ndarray, encoding: str, stamp: int) -> Image:
    data, step = encode_rgb(frame, encoding)
    msg = Image(height=frame.shape[0], width=frame.shape[1], encoding=encoding, step=step)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 10**9)
    msg.data = data
    return msg


def stage_camera(benchmark: str, model_folder: str) -> str | None:
    """The second camera the model's (3-subtask) stage head reads, as the node would serve it."""
    try:
        return RewardScorer(load_model(model_folder), 3).stage_camera
    except ModelError as error:
        fail(benchmark, str(error))


class RewardNodeUnderTest:
    """`inest-reward-node` in its own process, and this process's node that feeds and watches it."""

    def __init__(self, benchmark: str, model: str, node_args: list[str], diagnostics_period: float = 0.5) -> None:
        self.benchmark = benchmark
        self.stage_camera = stage_camera(benchmark, model)
        self.logs = tempfile.TemporaryDirectory()
        domain = 150 + os.getpid() % 50
        env = graph_environment(domain, self.logs.name)
        os.environ.update(env)  # this process's own participant joins the same private graph
        self.log_path = Path(self.logs.name) / "reward_node.log"
        with open(self.log_path, "w") as log:
            self.process = subprocess.Popen(
                [str(Path(sys.executable).parent / "inest-reward-node"), "--ros-args",
                 "-p", f"model:={Path(model).resolve()}", "-p", f"image_topic:={IMAGE_TOPIC}",
                 "-p", f"stage_image_topic:={SCENE_TOPIC}", "-p", f"diagnostics_period:={diagnostics_period}",
                 *node_args],
                env=env, stdout=log, stderr=subprocess.STDOUT,
            )  # fmt: skip
        rclpy.init(domain_id=domain)
        self.node = rclpy.create_node(benchmark)
        self.received: dict[int, float] = {}  # stamp -> time.perf_counter() its reward came
        self.diagnostics: list[dict[str, str]] = []
        self.node.create_subscription(Reward, "reward", self.on_reward, 1000)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 100)
        self.camera = self.node.create_publisher(Image, IMAGE_TOPIC, 1000)
        self.scene = self.node.create_publisher(Image, SCENE_TOPIC, 1000) if self.stage_camera else None

    def on_reward(self, msg: Reward) -> None:
        self.received[msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = time.perf_counter()

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        self.diagnostics.extend({item.key: item.value for item in status.values} for status in msg.status)

    def missing(self) -> list[str]:
        """What the node has not yet connected: its subscriptions to our cameras, its reward topic."""
        waiting = [] if self.camera.get_subscription_count() else [f"a subscriber of {IMAGE_TOPIC}"]
        if self.scene is not None and not self.scene.get_subscription_count():
            waiting.append(f"a subscriber of {SCENE_TOPIC}")
        return waiting + ([] if self.node.count_publishers("reward") else ["a publisher of reward"])

    def wait_until_ready(self, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while missing := self.missing():
            rclpy.spin_once(self.node, timeout_sec=0.1)
            if self.process.poll() is not None:
                lines = self.log_path.read_text().strip().splitlines() or ["(no output)"]
                fail(self.benchmark, f"the reward node exited: {lines[-1]}")
            if time.monotonic() > deadline:
                fail(self.benchmark, f"after {timeout:.0f} s the graph still lacks {', '.join(missing)}")

    def publish(self, camera: Image, scene: Image | None) -> None:
        """One moment: the camera's frame, then (if the node reads one) the scene camera's, unless
        `scene` is None (a withheld frame)."""
        self.camera.publish(camera)
        if self.scene is not None and scene is not None:
            self.scene.publish(scene)

    def spin_for(self, seconds: float) -> None:
        end = time.perf_counter() + seconds
        while (left := end - time.perf_counter()) > 0:
            rclpy.spin_once(self.node, timeout_sec=min(left, 0.05))

    def reset(self) -> None:
        self.received.clear()
        self.diagnostics.clear()

    def pairing(self) -> dict[str, float | int]:
        """The pairing's own cost since the last reset, from the node's diagnostics."""
        if self.stage_camera is None:
            return {}
        return {
            "waited_for_stage_frame": sum(int(d.get("waited_for_stage_frame", 0)) for d in self.diagnostics),
            "stage_wait_p99_ms": max((float(d.get("stage_wait_p99_ms", 0)) for d in self.diagnostics), default=0.0),
            "dropped_unpaired": sum(int(d.get("dropped_unpaired", 0)) for d in self.diagnostics),
            "scene_frames_dropped": sum(int(d.get("dropped_stage_unpaired", 0)) for d in self.diagnostics),
        }

    def counted_drops(self) -> int:
        """Camera frames the node said it dropped or refused as stale since the last reset (not the
        scene camera's own, `dropped_stage_unpaired`)."""
        return sum(
            int(d.get("dropped", 0)) - int(d.get("dropped_stage_unpaired", 0)) + int(d.get("rejected_stale", 0))
            for d in self.diagnostics
        )

    def figures(self, phase: str, sent: dict[int, float], every_frame: bool = True) -> dict[str, float | int]:
        """Latency of every answered frame (publish -> reward), and what became of the others.
        `every_frame`: every frame must be answered or counted (a paced stream; a flood past the
        subscription's queue loses frames DDS never reports)."""
        answered = [stamp for stamp in sent if stamp in self.received]
        if not answered:
            lines = self.log_path.read_text().strip().splitlines() or ["(no output)"]
            fail(self.benchmark, f"{phase}: no reward for any of the {len(sent)} frames sent; node: {lines[-1]}")
        counted = self.counted_drops()
        uncounted = len(sent) - len(answered) - counted
        if every_frame and uncounted > 0:
            fail(self.benchmark, f"{phase}: {uncounted} of {len(sent)} frames got no reward and were not counted")
        latencies = np.array([(self.received[stamp] - sent[stamp]) * 1e3 for stamp in answered])
        return {
            "valid_sent": len(sent),
            "answered": len(answered),
            "counted_drops": counted,
            "uncounted": max(uncounted, 0),
            "latency_p50_ms": round(float(np.percentile(latencies, 50)), 2),
            "latency_p99_ms": round(float(np.percentile(latencies, 99)), 2),
            "latency_max_ms": round(float(np.max(latencies)), 2),
            **self.pairing(),
        }

    def log_lines(self) -> list[str]:
        return self.log_path.read_text().splitlines()

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.shutdown()
        self.process.terminate()
        self.process.wait()
        self.logs.cleanup()
