"""`inest-teleop-standin`: a person at the controls, played by the scripted expert, driving a
simulator node over the graph: the simulator rehearses a robot's demonstration session.

The operator sees the world through a copy of the simulator kept in step with the node (same
seed, same actions; every episode_status is checked against it), acts with the expert's policy
plus human-like noise and pauses (stretches of standing still), and keeps only the takes that
place all three blocks in order, as a person discards a failed take. For each kept take it
writes a row of the episode times file (`episode,start,end`: wall-clock seconds since the epoch,
the receive times a recorder stamps; `inest-import-demos --episode-times` wants them relative to
the recording's start) and, to a separate file, the frames on which its subtasks truly end (what
a perfect labeller would write into inest-label-demos' label file). The node must run in lockstep
mode (`-p mode:=lockstep`) with `max_steps` room for the pauses.
"""

from __future__ import annotations

import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import rclpy
from inest_common.rosutil import namespaced, new_executor, ns_stamp, stamp_ns
from inest_common.settings import OneLineParser
from inest_interfaces.msg import Action, EpisodeStatus
from inest_interfaces.srv import ResetEpisode
from rclpy.node import Node
from rclpy.qos import QoSProfile
from rclpy.utilities import remove_ros_args

from .config import EnvConfig
from .env import SweepToTopEnv
from .expert import ExpertConfig, ScriptedExpert
from .subtasks import subtask_labels

WAIT_S = 10.0  # a simulator silent this long is an error
SETTLE_SEED = 2**31 - 1


class OutOfStep(RuntimeError):
    """The simulator node and the operator's copy of it no longer agree."""


class TeleopStandIn:
    def __init__(
        self, node: Node, namespace: str, max_steps: int, noise: float, pause: float, rng: np.random.Generator
    ) -> None:
        self.node, self.pause, self.rng = node, pause, rng
        self.env = SweepToTopEnv(config=EnvConfig(max_steps=max_steps))
        self.expert = ScriptedExpert(replace(ExpertConfig(), action_noise=noise))
        self.executor = new_executor()
        self.executor.add_node(node)
        qos = QoSProfile(depth=10)
        self.actions = node.create_publisher(Action, namespaced(namespace, "action"), qos)
        self.reset_client = node.create_client(ResetEpisode, namespaced(namespace, "reset"))
        self.statuses: list[EpisodeStatus] = []
        node.create_subscription(EpisodeStatus, namespaced(namespace, "episode_status"), self.statuses.append, qos)

    def wait(self, ready, what: str) -> None:
        deadline = time.monotonic() + WAIT_S
        while not ready():
            if time.monotonic() > deadline:
                raise OutOfStep(f"no {what} from the simulator within {WAIT_S:.0f} s")
            self.executor.spin_once(timeout_sec=0.02)

    def answer(self, stamp: int) -> EpisodeStatus:
        """The episode_status answering the action sent for the observation stamped `stamp`."""

        def answered() -> EpisodeStatus | None:
            return next((status for status in self.statuses if stamp_ns(status.action_stamp) == stamp), None)

        self.wait(lambda: answered() is not None, "episode_status")
        return answered()

    def check(self, state: list[float], step: int) -> None:
        if not np.allclose(np.asarray(state), self.env.state_vector(), atol=1e-4):
            raise OutOfStep(f"step {step}: the simulator's state differs from the operator's copy")

    def reset(self, seed: int) -> ResetEpisode.Response:
        self.wait(self.reset_client.service_is_ready, "reset service")
        future = self.reset_client.call_async(ResetEpisode.Request(seed=seed))
        self.wait(future.done, "reset answer")
        return future.result()

    def take(self, seed: int) -> tuple[float, float, list[int]] | None:
        """One take: (start, end) wall seconds and its subtask ends, or None when it failed."""
        start = time.time()
        answer = self.reset(seed)
        self.env.reset(seed=seed)
        self.expert.reset(seed=seed)
        self.check(answer.state, 0)
        stamp, progress, held, paused = stamp_ns(answer.header.stamp), [0], [False], 0
        success = truncated = False
        while not (success or truncated):
            if paused == 0 and self.rng.random() < self.pause:
                paused = int(self.rng.integers(2, 7))  # a person stops to look for half a second or so
            # what the simulator steps with: the message carries float32
            action = (np.zeros(3) if paused else self.expert.act(self.env)).astype(np.float32).astype(np.float64)
            paused = max(paused - 1, 0)
            self.statuses.clear()
            msg = Action(values=action.tolist())
            msg.header.stamp = ns_stamp(stamp)  # lockstep: the observation it answers
            self.actions.publish(msg)
            status = self.answer(stamp)
            _, _, _, truncated, info = self.env.step(action)
            self.check(status.state, len(progress))
            success, stamp = info["is_success"], stamp_ns(status.header.stamp)
            progress.append(self.env.progress)
            held.append(self.env.holds_current_block)
        if not success:
            return None
        _, ends = subtask_labels(np.array(progress), np.array(held), 3)
        return start, time.time(), ends.tolist()


def main(argv: list[str] | None = None) -> int:
    parser = OneLineParser(prog="inest-teleop-standin", description=__doc__.split("\n")[0])
    parser.add_argument("--episodes", type=int, default=50, help="takes to keep")
    parser.add_argument("--seed", type=int, default=0, help="layout seed of the first take")
    parser.add_argument("--namespace", default="sim0")
    parser.add_argument("--max-steps", type=int, default=150, help="the simulator node's max_steps")
    parser.add_argument("--noise", type=float, default=0.15, help="std of the operator's speed and turn noise")
    parser.add_argument("--pause", type=float, default=0.03, help="chance per step of stopping for 2-6 steps")
    parser.add_argument("--gap", type=float, default=1.0, help="seconds between takes")
    parser.add_argument("--times", type=Path, required=True, help="the episode times file to write")
    parser.add_argument("--ends", type=Path, required=True, help="the true subtask ends file to write")
    args = parser.parse_args(remove_ros_args(sys.argv)[1:] if argv is None else argv)
    rclpy.init()
    node = rclpy.create_node("inest_teleop_standin")
    operator = TeleopStandIn(
        node, args.namespace, args.max_steps, args.noise, args.pause, np.random.default_rng(args.seed)
    )
    times, ends, seed = ["episode,start,end"], ["episode,subtask,frame"], args.seed
    try:
        # a layout never kept first: a simulator whose first episode already shows seed `--seed`
        # answers that reset without publishing its first frame again, before the take began
        operator.reset(SETTLE_SEED)
        time.sleep(args.gap)  # its frame reaches the recorder before the first take starts
        while len(times) <= args.episodes:
            take = operator.take(seed)
            seed += 1
            if take is not None:
                name = f"take_{len(times) - 1:03d}"
                times.append(f"{name},{take[0]:.3f},{take[1] + args.gap / 2:.3f}")
                ends += [f"{name},{subtask},{frame}" for subtask, frame in enumerate(take[2])]
                print(f"{name}: seed {seed - 1}, {take[2][-1] + 1} frames", flush=True)
            time.sleep(args.gap)
    except OutOfStep as error:
        print(f"inest-teleop-standin: error: {error}", file=sys.stderr)
        return 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
        args.times.write_text("\n".join(times) + "\n")
        args.ends.write_text("\n".join(ends) + "\n")
    print(f"kept {len(times) - 1} takes (seeds {args.seed}..{seed - 1}); times in {args.times}, ends in {args.ends}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
