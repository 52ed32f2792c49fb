"""Selectable off-policy learners: every one trains, saves, loads and acts the same; the two mixins.

Small on purpose: 32-unit networks and batch 32 on the real simulator. Each SBX learner pays
its JIT compilation once (first test that trains it); later tests reuse the compiled code.
"""

from __future__ import annotations

import inspect
import subprocess
import sys
from collections import deque

import numpy as np
import pytest
import torch
from inest_agent_node.learner_state import JAX_FILE, TORCH_FILE, load_learner_state, save_learner_state
from inest_agent_node.learners import (
    DROQ_POLICY_KWARGS,
    LEARNERS,
    OverlappedUpdatesMixin,
    RewardBatchingMixin,
    build_learner_class,
    learner_class,
    learner_kwargs,
)
from inest_agent_node.replay_store import load_replay_buffer, save_replay_buffer
from stable_baselines3 import SAC
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper

from inest_agent_node.config import SacConfig
from inest_sim_node import EnvConfig, SweepToTopEnv

NAMES = tuple(LEARNERS)
TINY = SacConfig(learning_starts=50, batch_size=32, buffer_size=5_000, gradient_steps=1, net_arch=(32, 32))


@pytest.fixture(autouse=True)
def one_torch_thread():
    """32-unit networks gain nothing from a second thread, and lose a lot when other work shares the cores."""
    previous = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(previous)


def tiny_env(seed: int = 0) -> VecEnv:
    return make_vec_env(SweepToTopEnv, n_envs=1, seed=seed, env_kwargs={"config": EnvConfig(max_steps=50)})


def tiny_model(name: str, env: VecEnv, sac: SacConfig = TINY, seed: int = 0, **mixins: bool):
    kwargs = learner_kwargs(name, sac, critic_net_arch=[32, 32])  # CrossQ's 1024-wide critic is slow here
    return build_learner_class(name, **mixins)("MlpPolicy", env, seed=seed, verbose=0, **kwargs)


def probe_observations(env: VecEnv, count: int = 16) -> np.ndarray:
    rng = np.random.default_rng(1)
    low, high = env.observation_space.low, env.observation_space.high
    return rng.uniform(low, high, (count, *low.shape)).astype(np.float32)


def test_importing_learners_and_picking_a_torch_learner_does_not_import_jax(tmp_path):
    code = (
        "import sys\n"
        "from inest_agent_node.config import SacConfig\n"
        "from inest_agent_node.learners import LEARNERS, build_learner_class, learner_kwargs\n"
        "import inest_agent_node.learner_state, inest_agent_node.train\n"
        "build_learner_class('crossq', reward_batching=True)\n"
        "[learner_kwargs(name, SacConfig()) for name in LEARNERS]\n"
        "assert 'sac' in LEARNERS and 'jax' not in sys.modules and 'sbx' not in sys.modules\n"
    )
    subprocess.run([sys.executable, "-c", code], cwd=tmp_path, check=True, timeout=120)


def test_unknown_learner_names_the_known_ones():
    for call in (lambda: learner_class("ppo"), lambda: learner_kwargs("ppo", SacConfig())):
        with pytest.raises(ValueError, match=r"unknown learner 'ppo'; expected one of .*'sbx_droq'"):
            call()


@pytest.mark.parametrize("name", NAMES)
def test_learner_kwargs_are_keywords_the_learner_takes(name):
    kwargs = learner_kwargs(name, SacConfig())
    accepted = inspect.signature(learner_class(name).__init__).parameters
    assert set(kwargs) <= set(accepted)
    assert kwargs["learning_rate"] == SacConfig.learning_rate and kwargs["batch_size"] == SacConfig.batch_size
    policy_kwargs = kwargs["policy_kwargs"]
    if "crossq" in name:
        assert "tau" not in kwargs and "tau" not in accepted  # no target network
        assert policy_kwargs["net_arch"] == {"pi": [256, 256], "qf": [1024, 1024]}
    else:
        assert kwargs["tau"] == SacConfig.tau and policy_kwargs["net_arch"] == [256, 256]
    if name == "sbx_droq":
        assert policy_kwargs["dropout_rate"] > 0 and policy_kwargs["layer_norm"] is True


def test_one_class_per_combination_with_readable_names():
    assert build_learner_class("sac") is SAC
    overlapped = build_learner_class("sac", overlap_updates=True)
    assert overlapped is build_learner_class("sac", True) and overlapped.__name__ == "OverlappedSAC"
    assert issubclass(overlapped, SAC) and issubclass(overlapped, OverlappedUpdatesMixin)
    both = build_learner_class("sbx_sac", overlap_updates=True, reward_batching=True)
    assert both.__name__ == "OverlappedRewardBatchingSbxSAC"
    assert issubclass(both, learner_class("sbx_sac")) and issubclass(both, RewardBatchingMixin)
    assert build_learner_class("sbx_crossq", overlap_updates=True).__name__ == "OverlappedSbxCrossQ"


@pytest.mark.parametrize("name", NAMES)
def test_trains_saves_loads_and_acts_the_same_with_overlapped_updates(name, tmp_path):
    # one test for both: an SBX learner compiles its update again for every new model (~5-20 s here)
    env = tiny_env()
    model = tiny_model(name, env, overlap_updates=True)
    model.learn(100)
    assert model._n_updates == 0  # every train() call was only recorded
    assert [tuple(update) for update in model.pending_updates] == [(1, TINY.batch_size)] * 50
    model.run_pending_updates()
    assert model._n_updates == 50 and not model.pending_updates  # one update per step after learning_starts
    observations = probe_observations(env)
    actions, _ = model.predict(observations, deterministic=True)
    assert actions.shape == (len(observations), 3) and np.abs(actions).max() <= 1
    np.testing.assert_array_equal(model.predict(observations, deterministic=True)[0], actions)
    model.train(1, TINY.batch_size)  # an update still owed, as when a checkpoint falls between the two
    (tmp_path / "saved").mkdir()
    files = save_learner_state(model, name, tmp_path / "saved")
    save_replay_buffer(model.replay_buffer, tmp_path / "replay_buffer.npz")
    model.run_pending_updates()

    loaded = tiny_model(name, tiny_env(seed=5), seed=5, overlap_updates=True)  # other weights until loaded
    load_learner_state(loaded, name, tmp_path / "saved")
    load_replay_buffer(loaded.replay_buffer, tmp_path / "replay_buffer.npz")
    assert loaded.num_timesteps == 100 and loaded._n_updates == 50 and loaded.pending_updates == [(1, 32)]
    (tmp_path / "again").mkdir()
    save_learner_state(loaded, name, tmp_path / "again")  # every weight and optimiser moment came back
    arrays = JAX_FILE if name.startswith("sbx") else TORCH_FILE
    assert arrays in files and (tmp_path / "again" / arrays).read_bytes() == (tmp_path / "saved" / arrays).read_bytes()
    np.testing.assert_allclose(loaded.predict(observations, deterministic=True)[0], actions, atol=1e-6)
    assert loaded.replay_buffer.size() == model.replay_buffer.size() == 100
    np.testing.assert_array_equal(loaded.replay_buffer.observations, model.replay_buffer.observations)
    np.testing.assert_array_equal(loaded.replay_buffer.rewards, model.replay_buffer.rewards)
    if name == "sbx_droq":
        assert loaded.policy.dropout_rate == DROQ_POLICY_KWARGS["dropout_rate"] and loaded.policy.layer_norm
    loaded.learn(10, reset_num_timesteps=False)  # resumes like Trainer --resume, the owed update first
    loaded.run_pending_updates()
    assert loaded.num_timesteps == 110 and loaded._n_updates == 61


@pytest.mark.parametrize("name", ["sac", "sbx_sac"])
def test_same_seed_same_policy(name):
    observations = probe_observations(tiny_env())
    actions = []
    for _ in range(2):
        model = tiny_model(name, tiny_env(seed=3), seed=3)
        model.learn(60)
        actions.append(model.predict(observations, deterministic=True)[0])
    np.testing.assert_allclose(actions[0], actions[1], atol=1e-6)


class LateRewards(VecEnvWrapper):
    """Stands in for RewardVecEnv with batch_steps: NaN rewards from step(), the real ones
    once `batch_steps` steps have gathered (take_rewards), or at once with score_waiting()."""

    def __init__(self, venv: VecEnv, batch_steps: int) -> None:
        super().__init__(venv)
        self.batch_steps = batch_steps
        self.waiting: list[np.ndarray] = []
        self.scored: deque[np.ndarray] = deque()
        self.true_rewards: list[np.ndarray] = []

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        observations, rewards, dones, infos = self.venv.step_wait()
        rewards = rewards + 1.0  # distinguishable from zeros
        self.true_rewards.append(rewards)
        self.waiting.append(rewards)
        if len(self.waiting) >= self.batch_steps:
            self.score_waiting()
        return observations, np.full_like(rewards, np.nan), dones, infos

    def score_waiting(self) -> None:
        self.scored.extend(self.waiting)
        self.waiting.clear()

    def take_rewards(self, at_most: int) -> list[np.ndarray]:
        return [self.scored.popleft() for _ in range(min(at_most, len(self.scored)))]

    def accept_deferred_rewards(self) -> None:
        self.accepted = True  # the learner promised to hold transitions back


@pytest.mark.parametrize("name", NAMES)
def test_reward_batching_stores_a_transition_once_its_reward_is_known(name, tmp_path):
    env = LateRewards(tiny_env(), batch_steps=4)
    no_updates = SacConfig(learning_starts=10_000, buffer_size=100, net_arch=(32, 32))
    model = tiny_model(name, env, no_updates, reward_batching=True)
    assert env.accepted
    model.learn(10)
    buffer = model.replay_buffer
    assert buffer.size() == 8 and len(model.held_transitions) == 2  # steps 9 and 10 wait for their batch
    np.testing.assert_array_equal(buffer.rewards[:8, 0], np.concatenate(env.true_rewards[:8]))
    save_learner_state(model, name, tmp_path)  # held transitions are not part of the learner's state
    model.settle_rewards()
    assert buffer.size() == 10 and not model.held_transitions
    np.testing.assert_array_equal(buffer.rewards[:10, 0], np.concatenate(env.true_rewards))
    assert not np.isnan(buffer.rewards[:10]).any()
    loaded = tiny_model(name, env, no_updates, reward_batching=True)
    load_learner_state(loaded, name, tmp_path)
    assert loaded.held_transitions == deque() and loaded.num_timesteps == 10


def test_configure_jax_threads_sizes_the_xla_pool_before_the_backend_starts(tmp_path):
    code = (
        "import os, warnings\n"
        "from inest_agent_node.learners import configure_jax_threads\n"
        "configure_jax_threads(1)\n"
        "import jax, jax.numpy as jnp\n"
        "jnp.ones((64, 64)).sum().block_until_ready()\n"
        "names = [open(f'/proc/self/task/{t}/comm').read().strip() for t in os.listdir('/proc/self/task')]\n"
        "assert names.count('tf_XLAEigen') == 1, names\n"
        "with warnings.catch_warnings(record=True) as caught:\n"
        "    warnings.simplefilter('always')\n"
        "    configure_jax_threads(2)\n"
        "assert any('already started' in str(w.message) for w in caught), caught\n"
    )
    subprocess.run([sys.executable, "-c", code], cwd=tmp_path, check=True, timeout=120)
