"""A stable-baselines3 VecEnv whose environments are simulators (and a reward node) on ROS 2 topics.

Environment i lives under namespace `namespaces[i]`: it publishes `action`, and waits for the
`episode_status` answering that action (which carries the new state), then the `reward` stamped
like it (see pairing.py). Resets go through the simulator's `reset` and the reward node's `reset_reward`
services. When something stays silent for `timeout` seconds, it logs which topic of which
simulator, re-sends the action (a lockstep simulator re-publishes a step it already took) and
keeps waiting. A restarted simulator (its clock starts over, so it ignores the action) shows up
as a new publisher of its `episode_status`; a restarted reward node, whose trackers start over,
as a reward whose `episode_frame` counts from 1 again in the middle of an episode. Either way
the environment is reset, the restart logged, and its step in flight comes back as a broken one
(BROKEN_STEP in its info, the episode truncated) that the learner does not store: the run
goes on, and no step is learned from a subtask the reward forgot.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any

import numpy as np
from inest_common.rosutil import namespaced, new_executor, ns_stamp, stamp_ns
from inest_interfaces.msg import Action, EpisodeStatus, Reward
from inest_interfaces.srv import ResetEpisode
from inest_reward_node.runtime.reward_parts import LEARNED_STAGE, info_items, message_parts
from inest_sim_node.config import EnvConfig
from inest_sim_node.env import action_space, observation_space
from rclpy.node import Node
from rclpy.qos import QoSProfile
from stable_baselines3.common.vec_env import VecEnv
from std_srvs.srv import Trigger

from .envs import TRUE_PROGRESS, UpdateThread
from .learners import BROKEN_STEP
from .pairing import REWARD, STATUS, StepMailbox


class GraphVecEnv(VecEnv):
    def __init__(self, node: Node, namespaces: list[str], learned_reward: bool = True, timeout: float = 5.0) -> None:
        super().__init__(len(namespaces), observation_space(EnvConfig()), action_space())
        self.node, self.namespaces, self.learned_reward, self.timeout = node, namespaces, learned_reward, timeout
        self.executor = new_executor()
        self.executor.add_node(node)
        qos = QoSProfile(depth=10)
        self.mailboxes = [StepMailbox(learned_reward) for _ in namespaces]
        self.action_pubs, self.sim_resets, self.reward_resets, self.status_subs = [], [], [], []
        for index, namespace in enumerate(namespaces):
            self.action_pubs.append(node.create_publisher(Action, namespaced(namespace, "action"), qos))
            self.status_subs.append(
                node.create_subscription(
                    EpisodeStatus, namespaced(namespace, "episode_status"), lambda m, i=index: self.on_status(i, m), qos
                )
            )
            self.sim_resets.append(node.create_client(ResetEpisode, namespaced(namespace, "reset")))
            if learned_reward:
                node.create_subscription(
                    Reward, namespaced(namespace, "reward"), lambda m, i=index: self.on_reward(i, m), qos
                )
                self.reward_resets.append(node.create_client(Trigger, namespaced(namespace, "reset_reward")))
        self.while_waiting: Callable[[], None] | None = None  # work for an UpdateThread while the step runs
        self.updates = UpdateThread()
        self.stamps = np.zeros(self.num_envs, dtype=np.int64)  # each environment's current observation
        self.actions = np.zeros((self.num_envs, 3), dtype=np.float32)
        self.observations = np.zeros((self.num_envs, *self.observation_space.shape), dtype=np.float32)
        self.last_infos: list[dict[str, Any]] = [{} for _ in namespaces]  # each environment's latest step
        self.simulators: list[set[tuple[int, ...]]] = [set() for _ in namespaces]  # status publishers known
        self.episode_frames = np.zeros(self.num_envs, dtype=np.int64)  # the reward's count at the last step

    # --- message intake ------------------------------------------------------------
    def on_status(self, index: int, msg: EpisodeStatus) -> None:
        self.mailboxes[index].put_status(stamp_ns(msg.action_stamp), stamp_ns(msg.header.stamp), msg)

    def on_reward(self, index: int, msg: Reward) -> None:
        self.mailboxes[index].put(REWARD, stamp_ns(msg.header.stamp), msg)

    # --- waiting without ever giving up ----------------------------------------------
    def wait_until(self, ready, describe, resend=None) -> None:
        """Spin until `ready()`; every `timeout` seconds log `describe()` and call `resend()`."""
        deadline = time.monotonic() + self.timeout
        while not ready():
            self.executor.spin_once(timeout_sec=0.05)
            if time.monotonic() > deadline:
                self.node.get_logger().warning(f"still waiting after {self.timeout:.0f} s: {describe()}")
                if resend is not None:
                    resend()
                deadline = time.monotonic() + self.timeout

    def call(self, client, request, what: str, ask_again=lambda: False):
        """The service's answer; on a timeout, the request goes out again if `ask_again()` (the
        server restarted: the new one never saw it)."""
        self.wait_until(client.service_is_ready, lambda: f"service {client.srv_name} ({what}) is not available")
        futures = [client.call_async(request)]

        def retry() -> None:
            if ask_again():
                futures.append(client.call_async(request))

        self.wait_until(
            lambda: any(f.done() for f in futures), lambda: f"no answer from {client.srv_name} ({what})", retry
        )
        return next(f for f in futures if f.done()).result()

    # --- VecEnv --------------------------------------------------------------------------
    def reset_env(self, index: int, seed: int | None) -> np.ndarray:
        if self.learned_reward:
            # asked again on every timeout: a reward node killed mid-call never answers, its successor
            # never saw the request, and a second reset before the episode's first frame changes nothing
            self.call(self.reward_resets[index], Trigger.Request(), "reward tracker reset", lambda: True)
        request = ResetEpisode.Request(seed=-1 if seed is None else seed)
        response = self.call(self.sim_resets[index], request, "reset", lambda: self.restarted(index))
        if not response.success:
            raise RuntimeError(f"{self.namespaces[index] or 'simulator'} refused to reset: {response.message}")
        stamp = stamp_ns(response.header.stamp)
        if stamp <= self.stamps[index]:  # the clock went back: a new simulator process, whose stamps repeat old ones
            self.mailboxes[index] = StepMailbox(self.learned_reward)
        self.stamps[index] = stamp
        self.mailboxes[index].forget_before(stamp)
        self.simulators[index] = self.status_publishers(index)
        self.episode_frames[index] = 0
        self.observations[index] = response.state
        self.last_infos[index] = self.step_info(EpisodeStatus(), Reward())  # stage 0, nothing scored yet
        return self.observations[index].copy()

    def status_publishers(self, index: int) -> set[tuple[int, ...]]:
        """The publishers of this environment's episode status now (one per simulator process)."""
        topic = self.status_subs[index].topic_name
        return {tuple(info.endpoint_gid) for info in self.node.get_publishers_info_by_topic(topic)}

    def restarted(self, index: int) -> bool:
        """A simulator process this environment has not been reset with publishes its status: the
        simulator was restarted (the dead one stays listed for a while, so only a new one counts)."""
        return bool(self.status_publishers(index) - self.simulators[index])

    def step_info(self, status: EpisodeStatus, reward: Reward) -> dict[str, Any]:
        """A step's info: the simulator's reward and score, and the learned reward's stage and parts."""
        progress = status.blocks_in_order
        info: dict[str, Any] = {"env_reward": status.env_reward, "score": status.score, TRUE_PROGRESS: progress}
        if self.learned_reward:
            info.update(info_items(message_parts(reward)))
        else:  # the environment's reward: its stage is the true progress
            info[LEARNED_STAGE] = progress
        return info

    def reset(self) -> np.ndarray:
        observations = np.stack([self.reset_env(i, self._seeds[i]) for i in range(self.num_envs)])
        self._reset_seeds()
        self._reset_options()
        return observations

    def publish_action(self, index: int) -> None:
        msg = Action(values=self.actions[index].tolist())
        msg.header.stamp = ns_stamp(int(self.stamps[index]))
        self.action_pubs[index].publish(msg)

    def step_async(self, actions: np.ndarray) -> None:
        self.actions = np.asarray(actions, dtype=np.float32).reshape(self.num_envs, -1)
        self.updates.start(self.while_waiting)  # the actions are chosen: the policy may change now
        for index in range(self.num_envs):
            self.publish_action(index)

    def step_wait(self):
        results: dict[int, tuple[int, dict[str, Any]]] = {}

        def collect() -> bool:
            for index in range(self.num_envs):
                if index not in results:
                    taken = self.mailboxes[index].take(int(self.stamps[index]))
                    if taken is not None:
                        results[index] = taken
            return len(results) == self.num_envs

        def silent() -> str:
            return "; ".join(
                f"{self.namespaces[i] or '/'}: {', '.join(self.mailboxes[i].missing(int(self.stamps[i])))}"
                for i in range(self.num_envs)
                if i not in results
            )

        broken: dict[int, dict[str, Any]] = {}  # steps not to learn from (a restarted node): their infos

        def resend() -> None:
            for index in range(self.num_envs):
                if index in results:
                    continue
                if self.restarted(index):
                    self.break_episode(index, "the simulator restarted", broken)
                    results[index] = (int(self.stamps[index]), {})
                else:
                    self.publish_action(index)

        try:  # the messages are taken as they come, while the update runs
            self.wait_until(collect, silent, resend)
        finally:
            self.updates.join()
        for index, (_, messages) in results.items():
            frame = messages.get(REWARD, Reward()).episode_frame
            if self.learned_reward and index not in broken and frame <= self.episode_frames[index]:
                self.break_episode(
                    index,
                    f"the reward node lost this episode's subtask progress (restarted? its tracker counts "
                    f"{frame} frames, {self.episode_frames[index]} were scored before)",
                    broken,
                )
        observations = np.zeros((self.num_envs, *self.observation_space.shape), dtype=np.float32)
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        infos: list[dict[str, Any]] = []
        for index in range(self.num_envs):
            if index in broken:  # already reset: the new episode's first observation
                observations[index], dones[index] = self.observations[index], True
                infos.append(broken[index])
                continue
            new_stamp, messages = results[index]
            reward = messages.get(REWARD, Reward())
            self.episode_frames[index] = reward.episode_frame
            status = messages[STATUS]
            observation = np.asarray(status.state, dtype=np.float32)
            if observation.shape != self.observation_space.shape:
                raise ValueError(
                    f"{self.namespaces[index] or '/'}: episode_status carries a state of {observation.size} values, "
                    f"expected {self.observation_space.shape[0]}"
                )
            rewards[index] = reward.total if self.learned_reward else status.env_reward
            info = self.step_info(status, reward)
            self.stamps[index], self.observations[index], self.last_infos[index] = new_stamp, observation, dict(info)
            dones[index] = status.truncated  # the task's episodes end at their time limit only
            if dones[index]:
                info["TimeLimit.truncated"] = True
                info["terminal_observation"] = observation
                observation = self.reset_env(index, None)
            observations[index] = observation
            infos.append(info)
        return observations, rewards, dones, infos

    def break_episode(self, index: int, why: str, broken: dict[int, dict[str, Any]]) -> None:
        """End environment `index`'s episode where it stands, its step in flight a broken one (not
        learned from), and reset it; logged with `why`."""
        self.node.get_logger().warning(f"{self.namespaces[index] or '/'}: {why}; resetting it (its step is dropped)")
        terminal = {"terminal_observation": self.observations[index].copy(), "TimeLimit.truncated": True}
        broken[index] = {**self.last_infos[index], **terminal, BROKEN_STEP: True}
        self.reset_env(index, None)

    def close(self) -> None:
        self.updates.close()
        self.executor.shutdown()

    # --- the parts of the VecEnv interface that only in-process environments have ---------
    def get_attr(self, attr_name: str, indices=None) -> list[Any]:
        if attr_name == "render_mode":
            return [None] * self.num_envs
        raise AttributeError(f"simulators on the graph have no attribute {attr_name!r} to read")

    def set_attr(self, attr_name: str, value: Any, indices=None) -> None:
        raise AttributeError(f"cannot set {attr_name!r} on simulators over the graph")

    def env_method(self, method_name: str, *method_args, indices=None, **method_kwargs) -> list[Any]:
        raise AttributeError(f"cannot call {method_name!r} on simulators over the graph")

    def env_is_wrapped(self, wrapper_class, indices=None) -> list[bool]:
        return [False] * self.num_envs
