"""`inest-sim-node`: the simulator as a ROS 2 node (a thin adapter over SweepToTopEnv).

Publishes, all stamped with simulated time (one control period per step and per reset, so
every observation has its own stamp): `camera/<view>/image_raw` (sensor_msgs/Image, rgb8) for
each view in `cameras` (with `image_transport` "compressed", `camera/<view>/image_raw/compressed`
instead: sensor_msgs/CompressedImage JPEG, as image_transport's compressed transport and most robot
cameras send it), `episode_status` (inest_interfaces/EpisodeStatus, with the new state),
`state` (inest_interfaces/State, while someone subscribes) and `/clock`. Subscribes to
`action` (inest_interfaces/Action); serves `reset` (inest_interfaces/ResetEpisode).

Modes:
- lockstep (training): one step per action, applied only if the action's stamp is the current
  observation's stamp. An action answering the previous observation again (the agent timed out
  waiting) re-publishes that step's outputs instead of stepping twice; a reset before the
  episode's first step (a request asked again) answers with that episode instead of starting another.
- realtime (watching, teleoperation, a live policy): steps at the control rate holding the last
  action, starting a new episode after each truncation. Before an episode it starts itself, it
  asks the reward node serving its stream, if one does, to reset that stream's reward
  (`reset_reward`, std_srvs/Trigger), so that the new episode is not paid the last one's subtask.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import cv2
import numpy as np
from inest_common.rosutil import declare_dataclass, ns_stamp, run_node, stamp_ns
from inest_interfaces.msg import Action, EpisodeStatus, State
from inest_interfaces.srv import ResetEpisode
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CompressedImage, Image
from std_srvs.srv import Trigger

from .config import VIEWS, EnvConfig
from .env import SweepToTopEnv, validate_action

MODES = ("lockstep", "realtime")
IMAGE_TRANSPORTS = ("raw", "compressed")
JPEG_QUALITY = 90
REWARD_RESET_TIMEOUT_NS = 1_000_000_000  # a reward node that does not answer its reset by then is not waited for


@dataclass(frozen=True)
class SimNodeConfig:
    mode: str = "lockstep"
    cameras: tuple[str, ...] = VIEWS
    image_size: int = EnvConfig.image_size
    seed: int = 0  # episode i (0, 1, ...) uses seed + i unless a reset asks for a seed
    max_steps: int = EnvConfig.max_steps
    publish_clock: bool = True  # one simulator per graph should own /clock
    image_transport: str = "raw"  # "compressed": JPEG CompressedImage on <camera topic>/compressed

    def __post_init__(self) -> None:
        if self.mode not in MODES:
            raise ValueError(f"unknown mode {self.mode!r}; expected one of {MODES}")
        if self.image_transport not in IMAGE_TRANSPORTS:
            raise ValueError(f"unknown image_transport {self.image_transport!r}; expected one of {IMAGE_TRANSPORTS}")
        unknown = set(self.cameras) - set(VIEWS)
        if unknown or not self.cameras:
            raise ValueError(f"cameras must be a non-empty subset of {VIEWS}, got {list(self.cameras)}")
        for name in ("image_size", "max_steps"):
            if getattr(self, name) <= 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if self.seed < 0:
            raise ValueError(f"seed must be >= 0, got {self.seed}")


class SimNode(Node):
    def __init__(self) -> None:
        super().__init__("inest_sim_node")
        self.config = config = SimNodeConfig(**declare_dataclass(self, SimNodeConfig()))
        self.env = SweepToTopEnv(config=EnvConfig(max_steps=config.max_steps))
        self.period_ns = round(1e9 / self.env.config.world.control_hz)
        qos = QoSProfile(depth=10)
        compressed = config.image_transport == "compressed"
        kind, suffix = (CompressedImage, "/compressed") if compressed else (Image, "")
        self.image_pubs = {
            view: self.create_publisher(kind, f"camera/{view}/image_raw{suffix}", qos) for view in config.cameras
        }
        self.state_pub = self.create_publisher(State, "state", qos)
        self.status_pub = self.create_publisher(EpisodeStatus, "episode_status", qos)
        self.clock_pub = self.create_publisher(Clock, "/clock", qos) if config.publish_clock else None
        self.create_subscription(Action, "action", self.on_action, qos)
        self.create_service(ResetEpisode, "reset", self.on_reset)
        self.time_ns = 0  # simulated time of the current observation
        self.previous_ns = -1  # ... and of the one before it
        self.episode, self.seed, self.done = -1, config.seed, False
        self.held_action = np.zeros(3)
        self.env_reward = 0.0
        self.last_outputs: list[tuple[object, object]] = []
        self.reward_reset = self.create_client(Trigger, "reset_reward") if config.mode == "realtime" else None
        self.reward_reset_asked_ns: int | None = None  # when the pending reward reset was asked (realtime)
        self.start_episode(-1)
        if config.mode == "realtime":
            self.create_timer(self.period_ns / 1e9, self.on_tick)
        self.get_logger().info(f"{config.mode} simulator, cameras {list(config.cameras)} at {config.image_size} px")

    def start_episode(self, seed: int) -> np.ndarray:
        self.episode += 1
        self.seed = seed if seed >= 0 else self.config.seed + self.episode
        state, _ = self.env.reset(seed=self.seed)
        self.done, self.env_reward = False, 0.0
        self.advance_clock()
        self.publish_observation(state, action_stamp=0)
        return state

    def advance_clock(self) -> None:
        self.previous_ns, self.time_ns = self.time_ns, self.time_ns + self.period_ns

    def step(self, action: np.ndarray, action_stamp: int) -> None:
        state, reward, terminated, truncated, _ = self.env.step(action)
        self.env_reward = float(reward)
        self.done = terminated or truncated
        self.advance_clock()
        self.publish_observation(state, action_stamp)

    def publish_observation(self, state: np.ndarray, action_stamp: int) -> None:
        stamp = ns_stamp(self.time_ns)
        outputs: list[tuple[object, object]] = []
        for view, publisher in self.image_pubs.items():
            image = self.camera_message(self.env.render_camera(view, self.config.image_size))
            image.header.stamp, image.header.frame_id = stamp, f"{view}_camera"
            outputs.append((publisher, image))
        self.state = state
        values = state.tolist()
        status = EpisodeStatus(
            action_stamp=ns_stamp(action_stamp),
            episode=self.episode,
            step=self.env.elapsed_steps,
            seed=self.seed,
            blocks_in_order=self.env.progress,
            score=self.env.progress / 3,
            env_reward=self.env_reward,
            truncated=self.done,
            state=values,
        )
        status.header.stamp, status.header.frame_id = stamp, "world"
        state_msg = State(values=values)
        state_msg.header.stamp, state_msg.header.frame_id = stamp, "world"
        # status before the images: whoever waits on the reward has it already
        outputs = [(self.state_pub, state_msg), (self.status_pub, status), *outputs]
        if self.clock_pub is not None:
            outputs.append((self.clock_pub, Clock(clock=stamp)))
        self.last_outputs = outputs
        self.publish_outputs()

    def camera_message(self, frame: np.ndarray) -> Image | CompressedImage:
        """An rgb8 Image, or the JPEG CompressedImage image_transport makes of it."""
        if self.config.image_transport == "compressed":
            bgr = cv2.cvtColor(frame, cv2.COLOR_RGB2BGR)
            jpeg = cv2.imencode(".jpg", bgr, [cv2.IMWRITE_JPEG_QUALITY, JPEG_QUALITY])[1]
            return CompressedImage(format="rgb8; jpeg compressed bgr8", data=jpeg.tobytes())
        image = Image(height=frame.shape[0], width=frame.shape[1], encoding="rgb8", step=frame.shape[1] * 3)
        image.data = frame.tobytes()
        return image

    def publish_outputs(self) -> None:
        """This step's messages; `state` only while someone listens (the agent reads the status)."""
        for publisher, msg in self.last_outputs:
            if publisher is not self.state_pub or self.state_pub.get_subscription_count():
                publisher.publish(msg)

    def on_action(self, msg: Action) -> None:
        try:
            action = validate_action(np.asarray(msg.values, dtype=np.float64))
        except ValueError as error:
            self.get_logger().error(f"ignored a malformed action: {error}", throttle_duration_sec=1.0)
            return
        if self.config.mode == "realtime":
            self.held_action = action
            return
        stamp = stamp_ns(msg.header.stamp)
        if stamp == self.time_ns and not self.done:
            self.step(action, stamp)
        elif stamp == self.previous_ns:
            self.publish_outputs()  # the agent missed this step's outputs
        elif self.done:
            self.get_logger().warning("the episode is over: call the reset service", throttle_duration_sec=1.0)
        else:
            self.get_logger().warning(
                f"ignored an action for observation {stamp} ns; the current one is {self.time_ns} ns",
                throttle_duration_sec=1.0,
            )

    def on_tick(self) -> None:
        if self.reward_reset_asked_ns is not None:
            if time.monotonic_ns() - self.reward_reset_asked_ns < REWARD_RESET_TIMEOUT_NS:
                return  # the episode starts when the reward node has reset
            self.get_logger().warning("the reward node did not answer its reset within 1 s: starting without it")
            self.reward_reset_asked_ns = None
            self.start_episode(-1)
        elif self.done:
            self.begin_own_episode()
        else:
            self.step(self.held_action, 0)

    def begin_own_episode(self) -> None:
        """A new episode the simulator starts itself: the reward node serving this stream resets
        its reward first, where there is one (no node, no reset: a plain watching graph)."""
        if not self.reward_reset.service_is_ready():
            self.start_episode(-1)
            return
        self.reward_reset_asked_ns = time.monotonic_ns()
        self.reward_reset.call_async(Trigger.Request()).add_done_callback(self.on_reward_reset)

    def on_reward_reset(self, _answer: object) -> None:
        if self.reward_reset_asked_ns is None:
            return  # answered after the timeout: the episode has started already
        self.reward_reset_asked_ns = None
        self.start_episode(-1)

    def on_reset(self, request: ResetEpisode.Request, response: ResetEpisode.Response) -> ResetEpisode.Response:
        # a reset before the episode's first step answers with that episode: a request asked again
        # (its answer was slow, or its first server died) cannot put the simulator an episode ahead
        # of the caller, who acts on the stamp of the first answer it gets
        fresh = self.env.elapsed_steps == 0 and not self.done and request.seed in (-1, self.seed)
        state = self.state if fresh else self.start_episode(request.seed)
        response.success = True
        response.message = f"episode {self.episode}, seed {self.seed}"
        response.header.stamp, response.header.frame_id = ns_stamp(self.time_ns), "world"
        response.state = state.tolist()
        return response


def main() -> int:
    return run_node(SimNode)
