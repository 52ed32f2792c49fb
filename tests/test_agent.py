"""In-process SAC training: learned-reward environments, evaluation table, resumable runs, config."""

from __future__ import annotations

import dataclasses
import json

import numpy as np
import pytest
from inest_agent_node.envs import LEARNED_STAGE, RewardVecEnv, make_vec_env
from inest_agent_node.evaluate import evaluate, format_table
from inest_agent_node.learners import RewardBatchingMixin
from inest_agent_node.train import Trainer
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_reward_node.runtime.model import load_model
from inest_reward_node.runtime.rewards import RewardScorer
from inest_sim_node.expert import ScriptedExpert
from small_training import small_train_config
from stable_baselines3.common.vec_env import VecEnvWrapper

from inest_agent_node.config import SacConfig, TrainConfig
from inest_sim_node import EnvConfig


def test_evaluation_table_scores_the_expert_near_one_and_random_near_zero():
    expert = ScriptedExpert()

    def expert_policy(_observation, env):
        if env.elapsed_steps == 0:
            expert.reset(seed=0)
        return expert.act(env)

    rng = np.random.default_rng(0)
    expert_result = evaluate(expert_policy, episodes=20)
    random_result = evaluate(lambda _observation, _env: rng.uniform(-1, 1, 3), episodes=20)
    assert expert_result.mean_score >= 0.85 and expert_result.success_rate >= 0.8
    assert random_result.mean_score <= 0.1
    for result in (expert_result, random_result):
        assert sum(result.blocks_share) == pytest.approx(1.0)
    table = format_table({"expert": expert_result, "random": random_result})
    assert "expert" in table.splitlines()[1] and "random" in table.splitlines()[2]


def test_learned_reward_replaces_the_environment_reward(tiny_tcc_run):
    _, run_dir = tiny_tcc_run
    model = load_model(run_dir / "model")
    scorer = RewardScorer(model, 3, intrinsic=IntrinsicConfig(mode="embedding"), num_envs=2)
    env = RewardVecEnv(make_vec_env(2, EnvConfig(max_steps=20), seed=0, frames=("ego", 48)), scorer)
    env.reset()
    rng = np.random.default_rng(0)
    ends = 0
    for _ in range(25):
        _, rewards, dones, infos = env.step(rng.uniform(-1, 1, (2, 3)).astype(np.float32))
        assert rewards.shape == (2,) and rewards.dtype == np.float32
        assert all("env_reward" in info and "camera_frame" not in info for info in infos)
        assert not np.allclose(rewards, [info["env_reward"] for info in infos])
        ends += int(dones.sum())
        for index in np.flatnonzero(dones):
            assert scorer.trackers[index].completed == 0  # reset for the next episode
    assert ends == 2  # both 20-step episodes ended once
    assert sum(len(memory) for memory in scorer.memories) == 50  # memories kept across episode boundaries


def test_scoring_several_steps_at_once_gives_the_rewards_of_scoring_every_step(tiny_tcc_run):
    _, run_dir = tiny_tcc_run
    model = load_model(run_dir / "model")

    def learned_reward_env(batch_steps: int) -> RewardVecEnv:
        scorer = RewardScorer(model, 3, intrinsic=IntrinsicConfig(mode="embedding"), num_envs=2)
        venv = make_vec_env(2, EnvConfig(max_steps=20), seed=0, frames=("ego", 48))
        env = RewardVecEnv(venv, scorer, batch_steps=batch_steps)
        env.reset()
        return env

    every_step, batched = learned_reward_env(1), learned_reward_env(3)
    with pytest.raises(RuntimeError, match="only a reward-batching learner"):
        batched.step(np.zeros((2, 3), np.float32))  # nobody holds its NaN rewards back
    batched.accept_deferred_rewards()  # what learners.RewardBatchingMixin does
    rng = np.random.default_rng(0)
    expected = []
    for _ in range(25):  # the 20-step episodes end inside a batch
        actions = rng.uniform(-1, 1, (2, 3)).astype(np.float32)
        expected.append(every_step.step(actions)[1])
        _, rewards, _, infos = batched.step(actions)
        assert np.isnan(rewards).all()  # not known yet: nothing may train on it
    taken = batched.take_rewards(100)
    assert len(taken) == 24 and len(batched.waiting) == 1  # eight full batches of 3, one step waiting
    assert LEARNED_STAGE not in infos[0]
    batched.score_waiting()
    taken += batched.take_rewards(100)
    assert infos[0][LEARNED_STAGE] == every_step.reward.trackers[0].completed
    np.testing.assert_allclose(np.array(taken), np.array(expected), rtol=1e-4, atol=1e-5)
    for ours, reference in zip(batched.reward.memories, every_step.reward.memories, strict=True):
        np.testing.assert_allclose(ours.contents(), reference.contents(), rtol=1e-4, atol=1e-5)


def tiny_config(total_steps: int, observation: str = "stage") -> TrainConfig:
    return small_train_config(
        reward="env",
        observation=observation,
        total_steps=total_steps,
        final_eval_episodes=2,
        sac=SacConfig(learning_starts=100, buffer_size=5000, batch_size=32, net_arch=(32, 32)),
    )


def test_interrupted_training_resumes_with_its_step_counter_and_buffer(tmp_path):
    first = Trainer(tiny_config(400), tmp_path / "run", progress_bar=False)
    first.train()  # stands in for a run killed after its checkpoint at 400 steps
    checkpoint = tmp_path / "run" / "checkpoint"
    info = json.loads((checkpoint / "checkpoint.json").read_text())
    first_seconds = info["training_s"]
    assert first_seconds > 0 and info["steps"] == 400
    assert info["bytes"] == sum(path.stat().st_size for path in checkpoint.iterdir() if path.name != "checkpoint.json")
    assert not list(checkpoint.glob("*.pkl"))  # the replay buffer is plain arrays: loading it runs no code
    with pytest.raises(FileExistsError, match="--resume"):
        Trainer(tiny_config(600), tmp_path / "run", progress_bar=False)
    resumed = Trainer(tiny_config(600), tmp_path / "run", resume=True, progress_bar=False)
    assert resumed.model.num_timesteps == 400
    assert resumed.model.replay_buffer.size() == 200  # 400 steps of 2 environments
    assert len(resumed.history) == 2  # evaluations at 200 and 400
    result = resumed.train()
    assert resumed.model.num_timesteps == 600 and resumed.model.replay_buffer.size() == 300
    assert [point[0] for point in resumed.history] == [200, 400, 600]
    assert result.episodes == 2
    assert (tmp_path / "run" / "learning_curve.png").exists()
    wall_clock = json.loads((tmp_path / "run" / "results.json").read_text())["wall_clock_s"]
    assert wall_clock["training"] > round(first_seconds, 2)  # both sessions' training, counted once each
    assert wall_clock["final_evaluation"] > 0


def test_config_validation_and_yaml(tmp_path):
    with pytest.raises(ValueError, match="needs a reward model folder"):
        TrainConfig()
    with pytest.raises(ValueError, match="belongs to the inest reward"):
        TrainConfig(reward="xirl", model="m")
    path = tmp_path / "train.yaml"
    path.write_text("reward: env\nintrinsic: {mode: none}\nsac: {net_arch: [64, 64]}\n")
    assert TrainConfig.from_yaml(path).sac.net_arch == (64, 64)
    path.write_text("reward: env\nlearning_rate: 0.1\n")
    with pytest.raises(ValueError, match=r"unknown training setting\(s\) \['learning_rate'\]"):
        TrainConfig.from_yaml(path)


def test_resumed_inest_run_keeps_its_exploration_memories(tiny_tcc_run, tmp_path):
    _, reward_run = tiny_tcc_run
    config = small_train_config(
        reward="inest",
        model=str(reward_run / "model"),
        intrinsic=IntrinsicConfig(),  # the default bonus: its memories are what a resume must keep
        observation="state",  # the stage observation needs every step's reward at once
        reward_batch_steps=3,  # 100 vector steps: the checkpoint must store a transition still waiting
    )
    first = Trainer(config, tmp_path / "run", progress_bar=False)
    first.train()
    assert isinstance(first.model, RewardBatchingMixin) and not first.model.held_transitions
    sizes = [len(memory) for memory in first.reward_env.reward.memories]
    assert sum(sizes) == 200  # every frame of both environments went into a subtask memory
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    assert results["coverage"]["samples"] == 20  # every 10th vector step of 2 environments
    assert (tmp_path / "run" / "coverage.png").exists()
    resumed = Trainer(dataclasses.replace(config, total_steps=300), tmp_path / "run", resume=True, progress_bar=False)
    assert [len(memory) for memory in resumed.reward_env.reward.memories] == sizes
    assert resumed.model.replay_buffer.size() == 100  # every transition, none left waiting
    np.testing.assert_array_equal(
        resumed.reward_env.reward.memories[0].contents(), first.reward_env.reward.memories[0].contents()
    )


def test_held_transitions_reach_the_buffer_as_sac_would_store_them(tiny_tcc_run, tmp_path):
    _, reward_run = tiny_tcc_run
    buffers = {}
    for batch_steps in (1, 4):
        config = TrainConfig(
            reward="inest",
            model=str(reward_run / "model"),
            num_envs=2,
            observation="state",
            reward_batch_steps=batch_steps,
            sac=SacConfig(learning_starts=1000, buffer_size=1000, batch_size=16, net_arch=(16, 16)),
        )
        trainer = Trainer(config, tmp_path / f"batch{batch_steps}", progress_bar=False)
        trainer.model.learn(70)  # 35 vector steps of seeded random actions
        if batch_steps > 1:
            assert trainer.model.replay_buffer.size() == 32 and len(trainer.model.held_transitions) == 3
            trainer.model.settle_rewards()
        buffers[batch_steps] = trainer.model.replay_buffer
    assert buffers[4].size() == buffers[1].size() == 35
    for name in ("observations", "next_observations", "actions", "dones"):
        np.testing.assert_array_equal(getattr(buffers[4], name)[:35], getattr(buffers[1], name)[:35])
    np.testing.assert_allclose(buffers[4].rewards[:35], buffers[1].rewards[:35], rtol=1e-4, atol=1e-5)


def test_command_line_flags_override_the_config_file(tmp_path):
    from inest_agent_node.train import parse_args

    path = tmp_path / "train.yaml"
    path.write_text("reward: inest\nmodel: m\nintrinsic: {mode: embedding, k: 5}\nsac: {batch_size: 64}\n")
    config, _ = parse_args(["--out", "x", "--config", str(path), "--intrinsic", "state", "--total-steps", "1000"])
    assert (config.intrinsic.mode, config.intrinsic.k, config.total_steps) == ("state", 5, 1000)
    assert config.sac.batch_size == 64
    config, _ = parse_args(["--out", "x", "--config", str(path), "--gradient-steps", "1"])
    assert (config.sac.gradient_steps, config.sac.batch_size) == (1, 64)
    config, _ = parse_args(["--out", "x", "--config", str(path), "--confirm-steps", "1", "--stage-confidence", "0.8"])
    assert (config.learned_reward.confirm_steps, config.learned_reward.stage_confidence) == (1, 0.8)
    config, _ = parse_args(["--out", "x", "--config", str(path), "--instant-confidence", "0.95"])
    assert config.learned_reward.instant_confidence == 0.95
    filters = ["--stage-filter", "forward", "--filter-advance", "0.1", "--filter-temperature", "0.3"]
    config, _ = parse_args(["--out", "x", "--config", str(path), "--intrinsic-weight", "3", *filters])
    assert (config.intrinsic.mode, config.intrinsic.k, config.intrinsic.weight, config.intrinsic.boosted_weight) == (
        "embedding", 5, 3.0, 6.0,
    )  # fmt: skip
    filtering = config.learned_reward
    assert (filtering.stage_filter, filtering.filter_advance, filtering.filter_temperature) == ("forward", 0.1, 0.3)
    config, _ = parse_args(["--out", "x", "--config", str(path), "--reward", "env"])
    assert config.reward == "env" and config.intrinsic.mode == "none"
    path.write_text("num_envs: 2\n")  # a partial file: the model comes from the command line
    config, _ = parse_args(["--out", "x", "--config", str(path), "--reward", "xirl", "--model", "m"])
    assert (config.reward, config.model, config.num_envs, config.intrinsic.mode) == ("xirl", "m", 2, "none")


class UpdatesWhileStepping(VecEnvWrapper):
    """Stands in for the graph: runs `while_waiting` once the actions are out, recording what the
    replay buffer held at that moment."""

    def __init__(self, venv) -> None:
        super().__init__(venv)
        self.while_waiting = None
        self.buffer_sizes: list[int] = []
        self.model = None

    def reset(self):
        return self.venv.reset()

    def step_wait(self):
        if self.model.__dict__.get("pending_updates"):
            self.buffer_sizes.append(self.model.replay_buffer.size())
        if self.while_waiting is not None:
            self.while_waiting()
        return self.venv.step_wait()


def test_overlapped_updates_run_as_many_updates_on_the_same_transitions(tmp_path):
    config = tiny_config(300, observation="state")
    plain = Trainer(config, tmp_path / "plain", progress_bar=False)
    env = UpdatesWhileStepping(make_vec_env(config.num_envs, EnvConfig(reward=config.oracle), config.seed))
    overlapping = dataclasses.replace(config, overlap_updates=True)
    overlapped = Trainer(overlapping, tmp_path / "overlapped", progress_bar=False, env=env)
    env.model = overlapped.model  # the trainer hands the env its updates (while_waiting)
    with pytest.raises(ValueError, match="overlapped updates need an env"):
        Trainer(overlapping, tmp_path / "nowhere", progress_bar=False, env=make_vec_env(1, EnvConfig(), 0))
    threaded = Trainer(overlapping, tmp_path / "threaded", progress_bar=False)  # in process: a second thread
    plain.train()
    overlapped.train()
    threaded.train()
    assert overlapped.model._n_updates == threaded.model._n_updates == plain.model._n_updates > 0
    # an update deferred into the next step still samples only the transitions stored before it
    first_update = config.sac.learning_starts // config.num_envs
    assert env.buffer_sizes[0] == first_update + 1
