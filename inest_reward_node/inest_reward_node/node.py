"""`inest-reward-node`: the learned reward served over ROS 2 (a thin adapter over serving.py).

Subscribes to `<stream>/<image_topic>` (sensor_msgs/Image: rgb8, bgr8, rgba8, bgra8, any size)
for every stream in `streams`; publishes `<stream>/reward` (inest_interfaces/Reward with the
image's header), `<stream>/reward/total` (std_msgs/Float32) and `<stream>/reward/subtask`
(std_msgs/Int32) for plotting tools; serves `<stream>/reset_reward` (std_srvs/Trigger: new
episode, tracker reset, exploration memories kept); publishes /diagnostics every second.
Frames that arrive together are scored in one encoder forward pass.

Parameters: the RewardNodeConfig fields, `intrinsic.*` (IntrinsicConfig) and `reward.*`
(stages.RewardConfig: shaping, tracker, stage_source, hold_steps, stage_confidence,
intrinsic_cap; `reward.intrinsic_cap:=.inf` is no cap). `reward.stage_source:=privileged`
is refused: the node sees images only, not the simulator's progress.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import rclpy
import torch
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from inest_common.rosutil import declare_dataclass, namespaced, ns_stamp, run_node, stamp_ns
from inest_interfaces.msg import Reward
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import QoSProfile
from sensor_msgs.msg import Image
from std_msgs.msg import Float32, Int32
from std_srvs.srv import Trigger

from .calibrate import TCC_SCHEMES
from .images import ImageRejected, decode_image
from .intrinsic import IntrinsicConfig
from .model import ModelError, load_model
from .rewards import RewardScorer
from .serving import ScoredFrame, StreamScorer
from .stages import RewardConfig


@dataclass(frozen=True)
class RewardNodeConfig:
    model: str = "runs/pretrain-main/model"  # a pretraining run's model/ folder
    subtasks: int = 3
    variant: str = ""  # inest | xirl | holdr; empty: the model's natural one for `subtasks`
    streams: tuple[str, ...] = ("",)  # namespaces of the image sources, e.g. ["sim0", "sim1"]
    image_topic: str = "camera/ego/image_raw"
    max_batch: int = 32  # frames per forward pass at most
    max_pending: int = 4  # per stream; older unscored frames are dropped (and counted)
    diagnostics_period: float = 1.0  # seconds
    threads: int = 1  # torch threads: one keeps batch-1 latency steady when the simulator and agent share the cores

    def __post_init__(self) -> None:
        if self.subtasks not in TCC_SCHEMES:
            raise ValueError(f"subtasks must be one of {TCC_SCHEMES}, got {self.subtasks}")
        for name in ("max_batch", "max_pending", "threads"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.diagnostics_period > 0:
            raise ValueError(f"diagnostics_period must be positive (seconds), got {self.diagnostics_period}")
        if not self.streams or len(set(self.streams)) != len(self.streams):
            raise ValueError(f"streams must be distinct and at least one, got {list(self.streams)}")


def declare_reward_config(node: Node, prefix: str = "reward.") -> RewardConfig:
    """RewardConfig's fields as ROS parameters; `intrinsic_cap` is a double whose `.inf` means no cap
    (a None default would be declared as a string)."""
    defaults = RewardConfig()
    as_declared = dataclasses.replace(defaults, intrinsic_cap=defaults.cap)
    values = declare_dataclass(node, as_declared, prefix)
    cap = float(values["intrinsic_cap"])
    reward = RewardConfig(**{**values, "intrinsic_cap": None if math.isinf(cap) else cap})
    if reward.stage_source == "privileged":
        raise ValueError(
            "reward.stage_source 'privileged' needs the simulator's progress; the reward node only sees images"
        )
    return reward


class RewardNode(Node):
    def __init__(self) -> None:
        super().__init__("inest_reward_node")
        config = RewardNodeConfig(**declare_dataclass(self, RewardNodeConfig()))
        intrinsic = IntrinsicConfig(**declare_dataclass(self, IntrinsicConfig(), "intrinsic."))
        if intrinsic.mode == "state":
            raise ValueError("intrinsic.mode 'state' needs state vectors; the reward node only sees images")
        reward = declare_reward_config(self)
        self.config = config
        torch.set_num_threads(config.threads)
        model = load_model(config.model, scheme=config.subtasks)
        scorer = RewardScorer(
            model, config.subtasks, config.variant or None, intrinsic, len(config.streams), config=reward
        )
        self.streams = StreamScorer(scorer, config.max_pending)
        qos = QoSProfile(depth=10)
        self.reward_pubs, self.total_pubs, self.subtask_pubs = [], [], []
        for index, namespace in enumerate(config.streams):
            self.create_subscription(  # DDS keeps only the newest max_pending frames: a flood costs no decoding
                Image,
                namespaced(namespace, config.image_topic),
                lambda msg, i=index: self.on_image(i, msg),
                QoSProfile(depth=config.max_pending),
            )
            self.reward_pubs.append(self.create_publisher(Reward, namespaced(namespace, "reward"), qos))
            self.total_pubs.append(self.create_publisher(Float32, namespaced(namespace, "reward/total"), qos))
            self.subtask_pubs.append(self.create_publisher(Int32, namespaced(namespace, "reward/subtask"), qos))
            self.create_service(
                Trigger, namespaced(namespace, "reset_reward"), lambda req, res, i=index: self.on_reset(i, res)
            )
        self.diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(config.diagnostics_period, self.publish_diagnostics)
        self.get_logger().info(
            f"scoring {[namespaced(ns, config.image_topic) for ns in config.streams]} with {config.model} "
            f"({scorer.variant}, {config.subtasks} subtasks, intrinsic {intrinsic.mode}, "
            f"{reward.shaping} shaping, {reward.tracker} tracker)"
        )

    def on_image(self, stream: int, msg: Image) -> None:
        received = time.perf_counter()
        try:
            frame = decode_image(msg.encoding, msg.height, msg.width, msg.step, msg.data)
        except ImageRejected as error:
            new_reason = str(error) != self.streams.stats.last_rejection
            self.streams.reject(str(error))
            message = f"rejected a frame on stream {stream}: {error}"
            if new_reason:  # every new reason is logged; a flood of the same one once a second
                self.get_logger().warning(message)
            else:
                self.get_logger().warning(message, throttle_duration_sec=1.0)
            return
        self.streams.submit(stream, stamp_ns(msg.header.stamp), frame, received, msg.header.frame_id)

    def on_reset(self, stream: int, response: Trigger.Response) -> Trigger.Response:
        self.publish(self.streams.flush())  # frames of the old episode belong to it
        self.streams.reset(stream)
        response.success, response.message = True, f"stream {stream}: subtask tracker reset"
        return response

    def publish(self, scored: list[ScoredFrame]) -> None:
        for frame in scored:
            msg = Reward()
            msg.header.stamp = ns_stamp(frame.stamp)
            msg.header.frame_id = frame.frame_id
            msg.total, msg.distance_reward = frame.total, frame.distance
            msg.subtask_bonus, msg.intrinsic_bonus = frame.bonus, frame.intrinsic
            msg.subtask, msg.num_subtasks = frame.subtask, self.streams.scorer.num_subtasks
            msg.subtask_completed = frame.completed_subtask
            self.reward_pubs[frame.stream].publish(msg)
            self.total_pubs[frame.stream].publish(Float32(data=frame.total))
            self.subtask_pubs[frame.stream].publish(Int32(data=frame.subtask))

    def publish_diagnostics(self) -> None:
        summary = self.streams.take_stats()
        status = DiagnosticStatus(name="inest_reward_node: scoring", hardware_id=self.get_fully_qualified_name())
        problems = summary["rejected"] or summary["dropped"]
        status.level = DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
        status.message = summary["last_rejection"] or ("frames dropped" if summary["dropped"] else "ok")
        status.values = [
            KeyValue(key=key, value=f"{value:.3f}" if isinstance(value, float) else str(value))
            for key, value in summary.items()
        ]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics.publish(array)

    def spin(self) -> None:
        """Take every callback that is ready, then score what arrived in one batch."""
        executor = SingleThreadedExecutor()
        executor.add_node(self)
        try:
            while rclpy.ok():
                executor.spin_once(timeout_sec=0.1)
                taken = 0
                while self.streams.num_pending and taken < self.config.max_batch:
                    before = self.streams.num_pending
                    executor.spin_once(timeout_sec=0.0)
                    if self.streams.num_pending == before:
                        break
                    taken += 1
                if self.streams.num_pending:
                    self.publish(self.streams.flush())
        finally:
            executor.shutdown()


def main() -> int:
    return run_node(RewardNode, RewardNode.spin, (ValueError, ModelError))
