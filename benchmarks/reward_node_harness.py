"""What the reward-node benchmarks share: a reward node of their own on a private ROS domain,
serving one stream or several (one namespace each); per stream, publishers for the camera it
scores and, when the model's stage head reads a second camera (the default model's scene
camera), for that camera too, each pair stamped alike; the rewards and /diagnostics that come
back; simulator frames to send; and a run that got no answers, or lost frames nobody counted,
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
from inest_common.rosutil import namespaced
from inest_interfaces.msg import Reward
from inest_reward_node.runtime.images import COMPRESSIONS, encode_compressed, encode_rgb
from inest_reward_node.runtime.model import ModelError, load_model
from inest_reward_node.runtime.rewards import RewardScorer
from sensor_msgs.msg import CompressedImage, Image

from inest_sim_node import EnvConfig, SweepToTopEnv

IMAGE_TOPIC = "camera/image_raw"
SCENE_TOPIC = "camera/scene/image_raw"
SIMULATOR_SIZE = 96  # px, the simulator's frames: the default model's input
JPEG_QUALITY = 80  # compressed_image_transport's default jpeg_quality


def fail(benchmark: str, why: str) -> NoReturn:
    print(f"{benchmark}: {why}", file=sys.stderr)
    sys.exit(1)


def image(frame: np.ndarray, encoding: str, stamp: int) -> Image | CompressedImage:
    """A raw Image in `encoding`, or for "jpeg" or "png" the CompressedImage image_transport's
    compressed transport publishes."""
    if encoding in COMPRESSIONS:
        msg = CompressedImage(format=f"rgb8; {encoding} compressed bgr8")
        msg.data = encode_compressed(frame, encoding, JPEG_QUALITY)
    else:
        data, step = encode_rgb(frame, encoding)
        msg = Image(height=frame.shape[0], width=frame.shape[1], encoding=encoding, step=step, data=data)
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp, 10**9)
    return msg


def simulator_frames(count: int) -> tuple[np.ndarray, np.ndarray]:
    """`count` moments of random play: the egocentric and the scene camera's frame of each."""
    env = SweepToTopEnv(config=EnvConfig())
    env.reset(seed=0)
    ego, scene = [], []
    for _ in range(count):
        env.step(env.action_space.sample())
        ego.append(env.render_camera("ego", SIMULATOR_SIZE))
        scene.append(env.render_camera("allo", SIMULATOR_SIZE))
    return np.stack(ego), np.stack(scene)


def stage_camera(benchmark: str, model_folder: str) -> str | None:
    """The second camera the model's (3-subtask) stage head reads, as the node would serve it."""
    try:
        return RewardScorer(load_model(model_folder), 3).stage_camera
    except ModelError as error:
        fail(benchmark, str(error))


def percentiles(latencies_ms: np.ndarray) -> dict[str, float]:
    return {
        "latency_p50_ms": round(float(np.percentile(latencies_ms, 50)), 2),
        "latency_p99_ms": round(float(np.percentile(latencies_ms, 99)), 2),
        "latency_max_ms": round(float(np.max(latencies_ms)), 2),
    }


class RewardNodeUnderTest:
    """`inest-reward-node` in its own process, and this process's node that feeds and watches it.
    `streams`: the node's `streams` parameter, one namespace per camera; the default, one stream
    in no namespace. Stream arguments below are indices into it. `image_transport`: the node's
    (raw: Image on the topics; compressed: CompressedImage on <topic>/compressed)."""

    def __init__(
        self,
        benchmark: str,
        model: str,
        node_args: list[str],
        diagnostics_period: float = 0.5,
        streams: tuple[str, ...] = ("",),
        image_transport: str = "raw",
    ) -> None:
        self.benchmark, self.streams = benchmark, streams
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
                 "-p", f"image_transport:={image_transport}",
                 *([] if streams == ("",) else ["-p", f"streams:=[{','.join(streams)}]"]), *node_args],
                env=env, stdout=log, stderr=subprocess.STDOUT,
            )  # fmt: skip
        rclpy.init(domain_id=domain)
        self.node = rclpy.create_node(benchmark)
        # per stream: stamp -> time.perf_counter() its reward came
        self.received: list[dict[int, float]] = [{} for _ in streams]
        self.diagnostics: list[dict[str, str]] = []
        self.cameras, self.scenes = [], []
        message, self.suffix = (Image, "") if image_transport == "raw" else (CompressedImage, "/compressed")
        for index, namespace in enumerate(streams):
            self.node.create_subscription(
                Reward, namespaced(namespace, "reward"), lambda msg, i=index: self.on_reward(i, msg), 1000
            )
            camera_topic = namespaced(namespace, IMAGE_TOPIC) + self.suffix
            scene_topic = namespaced(namespace, SCENE_TOPIC) + self.suffix
            self.cameras.append(self.node.create_publisher(message, camera_topic, 1000))
            self.scenes.append(self.node.create_publisher(message, scene_topic, 1000) if self.stage_camera else None)
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.on_diagnostics, 100)

    def on_reward(self, stream: int, msg: Reward) -> None:
        self.received[stream][msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec] = time.perf_counter()

    def on_diagnostics(self, msg: DiagnosticArray) -> None:
        self.diagnostics.extend({item.key: item.value for item in status.values} for status in msg.status)

    def missing(self) -> list[str]:
        """What the node has not yet connected: its subscriptions to our cameras, its reward topics."""
        waiting = []
        for namespace, camera, scene in zip(self.streams, self.cameras, self.scenes, strict=True):
            for topic, publisher in ((IMAGE_TOPIC, camera), (SCENE_TOPIC, scene)):
                if publisher is not None and not publisher.get_subscription_count():
                    waiting.append(f"a subscriber of {namespaced(namespace, topic)}{self.suffix}")
            if not self.node.count_publishers(reward := namespaced(namespace, "reward")):
                waiting.append(f"a publisher of {reward}")
        return waiting

    def wait_until_ready(self, timeout: float = 60.0) -> None:
        deadline = time.monotonic() + timeout
        while missing := self.missing():
            rclpy.spin_once(self.node, timeout_sec=0.1)
            if self.process.poll() is not None:
                lines = self.log_path.read_text().strip().splitlines() or ["(no output)"]
                fail(self.benchmark, f"the reward node exited: {lines[-1]}")
            if time.monotonic() > deadline:
                fail(self.benchmark, f"after {timeout:.0f} s the graph still lacks {', '.join(missing)}")

    def publish(self, camera: Image | CompressedImage, scene: Image | CompressedImage | None, stream: int = 0) -> None:
        """One moment of a stream: the camera's frame, then (if the node reads one) the scene
        camera's, unless `scene` is None (a withheld frame)."""
        self.cameras[stream].publish(camera)
        if self.scenes[stream] is not None and scene is not None:
            self.scenes[stream].publish(scene)

    def spin_for(self, seconds: float) -> None:
        end = time.perf_counter() + seconds
        while (left := end - time.perf_counter()) > 0:
            rclpy.spin_once(self.node, timeout_sec=min(left, 0.05))

    def reset(self) -> None:
        for received in self.received:
            received.clear()
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

    def counted_drops(self, stream: int = 0) -> int:
        """The stream's camera frames the node said it dropped or refused as stale since the last
        reset (not the scene camera's own, `dropped_stage_unpaired`)."""
        return sum(int(d.get(f"stream{stream}_unanswered", 0)) for d in self.diagnostics)

    def latencies_ms(self, sent: dict[int, float], stream: int = 0) -> np.ndarray:
        """Publish -> reward of every frame of `sent` (stamp -> time.perf_counter() sent) answered."""
        received = self.received[stream]
        return np.array([(received[stamp] - time_sent) * 1e3 for stamp, time_sent in sent.items() if stamp in received])

    def stream_figures(
        self, phase: str, sent: dict[int, float], every_frame: bool = True, stream: int = 0
    ) -> dict[str, float | int]:
        """Latency of every answered frame of a stream (publish -> reward), and what became of the
        others. `every_frame`: every frame must be answered or counted (a paced stream; a flood
        past the subscription's queue loses frames DDS never reports)."""
        latencies = self.latencies_ms(sent, stream)
        if not len(latencies):
            lines = self.log_path.read_text().strip().splitlines() or ["(no output)"]
            fail(self.benchmark, f"{phase}: no reward for any of the {len(sent)} frames sent; node: {lines[-1]}")
        counted = self.counted_drops(stream)
        uncounted = len(sent) - len(latencies) - counted
        if every_frame and uncounted > 0:
            fail(self.benchmark, f"{phase}: {uncounted} of {len(sent)} frames got no reward and were not counted")
        return {
            "valid_sent": len(sent),
            "answered": len(latencies),
            "counted_drops": counted,
            "uncounted": max(uncounted, 0),
            **percentiles(latencies),
        }

    def figures(self, phase: str, sent: dict[int, float], every_frame: bool = True) -> dict[str, float | int]:
        """The one stream's figures (`stream_figures`) and the pairing's cost."""
        return self.stream_figures(phase, sent, every_frame) | self.pairing()

    def log_lines(self) -> list[str]:
        return self.log_path.read_text().splitlines()

    def close(self) -> None:
        self.node.destroy_node()
        rclpy.shutdown()
        self.process.terminate()
        self.process.wait()
        self.logs.cleanup()
