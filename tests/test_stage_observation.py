"""The stage observation, the approach oracle and the reward diagnostics."""

from __future__ import annotations

import json

import numpy as np
import pytest
from inest_agent_node.diagnostics import RewardDiagnostics
from inest_agent_node.envs import (
    LEARNED_STAGE,
    TRUE_PROGRESS,
    RewardVecEnv,
    StageObservationVecEnv,
    build_env,
    make_vec_env,
)
from inest_agent_node.rewards import EnvironmentReward
from inest_agent_node.train import Trainer
from inest_reward_node.runtime.intrinsic import IntrinsicConfig
from inest_sim_node.observation import ROBOT_FIELDS, observation_fields, stage_fields, stage_observation
from inest_sim_node.scoring import dense_reward
from small_training import small_train_config

from inest_agent_node.config import TrainConfig
from inest_sim_node import STATE_FIELDS, EnvConfig, SweepToTopEnv


def state_with(robot=(0.0, 0.0), heading=0.0, blocks=((0.0, 0.5), (0.5, 0.0), (-0.3, -0.4))) -> np.ndarray:
    state = np.zeros(len(STATE_FIELDS), np.float32)
    state[0:4] = [*robot, np.cos(heading), np.sin(heading)]
    state[5:11] = np.ravel(blocks)
    return state


def test_stage_observation_gives_the_stage_block_in_the_robot_frame():
    state = state_with()
    observation = stage_observation(state[None], np.array([0]), 3)[0]
    names = [*STATE_FIELDS, *stage_fields(3)]
    assert len(observation) == len(names) == 28
    values = dict(zip(names, observation, strict=True))
    assert [values[f"stage_{k}"] for k in range(4)] == [1, 0, 0, 0]
    # facing up (+y), red straight ahead at 0.5
    assert values["block_forward"] == pytest.approx(0.5) and values["block_lateral"] == pytest.approx(0.0)
    # stage 1: blue at +x is to the right of a robot facing up
    values = dict(zip(names, stage_observation(state[None], np.array([1]), 3)[0], strict=True))
    assert values["block_forward"] == pytest.approx(0.0, abs=1e-6) and values["block_lateral"] == pytest.approx(-0.5)
    # turned a quarter counter-clockwise (facing -x): blue at +x is straight behind
    turned = state_with(heading=np.pi / 2)
    values = dict(zip(names, stage_observation(turned[None], np.array([1]), 3)[0], strict=True))
    assert values["block_forward"] == pytest.approx(-0.5) and values["block_distance"] == pytest.approx(0.5)
    # six subtasks: stages 2 and 3 both work on blue; done (stage 6) points at the last block
    six = stage_observation(np.stack([state] * 3), np.array([2, 3, 6]), 6)
    assert six.shape == (3, 21 + 7 + 3)
    np.testing.assert_allclose(six[0, -3:], six[1, -3:])
    assert six[2, -1] == pytest.approx(0.5)  # yellow at (-0.3, -0.4)
    with pytest.raises(ValueError, match=r"outside 0\.\.3"):
        stage_observation(state[None], np.array([4]), 3)


def test_the_robot_observation_hides_the_score_and_the_in_goal_flags():
    state = state_with()
    state[STATE_FIELDS.index("ordered_progress")] = 2 / 3
    state[STATE_FIELDS.index("in_goal_red")] = 1.0
    robot = stage_observation(state[None], np.array([1]), 3, sensed_only=True)[0]
    names = observation_fields("robot", 3)
    assert len(robot) == len(names) == 17 + 4 + 3 and "ordered_progress" not in names and "in_goal_red" not in names
    values = dict(zip(names, robot, strict=True))
    assert values["stage_1"] == 1 and values["block_lateral"] == pytest.approx(-0.5)  # the reward's stage still
    whole = dict(zip(observation_fields("stage", 3), stage_observation(state[None], np.array([1]), 3)[0], strict=True))
    assert all(values[name] == whole[name] for name in ROBOT_FIELDS)  # the sensed entries are the state's own


def test_approach_oracle_shares_each_blocks_third_so_finishing_pays_most():
    plain, approach = SweepToTopEnv(), SweepToTopEnv(reward="approach")
    for env in (plain, approach):
        env.reset(seed=3)
    action = np.zeros(3)
    closeness = 3 * plain.step(action)[1]
    x, y, _ = approach.world.robot_pose
    distance = np.hypot(*(approach.world.block_xy[0] - (x, y)))
    expected = 0.5 * closeness + 0.35 * (1 - min(1.0, distance / 1.5)) + 0.15 * approach.world.in_gripper(0)
    assert approach.step(action)[1] * 3 == pytest.approx(expected)
    gaps = np.array([0.0, 0.0, 0.01])
    hovering = dense_reward(2, gaps, 1.86, approach=(0.0, True))  # next to the last block, holding it
    assert hovering < dense_reward(3, gaps * 0, 1.86, approach=(1.5, False)) == 1.0
    with pytest.raises(ValueError, match="unknown oracle reward"):
        SweepToTopEnv(reward="shaped")


def test_stage_wrapper_reports_the_stage_of_each_terminal_observation_and_starts_episodes_at_zero():
    venv = RewardVecEnv(make_vec_env(2, EnvConfig(max_steps=5), seed=0), EnvironmentReward(2))
    env = StageObservationVecEnv(venv, 3)  # the environment's reward: its stage is the true progress
    observations = env.reset()
    assert observations.shape == (2, 24) and env.observation_space.contains(observations[0])
    for _ in range(5):
        observations, _, dones, infos = env.step(np.zeros((2, 3), np.float32))
    assert dones.all()
    for info, observation in zip(infos, observations, strict=True):
        assert info["terminal_observation"].shape == (24,) and observation[17] == 1.0  # stage_0


def test_a_stage_claimed_for_a_block_not_in_the_goal_is_a_false_completion():
    diagnostics = RewardDiagnostics(num_envs=2, num_subtasks=3)

    def info(progress: int, stage: int) -> dict:
        return {TRUE_PROGRESS: progress, LEARNED_STAGE: stage, "shaping_reward": -0.5, "subtask_bonus": 2.0 * stage}

    diagnostics.update([info(0, 1), info(1, 1)], np.array([False, False]), np.array([1.0, 2.0]))  # env 0: too early
    diagnostics.update([info(0, 0), info(2, 1)], np.array([True, True]), np.array([3.0, 2.0]))  # env 1: blue missed
    summary = diagnostics.summary()
    assert summary["false_completion_rate"] == 0.5 and summary["missed_rate"] == 0.5
    assert summary["unearned_completion_rate"] == 0.5  # env 0 never had red in the goal
    assert summary["shaping_per_step"] == -0.5 and summary["bonus_per_step"] == pytest.approx(1.5)
    assert summary["max_progress_mean"] == 1.0 and summary["episodes"] == 2 and summary["reward_per_step"] == 2.0
    assert diagnostics.summary() == {}  # cleared


def test_a_claim_its_block_earns_within_a_few_steps_is_early_a_later_or_never_one_unplaced_a_never_one_never_placed():
    diagnostics = RewardDiagnostics(num_envs=3, num_subtasks=3)
    # env 0 claims red two steps early; env 1 claims it and never places it; env 2 places it six steps late
    trajectory = [((0, 1), (0, 1), (0, 1)), ((0, 1), (0, 1), (0, 1)), ((1, 1), (0, 1), (0, 1))]
    trajectory += [((1, 1), (0, 1), (0, 1))] * 3 + [((1, 1), (0, 1), (1, 1))]
    for step, row in enumerate(trajectory):
        infos = [
            {TRUE_PROGRESS: progress, LEARNED_STAGE: stage, "shaping_reward": 1.0, "subtask_bonus": 2.0,
             "intrinsic_reward": -1.0}
            for progress, stage in row
        ]  # fmt: skip
        diagnostics.update(infos, np.full(3, step == len(trajectory) - 1), np.zeros(3))
    summary = diagnostics.summary()
    assert summary["unearned_completion_rate"] == 1.0  # all three were paid before their block was in
    assert summary["early_claim_rate"] == pytest.approx(1 / 3) and summary["unplaced_claim_rate"] == pytest.approx(
        2 / 3
    )
    assert summary["never_placed_claim_rate"] == pytest.approx(1 / 3)  # env 1's: env 2 placed its block in the end
    assert summary["ends_overclaimed_rate"] == pytest.approx(1 / 3)  # env 1 ends paid for red
    assert summary["overpaid_step_per_step"] == pytest.approx((2 + 7 + 6) / 21)  # as unearned: no block pushed out
    assert (summary["shaping_share"], summary["bonus_share"], summary["intrinsic_share"]) == (0.25, 0.5, 0.25)
    # every step of every env until its block is placed was paid in a stage claimed early
    assert summary["unearned_step_per_step"] == pytest.approx((2 + 7 + 6) / 21)
    assert summary["intrinsic_unearned_per_step"] == -1.0 and summary["intrinsic_earned_per_step"] == -1.0


def test_learned_reward_training_sees_the_trackers_stage_and_records_diagnostics(tiny_tcc_run, tmp_path):
    _, reward_run = tiny_tcc_run
    config = small_train_config(
        reward="inest",
        model=str(reward_run / "model"),
        intrinsic=IntrinsicConfig(mode="embedding"),
        total_steps=400,  # 200 vector steps: each evaluation interval ends a 100-step episode per env
        eval_episodes=2,
        final_eval_episodes=2,
        checkpoint_every=400,
    )
    trainer = Trainer(config, tmp_path / "run", progress_bar=False)
    assert trainer.model.observation_space.shape == (24,)
    trainer.train()
    scorer = trainer.reward_env.reward
    stored = trainer.model.replay_buffer.observations[: trainer.model.replay_buffer.size(), 0]
    assert stored.shape[1] == 24 and np.all(stored[:, 17:21].sum(axis=1) == 1)  # always exactly one stage
    assert scorer.num_envs == 2
    results = json.loads((tmp_path / "run" / "results.json").read_text())
    diagnostics = results["reward_diagnostics"]
    assert [entry["steps"] for entry in diagnostics] == [200, 400]
    assert {"shaping_per_step", "bonus_per_step", "intrinsic_per_step", "false_completion_rate"} <= set(diagnostics[0])
    assert results["config"]["observation"] == "robot"
    with pytest.raises(ValueError, match="reward_batch_steps to 1"):
        TrainConfig(reward="inest", model="m", reward_batch_steps=4)


def test_evaluation_env_follows_the_training_observation(tiny_tcc_run):
    _, reward_run = tiny_tcc_run
    config = TrainConfig(reward="topic", model=str(reward_run / "model"), intrinsic=IntrinsicConfig(mode="none"))
    env = build_env(config, num_envs=2, evaluation=True)
    assert env.observation_space.shape == (24,)
    with pytest.raises(ValueError, match="needs `model`"):
        build_env(TrainConfig(reward="topic", intrinsic=IntrinsicConfig(mode="none")), 2, evaluation=True)


def test_the_environments_reward_is_a_reward_function_like_the_learned_ones():
    from inest_reward_node.runtime.rewards import RewardFunction

    reward = EnvironmentReward(2)
    assert isinstance(reward, RewardFunction) and reward.camera is None  # it renders no frames
    env = RewardVecEnv(make_vec_env(2, EnvConfig(max_steps=30, reward="approach"), seed=3), reward)
    env.reset()
    rng = np.random.default_rng(0)
    for _ in range(40):
        _, rewards, _, infos = env.step(rng.uniform(-1, 1, (2, 3)).astype(np.float32))
        assert rewards.tolist() == pytest.approx([info["env_reward"] for info in infos])
        assert [info[LEARNED_STAGE] for info in infos] == [info[TRUE_PROGRESS] for info in infos]
        assert [info["shaping_reward"] for info in infos] == pytest.approx(rewards.tolist())
    with pytest.raises(ValueError, match="env_rewards and known_stages"):
        reward.score(None)


def test_the_environments_reward_scored_several_steps_at_once_is_each_steps_own():
    env = RewardVecEnv(
        make_vec_env(2, EnvConfig(max_steps=30, reward="approach"), seed=3), EnvironmentReward(2), batch_steps=3
    )
    env.accept_deferred_rewards()  # what learners.RewardBatchingMixin does
    env.reset()
    rng = np.random.default_rng(1)
    given = [
        [info["env_reward"] for info in env.step(rng.uniform(-1, 1, (2, 3)).astype(np.float32))[3]] for _ in range(6)
    ]
    np.testing.assert_allclose(np.array(env.take_rewards(10)), np.array(given), rtol=1e-6)  # no step's overwritten
