"""Vectorised training environments whose reward comes from a RewardFunction (rewards.py: a
learned reward model or the simulator's own), and the policy's stage observation on top of any
vector env.

A learned reward is computed from each environment's camera frame after the step (the
transition's next frame, including the last frame of an episode, which auto-reset would
otherwise replace), all N frames in one encoder forward pass. Every step's infos carry the same
keys whoever computed the reward (these envs or the graph's): TRUE_PROGRESS, LEARNED_STAGE (the
reward's stage: the true progress for the environment's reward) and the reward's parts, under
the info keys of reward_parts.PARTS.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import gymnasium
import numpy as np
from inest_reward_node.learning.task_stages import privileged_stages
from inest_reward_node.runtime.reward_parts import LEARNED_STAGE, RewardParts, info_items
from inest_reward_node.runtime.rewards import RewardFunction, Steps
from inest_sim_node.observation import stage_observation, stage_observation_space
from stable_baselines3.common.vec_env import DummyVecEnv, VecEnv, VecEnvWrapper

from inest_sim_node import EnvConfig, SweepToTopEnv

from .config import TrainConfig
from .rewards import build_reward

FRAME_KEY = "camera_frame"
STAGE_FRAME_KEY = "stage_camera_frame"  # the stage head's camera, when it is not the encoder's
TRUE_PROGRESS = "progress"  # blocks placed in order (the simulator's, 0..3)


class CameraFrameInInfo(gymnasium.Wrapper):
    """Puts the camera frame the learned reward scores into `info`, so it survives auto-reset,
    and the stage head's camera frame too when it reads another camera (`stage_view`)."""

    def __init__(self, env: SweepToTopEnv, view: str, size: int, stage_view: str | None = None) -> None:
        super().__init__(env)
        self.view, self.size, self.stage_view = view, size, stage_view

    def step(self, action: np.ndarray) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        observation, reward, terminated, truncated, info = self.env.step(action)
        info[FRAME_KEY] = self.env.unwrapped.render_camera(self.view, self.size)
        if self.stage_view is not None:
            info[STAGE_FRAME_KEY] = self.env.unwrapped.render_camera(self.stage_view, self.size)
        return observation, reward, terminated, truncated, info


def make_vec_env(
    num_envs: int,
    env_config: EnvConfig,
    seed: int,
    frames: tuple[str, int] | None = None,
    stage_view: str | None = None,
) -> VecEnv:
    """N in-process environments on seeds seed, seed + 1, ...; `frames` = (view, size) adds camera
    frames, `stage_view` those of a second camera for the stage head."""

    def make() -> gymnasium.Env:
        env = SweepToTopEnv(config=env_config)
        return CameraFrameInInfo(env, *frames, stage_view) if frames else env

    venv = DummyVecEnv([make] * num_envs)
    venv.seed(seed)  # the first reset of environment i uses seed + i
    return venv


@dataclass
class WaitingStep:
    """One vector step whose frames are not scored yet."""

    frames: np.ndarray  # (N, H, W, 3)
    stage_frames: np.ndarray | None  # (N, H, W, 3) of the stage head's camera, when it is another
    states: np.ndarray  # (N, state_dim), the transition's next states (terminal ones at episode ends)
    dones: np.ndarray  # (N,)
    env_rewards: np.ndarray  # (N,) the environments' own rewards
    infos: list[dict[str, Any]]


class RewardVecEnv(VecEnvWrapper):
    """Replaces the environments' reward by a RewardFunction's; the oracle stays in info["env_reward"].

    With `batch_steps` > 1 the frames of that many vector steps are scored together: one encoder
    pass over batch_steps x N frames costs about 40 % less per frame on 2 cores than N at a time,
    and the novelty memories are searched once; the rewards are those of scoring every step
    (RewardScorer.score with rounds). step() then returns NaN rewards (a reward that
    is not known yet must not be trained on) and the learned ones come out of take_rewards() in
    step order, for an algorithm that holds each transition until its reward is known
    (learners.RewardBatchingMixin), which says so with `accept_deferred_rewards()`; stepping
    without it raises instead of handing anyone NaN rewards. The subtask and intrinsic entries
    of a step's infos are filled in when it is scored.
    """

    def __init__(self, venv: VecEnv, reward: RewardFunction, record_every: int = 10, batch_steps: int = 1) -> None:
        super().__init__(venv)
        if reward.num_envs != venv.num_envs:
            raise ValueError(f"the reward tracks {reward.num_envs} environments, the vector env has {venv.num_envs}")
        if batch_steps < 1:
            raise ValueError(f"batch_steps must be at least 1, got {batch_steps}")
        self.reward = reward
        self.record_every = record_every
        self.batch_steps = batch_steps
        self.steps = 0  # vector steps scored
        self.visited: list[np.ndarray] = []  # every `record_every`-th vector step's embeddings, for coverage
        self.waiting: list[WaitingStep] = []
        self.scored: deque[np.ndarray] = deque()  # learned rewards not yet taken, oldest first
        self.deferred_rewards_accepted = False
        # called with the scored rows' Steps and RewardParts after each scoring
        self.scored_hook: Callable[[Steps, RewardParts], None] | None = None

    def accept_deferred_rewards(self) -> None:
        """Called by the one consumer that holds transitions until take_rewards() (RewardBatchingMixin)."""
        self.deferred_rewards_accepted = True

    def exploration_state(self) -> dict[str, np.ndarray]:
        """The reward's novelty memories and the coverage record: what a resumed run must not forget."""
        state = self.reward.exploration_state()
        if self.visited:
            state["visited"] = np.concatenate(self.visited)
        return state

    def restore_exploration(self, state: dict[str, np.ndarray]) -> None:
        self.reward.restore_exploration({key: value for key, value in state.items() if key != "visited"})
        self.visited = [state["visited"]] if "visited" in state else []

    def reset(self) -> np.ndarray:
        self.score_waiting()  # frames of the episodes being cut off still earn their rewards
        self.reward.reset()
        return self.venv.reset()

    def step_async(self, actions: np.ndarray) -> None:
        if self.batch_steps > 1 and not self.deferred_rewards_accepted:
            raise RuntimeError(
                f"RewardVecEnv(batch_steps={self.batch_steps}) returns NaN until a batch is scored: "
                "only a reward-batching learner (learners.RewardBatchingMixin) may step it; use batch_steps=1"
            )
        self.venv.step_async(actions)

    def step_wait(self):
        observations, env_rewards, dones, infos = self.venv.step_wait()
        frames = np.stack([info.pop(FRAME_KEY) for info in infos]) if FRAME_KEY in infos[0] else None
        stage_frames = np.stack([info.pop(STAGE_FRAME_KEY) for info in infos]) if STAGE_FRAME_KEY in infos[0] else None
        states = np.stack(
            [info.get("terminal_observation", obs) for info, obs in zip(infos, observations, strict=True)]
        )
        for index, info in enumerate(infos):
            info["env_reward"] = float(env_rewards[index])
        self.waiting.append(WaitingStep(frames, stage_frames, states, dones.copy(), env_rewards.copy(), infos))
        if len(self.waiting) >= self.batch_steps:
            self.score_waiting()
        if self.batch_steps == 1:
            return observations, self.scored.popleft(), dones, infos
        return observations, np.full(self.num_envs, np.nan, dtype=np.float32), dones, infos

    def score_waiting(self) -> None:
        """Score every waiting step: one encoder pass and one novelty search for all of them."""
        if not self.waiting:
            return
        count, waiting, reward = self.num_envs, self.waiting, self.reward
        states = np.concatenate([step.states for step in waiting])
        envs, ends = np.tile(np.arange(count), len(waiting)), np.concatenate([step.dones for step in waiting])
        steps = Steps(
            envs=envs,
            rounds=np.repeat(np.arange(len(waiting)), count),
            episode_ends=ends,
            states=states,
            known_stages=privileged_stages(states, reward.num_subtasks) if reward.needs_known_stages else None,
            env_rewards=np.concatenate([step.env_rewards for step in waiting]),
        )
        scored = reward.score(
            None if reward.camera is None else np.concatenate([step.frames for step in waiting]),
            None if reward.stage_camera is None else np.concatenate([step.stage_frames for step in waiting]),
            steps,
        )
        if self.scored_hook is not None:
            self.scored_hook(steps, scored)
        for position, step in enumerate(waiting):
            parts = scored.select(slice(position * count, (position + 1) * count))
            if self.steps % self.record_every == 0 and parts.embeddings.shape[1]:
                self.visited.append(parts.embeddings)
            self.steps += 1
            for index, info in enumerate(step.infos):
                info.update(info_items(parts.row(index)))
            self.scored.append(parts.total.astype(np.float32))
        self.waiting.clear()

    def take_rewards(self, at_most: int) -> list[np.ndarray]:
        """Up to `at_most` learned rewards not taken yet, one (N,) array per vector step, oldest first."""
        return [self.scored.popleft() for _ in range(min(at_most, len(self.scored)))]


class StageObservationVecEnv(VecEnvWrapper):
    """Appends the reward's stage (one-hot of `infos[LEARNED_STAGE]`) and the stage block's offsets
    in the robot frame to every state observation (observation.stage_observation), on what a
    robot senses (`sensed_only`) or on the whole simulator state.

    A stage is known only once the step's reward is: the wrapped env must fill LEARNED_STAGE in
    every step's infos (a RewardVecEnv scoring each step as it happens, or the graph's rewards;
    for the environment's reward it is the simulator's true progress). Episodes start in stage 0.
    """

    def __init__(self, venv: VecEnv, num_subtasks: int, sensed_only: bool = True) -> None:
        space = stage_observation_space(venv.observation_space, num_subtasks, sensed_only)
        super().__init__(venv, observation_space=space)
        self.num_subtasks, self.sensed_only = num_subtasks, sensed_only

    def observe(self, states: np.ndarray, stages: np.ndarray) -> np.ndarray:
        return stage_observation(states, stages, self.num_subtasks, self.sensed_only)

    def reset(self) -> np.ndarray:
        observations = self.venv.reset()
        return self.observe(observations, np.zeros(len(observations), int))

    def step_wait(self):
        observations, rewards, dones, infos = self.venv.step_wait()
        if LEARNED_STAGE not in infos[0]:
            raise RuntimeError(
                f"the stage observation needs infos[{LEARNED_STAGE!r}] after every step "
                "(a learned reward scored several steps at once has none yet: use reward_batch_steps 1)"
            )
        stages = np.array([info[LEARNED_STAGE] for info in infos], dtype=int)
        for index in np.flatnonzero(dones):
            terminal = infos[index]["terminal_observation"]
            infos[index]["terminal_observation"] = self.observe(terminal, stages[index])[0]
            stages[index] = 0  # the observation returned is the next episode's first
        return self.observe(observations, stages), rewards, dones, infos


class UpdateThread:
    """Runs an overlapped learner's deferred updates (learners.OverlappedUpdatesMixin) on a second
    thread while the environments step: on two cores the update (XLA or torch kernels, which
    release the GIL) gets one and the simulation, the reward and the messages the other. It is
    joined before the step returns, and the step neither reads the policy nor writes the replay
    buffer, so the two never touch the same state; an error in an update is raised from the join."""

    def __init__(self) -> None:
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="inest-updates")
        self._running: Future | None = None

    def start(self, work: Callable[[], None] | None) -> None:
        self.join()  # one update at a time, and none of its errors lost
        if work is not None:
            self._running = self._pool.submit(work)

    def join(self) -> None:
        running, self._running = self._running, None
        if running is not None:
            running.result()

    def close(self) -> None:
        self._pool.shutdown()


class ConcurrentUpdatesVecEnv(VecEnvWrapper):
    """In-process environments that run `while_waiting` on an UpdateThread while they step and score."""

    def __init__(self, venv: VecEnv) -> None:
        super().__init__(venv)
        self.while_waiting: Callable[[], None] | None = None
        self.updates = UpdateThread()

    def reset(self) -> np.ndarray:
        return self.venv.reset()

    def step_async(self, actions: np.ndarray) -> None:
        self.updates.start(self.while_waiting)
        self.venv.step_async(actions)

    def step_wait(self):
        try:
            return self.venv.step_wait()
        finally:
            self.updates.join()

    def close(self) -> None:
        self.updates.close()
        self.venv.close()


def build_env(
    config: TrainConfig,
    num_envs: int | None = None,
    seed: int | None = None,
    evaluation: bool = False,
    wrap_simulators: Callable[[VecEnv], VecEnv] | None = None,
) -> VecEnv:
    """The vector env `config` trains on: in-process simulators, its reward (rewards.build_reward),
    the stage observation. `evaluation`: the same observation path, without the intrinsic bonus
    (its memories belong to training) and with the reward node's model for the topic reward.
    `wrap_simulators` wraps the simulators' vector env, whose infos still hold the camera frames
    of a learned reward (FRAME_KEY), before anything else sees it."""
    wrap_simulators = wrap_simulators or (lambda venv: venv)
    num_envs = num_envs or config.num_envs
    seed = config.seed if seed is None else seed
    reward = build_reward(config, num_envs, evaluation)
    frames = None if reward.camera is None else (reward.camera, reward.image_size)
    env_config = EnvConfig(view=config.view, reward=config.oracle)
    venv = wrap_simulators(make_vec_env(num_envs, env_config, seed, frames, reward.stage_camera))
    batch_steps = 1 if evaluation else config.reward_batch_steps
    return with_observation(
        RewardVecEnv(venv, reward, batch_steps=batch_steps), config.observation, config.stage_subtasks
    )


def with_observation(venv: VecEnv, observation: str, stage_subtasks: int) -> VecEnv:
    """The policy's observation (observation.STATE_OBSERVATIONS) on simulators' state vectors,
    with the stage of a reward of `stage_subtasks` subtasks."""
    if observation == "state":
        return venv
    return StageObservationVecEnv(venv, stage_subtasks, sensed_only=observation == "robot")
