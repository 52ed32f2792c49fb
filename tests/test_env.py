"""The gymnasium environment: API conformance, determinism, bad input."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from inest_sim_node import ENV_ID, STATE_FIELDS, EnvConfig, SweepToTopEnv


@pytest.mark.parametrize("observation", ["state", "pixels", "state_pixels"])
@pytest.mark.parametrize("view", ["ego", "allo"])
def test_passes_the_gymnasium_checker(observation, view):
    env = gym.make(ENV_ID, observation=observation, view=view, image_size=64, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)
    obs, _ = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert env.render().shape == (256, 256, 3)


def test_state_vector_matches_its_documented_fields(env):
    state, info = env.reset(seed=3)
    assert state.shape == (len(STATE_FIELDS),) == (21,)
    named = dict(zip(STATE_FIELDS, state, strict=True))
    x, y, angle = env.world.robot_pose
    assert named["robot_x"] == pytest.approx(x, abs=1e-6) and named["robot_y"] == pytest.approx(y, abs=1e-6)
    assert named["robot_cos"] == pytest.approx(np.cos(angle), abs=1e-6)
    assert named["red_x"] == pytest.approx(env.world.block_xy[0][0], abs=1e-6)
    assert named["dist_robot_blue"] == pytest.approx(np.hypot(*(env.world.block_xy[1] - [x, y])), abs=1e-5)
    assert named["ordered_progress"] == 0.0 and info["score"] == 0.0


def _rollout(env, seed, steps=30):
    obs, _ = env.reset(seed=seed)
    trace = [obs]
    rng = np.random.default_rng(123)
    for _ in range(steps):
        obs, reward, _, _, _ = env.step(rng.uniform(-1, 1, 3))
        trace.append(np.append(obs, reward))
    return np.concatenate(trace)


def test_same_seed_same_episode_other_seed_other_layout():
    env = SweepToTopEnv(config=EnvConfig())
    first, again, other = _rollout(env, 7), _rollout(env, 7), _rollout(env, 8)
    np.testing.assert_array_equal(first, again)
    assert not np.allclose(first[:21], other[:21])
    env_b = SweepToTopEnv(config=EnvConfig())  # a second instance agrees too
    np.testing.assert_array_equal(first, _rollout(env_b, 7))


def test_episode_truncates_at_the_step_limit():
    env = SweepToTopEnv(config=EnvConfig(max_steps=5))
    env.reset(seed=0)
    flags = [env.step(np.zeros(3))[3] for _ in range(5)]
    assert flags == [False, False, False, False, True]


def test_random_layouts_vary_colour_positions():
    env = SweepToTopEnv(config=EnvConfig())
    orders = set()
    for seed in range(30):
        env.reset(seed=seed)
        orders.add(tuple(np.argsort(env.world.block_xy[:, 0])))
    assert len(orders) >= 5  # which colour sits where is randomised


def test_demo_layout_is_fixed():
    env = SweepToTopEnv(config=EnvConfig.from_kwargs(layout={"kind": "demo"}))
    env.reset(seed=1)
    first = env.world.block_xy.copy()
    env.reset(seed=2)
    np.testing.assert_array_equal(first, env.world.block_xy)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"view": "side"}, "unknown view 'side'"),
        ({"image_size": 0}, "image_size must be a positive integer"),
        ({"image_size": -5}, "image_size must be a positive integer"),
        ({"max_steps": 0}, "max_steps must be a positive integer"),
        ({"observation": "depth"}, "unknown observation 'depth'"),
        ({"colour": "red"}, "unknown environment argument"),
        ({"layout": {"kind": "spiral"}}, "unknown layout 'spiral'"),
        ({"world": {"max_speed": float("nan")}}, "max_speed must be a positive finite"),
    ],
)
def test_bad_constructor_arguments_name_the_problem(kwargs, message):
    with pytest.raises(ValueError, match=message):
        gym.make(ENV_ID, **kwargs)


@pytest.mark.parametrize("bad", [[np.nan, 0, 0], [0, np.inf, 0], [0, 0, -np.inf]])
def test_nan_or_inf_actions_are_rejected_and_the_world_is_untouched(env, bad):
    env.reset(seed=0)
    before = env.state_vector()
    with pytest.raises(ValueError, match="NaN or inf"):
        env.step(bad)
    np.testing.assert_array_equal(before, env.state_vector())
    assert env.elapsed_steps == 0


def test_wrongly_shaped_action_is_rejected(env):
    env.reset(seed=0)
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        env.step([0.0, 0.0])


def test_out_of_range_actions_are_clipped_not_rejected(env):
    env.reset(seed=0)
    env.step([5.0, 0.0, 0.0])
    speed_limited = env.state_vector()
    env.reset(seed=0)
    env.step([1.0, 0.0, 0.0])
    np.testing.assert_allclose(speed_limited, env.state_vector())
