"""The scripted expert solves the ordered task reliably and with variety."""

from __future__ import annotations

import numpy as np
import pytest
from inest_sim_node.expert import ExpertConfig, ScriptedExpert, run_expert_episode

from inest_sim_node import EnvConfig, SweepToTopEnv


def test_expert_succeeds_on_at_least_95_percent_of_200_seeds():
    env = SweepToTopEnv(config=EnvConfig())  # default 100-step limit
    expert = ScriptedExpert()
    results = [run_expert_episode(env, expert, seed) for seed in range(200)]
    success = np.mean([score == 1.0 for score, _ in results])
    assert success >= 0.95, f"expert success {success:.3f}"
    assert max(solved for _, solved in results) <= env.config.max_steps


def test_expert_demonstrations_differ_between_seeds_on_one_layout():
    env = SweepToTopEnv(config=EnvConfig.from_kwargs(layout={"kind": "demo"}))
    expert = ScriptedExpert()
    paths = []
    for seed in range(3):
        env.reset(seed=seed)
        expert.reset(seed=seed)
        positions = []
        for _ in range(30):
            env.step(expert.act(env))
            positions.append(env.world.robot_pose[:2])
        paths.append(np.array(positions))
    assert np.abs(paths[0] - paths[1]).max() > 0.05
    assert np.abs(paths[1] - paths[2]).max() > 0.05


def test_bad_expert_config_is_rejected():
    with pytest.raises(ValueError, match="standoff"):
        ExpertConfig(standoff=(0.6, 0.5))
    with pytest.raises(ValueError, match="action_noise"):
        ExpertConfig(action_noise=-0.1)
