"""`inest-reward-node`: the learned reward served over ROS 2 (a thin adapter over serving.py).

Subscribes to `<stream>/<image_topic>` (sensor_msgs/Image: rgb8, bgr8, rgba8, bgra8, mono8, sides
within `min_image_size`..`max_image_size`) for every stream in `streams`, and to
`<stream>/<stage_image_topic>` too when the model's stage head reads a second camera (a scene
camera; its frames pair with the first camera's by stamp); with `image_transport:=compressed`,
to `<topic>/compressed` instead (sensor_msgs/CompressedImage, JPEG or PNG: image_transport's
compressed transport, what cameras are usually recorded as); publishes `<stream>/reward`
(inest_interfaces/Reward with the image's header), `<stream>/reward/total` (std_msgs/Float32) and
`<stream>/reward/subtask` (std_msgs/Int32) for plotting tools; serves `<stream>/reset_reward`
(std_srvs/Trigger: new episode, tracker reset, exploration memories kept); publishes /diagnostics
every second.
Setting the `model` parameter while the node runs loads that model (a refitted one) without a
restart: frames already received are scored by the old one, each stream carries on its episode
at its stage, the novelty memories are kept if the encoder weights are the same, and every
reward says which model scored it (Reward.model_generation; the log and /diagnostics name it).
A model that cannot be loaded, or reads other cameras, is refused with the reason, and the node
goes on with the one it has. Every other parameter is read at start-up; changing one later is refused.
Frames that arrive together, of every stream, are scored in one encoder forward pass (`max_batch`
at most). Malformed frames are refused from their header fields alone, in constant time, so a
flood of them cannot delay valid ones; the stamp policy is serving.py's.

Parameters: the RewardNodeConfig fields, `intrinsic.*` (IntrinsicConfig) and `reward.*`
(runtime.config.RewardConfig: shaping, tracker, stage_source, stage_evidence, hold_steps,
stage_confidence, confirm_window, confirm_steps, instant_confidence, retract_confidence,
retract_steps, intrinsic_cap, stage_support, stage_filter, filter_advance, filter_regress,
filter_temperature;
`reward.intrinsic_cap:=.inf` is no cap). `reward.stage_source:=privileged`
is refused: the node sees images only, not the simulator's progress.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass

import cv2
import rclpy
import torch
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from inest_common.rosutil import declare_dataclass, namespaced, new_executor, ns_stamp, run_node, stamp_ns
from inest_interfaces.msg import Reward
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import Executor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile
from sensor_msgs.msg import CompressedImage, Image
from std_msgs.msg import Float32, Int32
from std_srvs.srv import Trigger

from .runtime.config import RewardConfig
from .runtime.images import RESIZE_MODES, ImageRejected, decode_compressed, decode_image
from .runtime.intrinsic import IntrinsicConfig
from .runtime.model import DEFAULT_MODEL, TCC_SCHEMES, ModelError, encoder_digest, load_model
from .runtime.reward_parts import message_fields
from .runtime.rewards import RewardScorer
from .runtime.serving import ScoredFrame, StreamScorer, ThrottledLog

IMAGE_TRANSPORTS = ("raw", "compressed")


@dataclass(frozen=True)
class RewardNodeConfig:
    model: str = DEFAULT_MODEL  # a pretraining run's model/ folder; default: the committed one
    subtasks: int = 3
    variant: str = ""  # inest | xirl | holdr | reds; empty: the model's natural one for `subtasks`
    streams: tuple[str, ...] = ("",)  # namespaces of the image sources, e.g. ["sim0", "sim1"]
    image_topic: str = "camera/ego/image_raw"
    stage_image_topic: str = "camera/allo/image_raw"  # only for a stage head that reads a second camera
    # raw: sensor_msgs/Image on the topics; compressed: sensor_msgs/CompressedImage (JPEG, PNG) on
    # <topic>/compressed, image_transport's name for it
    image_transport: str = "raw"
    max_batch: int = 32  # frames per forward pass at most
    # ms a flush waits for the other streams' frames: lockstep simulators' frames of one round
    # arrive within a millisecond or two, and one forward pass for all of them costs less than several
    round_wait_ms: float = 2.0
    max_pending: int = 4  # per stream; older unscored frames are dropped (and counted)
    queue_depth: int = 1000  # per stream, the subscription's: DDS drops beyond it silently, so it holds a burst
    min_image_size: int = 32  # pixels, the shorter side at least: smaller frames are rejected
    max_image_size: int = 4096  # pixels, the longer side at most
    resize: str = "crop"  # crop: the centred square (the training camera's aspect), then resized | squash
    backward_stamps: str = "reset"  # a stamp older than the stream's newest: reset (a new episode) | reject
    log_period: float = 5.0  # seconds: a repeated rejection or backward stamp is logged once per period, counted
    diagnostics_period: float = 1.0  # seconds
    threads: int = 1  # torch threads: one keeps batch-1 latency steady when the simulator and agent share the cores

    def __post_init__(self) -> None:
        if self.resize not in RESIZE_MODES:
            raise ValueError(f"resize must be one of {RESIZE_MODES}, got {self.resize!r}")
        if self.image_transport not in IMAGE_TRANSPORTS:
            raise ValueError(f"image_transport must be one of {IMAGE_TRANSPORTS}, got {self.image_transport!r}")
        if not 1 <= self.min_image_size <= self.max_image_size:
            raise ValueError(
                f"need 1 <= min_image_size <= max_image_size, got {self.min_image_size} and {self.max_image_size}"
            )
        if self.subtasks not in TCC_SCHEMES:
            raise ValueError(f"subtasks must be one of {TCC_SCHEMES}, got {self.subtasks}")
        for name in ("max_batch", "max_pending", "threads"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be >= 1, got {getattr(self, name)}")
        if not self.diagnostics_period > 0:
            raise ValueError(f"diagnostics_period must be positive (seconds), got {self.diagnostics_period}")
        if not 0 <= self.round_wait_ms <= 1000:
            raise ValueError(f"round_wait_ms must be in [0, 1000], got {self.round_wait_ms}")
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
        self.config, self.intrinsic, self.reward_config = config, intrinsic, reward
        # OpenCV's own warning per undecodable file ("PNG input buffer is incomplete") would bypass
        # the rate-limited log below, whose rejection line says the same once per log period
        cv2.utils.logging.setLogLevel(cv2.utils.logging.LOG_LEVEL_ERROR)
        torch.set_num_threads(config.threads)
        scorer = self.new_scorer(config.model)
        self.model, self.encoder = config.model, encoder_digest(config.model)
        self.log = ThrottledLog(config.log_period)
        self.streams = StreamScorer(scorer, config.max_pending, config.backward_stamps, self.log, config.max_batch)
        qos = QoSProfile(depth=10)
        self.reward_pubs, self.total_pubs, self.subtask_pubs = [], [], []
        message, suffix = (Image, "") if config.image_transport == "raw" else (CompressedImage, "/compressed")
        for index, namespace in enumerate(config.streams):
            self.create_subscription(
                message,
                namespaced(namespace, config.image_topic) + suffix,
                lambda msg, i=index: self.on_image(i, msg),
                QoSProfile(depth=config.queue_depth),
            )
            if scorer.stage_camera is not None:
                self.create_subscription(
                    message,
                    namespaced(namespace, config.stage_image_topic) + suffix,
                    lambda msg, i=index: self.on_image(i, msg, stage=True),
                    QoSProfile(depth=config.queue_depth),
                )
            self.reward_pubs.append(self.create_publisher(Reward, namespaced(namespace, "reward"), qos))
            self.total_pubs.append(self.create_publisher(Float32, namespaced(namespace, "reward/total"), qos))
            self.subtask_pubs.append(self.create_publisher(Int32, namespaced(namespace, "reward/subtask"), qos))
            self.create_service(
                Trigger, namespaced(namespace, "reset_reward"), lambda req, res, i=index: self.on_reset(i, res)
            )
        self.diagnostics = self.create_publisher(DiagnosticArray, "/diagnostics", 10)
        self.create_timer(config.diagnostics_period, self.publish_diagnostics)
        evidence = f" reading {scorer.evidence}" if scorer.evidence else ""
        stage = (
            f", stage from {[namespaced(ns, config.stage_image_topic) for ns in config.streams]} "
            f"({scorer.stage_camera} camera)"
            if scorer.stage_camera
            else ""
        )
        self.get_logger().info(
            f"scoring {[namespaced(ns, config.image_topic) for ns in config.streams]} with {config.model} "
            f"({scorer.variant}, {config.subtasks} subtasks, intrinsic {intrinsic.mode}, "
            f"{reward.shaping} shaping, {reward.tracker} tracker{evidence}{stage})"
        )
        self.add_on_set_parameters_callback(self.on_set_parameters)

    def new_scorer(self, model: str) -> RewardScorer:
        config = self.config
        return RewardScorer(
            load_model(model, scheme=config.subtasks),
            config.subtasks,
            config.variant or None,
            self.intrinsic,
            len(config.streams),
            config=self.reward_config,
        )

    def on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        """A new `model` is loaded now (a refitted one); any other parameter is read at start-up only."""
        fixed = sorted(parameter.name for parameter in parameters if parameter.name != "model")
        if fixed:
            return SetParametersResult(
                successful=False, reason=f"{', '.join(fixed)}: read at start-up; restart the node"
            )
        for parameter in parameters:
            try:
                self.load(str(parameter.value))
            except (ModelError, ValueError, OSError) as error:
                self.get_logger().warning(f"kept model {self.model}: {parameter.value} refused: {error}")
                return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def load(self, model: str) -> None:
        """Score with `model` from the next frame on, the running episodes carried on."""
        scorer, encoder = self.new_scorer(model), encoder_digest(model)
        self.publish(self.streams.flush())  # what arrived under the old model is scored by it
        self.streams.replace_scorer(scorer, keep_memories=encoder == self.encoder)
        memories = "kept" if encoder == self.encoder else "cleared (another encoder)"
        self.model, self.encoder = model, encoder
        self.get_logger().info(
            f"model generation {self.streams.model_generation}: {model} scores from the next frame on; "
            f"episodes carry on at their stage, novelty memories {memories}"
        )

    def on_image(self, stream: int, msg: Image | CompressedImage, stage: bool = False) -> None:
        """A frame of the encoder's camera, or (`stage`) of the stage head's second camera."""
        received = time.perf_counter()
        config, size = self.config, self.streams.scorer.image_size
        bounds = (size, config.resize, config.min_image_size, config.max_image_size)
        try:
            if isinstance(msg, CompressedImage):
                frame, height, width = decode_compressed(msg.format, msg.data, *bounds)
            else:
                frame = decode_image(msg.encoding, msg.height, msg.width, msg.step, msg.data, *bounds)
                height, width = msg.height, msg.width
        except ImageRejected as error:
            self.streams.reject(error.kind, f"stream {stream}{' stage camera' if stage else ''}: {error}")
        else:
            stamp = stamp_ns(msg.header.stamp)
            if stage:
                self.streams.submit_stage(stream, stamp, frame, received)
            else:
                if height != width:
                    self.log.once(
                        f"aspect:{width}x{height}",
                        f"{width}x{height} frames: "
                        + ("centre-cropped to the training camera's square" if config.resize == "crop" else "squashed")
                        + f", then resized to {size}x{size} (resize:={config.resize})",
                        "info",
                    )
                self.publish(self.streams.submit(stream, stamp, frame, received, msg.header.frame_id))
        self.write_log()

    def write_log(self) -> None:
        logger = self.get_logger()
        for level, line in self.log.take():  # one call site per severity: rclpy refuses a change
            if level == "info":
                logger.info(line)
            else:
                logger.warning(line)

    def on_reset(self, stream: int, response: Trigger.Response) -> Trigger.Response:
        self.publish(self.streams.flush())  # frames of the old episode belong to it
        self.streams.reset(stream)
        response.success, response.message = True, f"stream {stream}: subtask tracker reset"
        return response

    def publish(self, scored: list[ScoredFrame]) -> None:
        for frame in scored:
            msg = Reward(
                **message_fields(vars(frame)),
                num_subtasks=self.streams.scorer.num_subtasks,
                episode_frame=frame.episode_frame,
                model_generation=frame.model_generation,
            )
            msg.header.stamp = ns_stamp(frame.stamp)
            msg.header.frame_id = frame.frame_id
            self.reward_pubs[frame.stream].publish(msg)
            # the plain-number copies are for plots and recorders: published only while one listens,
            # since two more messages per frame cost the training graph (the agent reads `reward`)
            if self.total_pubs[frame.stream].get_subscription_count():
                self.total_pubs[frame.stream].publish(Float32(data=frame.total))
            if self.subtask_pubs[frame.stream].get_subscription_count():
                self.subtask_pubs[frame.stream].publish(Int32(data=frame.completed))

    def publish_diagnostics(self) -> None:
        self.write_log()  # the counts of floods that have stopped
        summary = self.streams.take_stats()
        status = DiagnosticStatus(name="inest_reward_node: scoring", hardware_id=self.get_fully_qualified_name())
        problems = [
            f"{summary[key]} {what}"
            for key, what in (
                ("rejected", "rejected"), ("dropped", "dropped"), ("zero_stamps", "zero stamps"),
                ("repeated_stamps", "repeated stamps"), ("stamp_resets", "backward stamps"),
            )
            if summary[key]
        ]  # fmt: skip
        if summary["rejected"]:
            problems.append(f"last rejection: {summary['last_rejection']}")
        status.level = DiagnosticStatus.WARN if problems else DiagnosticStatus.OK
        status.message = "; ".join(problems) or "ok"
        summary |= {"model": self.model, "model_generation": self.streams.model_generation}
        status.values = [
            KeyValue(key=key, value=f"{value:.3f}" if isinstance(value, float) else str(value))
            for key, value in summary.items()
        ]
        array = DiagnosticArray(status=[status])
        array.header.stamp = self.get_clock().now().to_msg()
        self.diagnostics.publish(array)

    def spin(self) -> None:
        """Take every callback that is ready, wait up to `round_wait_ms` for a frame from every
        stream (a lockstep round), then score what arrived, of every stream, in one batch (more
        than `max_batch` in as many batches, one after another)."""
        executor = new_executor()
        executor.add_node(self)
        round_wait = self.config.round_wait_ms / 1e3
        try:
            while rclpy.ok():
                executor.spin_once(timeout_sec=0.1)
                self.take_ready(executor)
                if not self.streams.num_pending:
                    continue
                deadline = time.perf_counter() + round_wait
                while not self.streams.round_complete and (left := deadline - time.perf_counter()) > 0:
                    executor.spin_once(timeout_sec=left)
                    self.take_ready(executor)
                self.publish(self.streams.flush())
                while self.streams.ready:
                    self.publish(self.streams.flush())
        finally:
            executor.shutdown()

    def take_ready(self, executor: Executor) -> None:
        """Run the callbacks already waiting, while they bring frames (of either camera), up to
        `max_batch` pending."""
        while self.streams.num_pending < self.config.max_batch:
            before = self.streams.arrivals
            executor.spin_once(timeout_sec=0.0)
            if self.streams.arrivals == before:
                break


def main() -> int:
    return run_node(RewardNode, RewardNode.spin, (ValueError, ModelError))
