"""Physics of the task world: containment, grasping, finger control."""

from __future__ import annotations

import numpy as np

from inest_sim_node import EnvConfig, SweepToTopEnv

RED = 0


def _assert_blocks_inside(world):
    """Centres stay inside the walls and no block sinks even half-way into one.

    Contacts are soft (pymunk's collision slop and 10 solver iterations, as in X-MAGICAL), so a
    block squeezed by the robot may overlap a wall by a few centimetres, never escape.
    """
    half = world.config.arena_half_size
    for centre, shape in zip(world.block_xy, world.block_shapes, strict=True):
        assert np.all(np.abs(centre) < half), centre
        bb = shape.bb
        deepest = max(-half - bb.left, bb.right - half, -half - bb.bottom, bb.top - half)
        assert deepest < world.config.block_side / 2, bb


def test_blocks_never_leave_the_arena_under_random_actions():
    env = SweepToTopEnv(config=EnvConfig(max_steps=400))
    rng = np.random.default_rng(0)
    for seed in range(4):
        env.reset(seed=seed)
        action = rng.uniform(-1, 1, 3)
        for step in range(400):
            if step % 10 == 0:  # hold actions for a while so the robot really rams into things
                action = rng.uniform(-1, 1, 3)
                action[0] = abs(action[0]) if step % 20 else action[0]
            env.step(action)
            _assert_blocks_inside(env.world)


def test_block_rammed_into_a_wall_stays_inside(demo_world):
    demo_world.place_block(RED, (0.0, 0.8))  # straight ahead of the robot, near the top wall
    demo_world.apply_action(np.array([1.0, 0.0, 1.0]))
    for _ in range(40):
        demo_world.step()
        _assert_blocks_inside(demo_world)
    assert demo_world.block_xy[RED][1] > 0.8  # it was pushed, and stopped at the wall


def test_grasped_block_moves_with_the_gripper(demo_world):
    world = demo_world
    x, y, _ = world.robot_pose
    world.place_block(RED, (x, y + 0.3))  # between the open fingers
    world.apply_action(np.array([0.0, 0.0, 1.0]))  # close
    for _ in range(3):
        world.step()
    assert world.in_gripper(RED)
    assert 0.2 < world.finger_opening < 0.9  # the block keeps the fingers apart
    start_block = world.block_xy[RED].copy()
    start_offset = np.array(world.robot.world_to_local(tuple(start_block)))
    world.apply_action(np.array([-0.6, 0.4, 1.0]))  # back away while turning
    for _ in range(8):
        world.step()
    moved = np.linalg.norm(world.block_xy[RED] - start_block)
    offset = np.array(world.robot.world_to_local(tuple(world.block_xy[RED])))
    assert moved > 0.4  # friction alone dragged it along ...
    assert np.linalg.norm(offset - start_offset) < 0.05  # ... and it stayed where the fingers hold it


def test_open_fingers_let_go_of_the_block(demo_world):
    world = demo_world
    x, y, _ = world.robot_pose
    world.place_block(RED, (x, y + 0.3))
    world.apply_action(np.array([0.0, 0.0, -1.0]))
    world.step()
    start_block = world.block_xy[RED].copy()
    world.apply_action(np.array([-0.6, 0.0, -1.0]))
    for _ in range(6):
        world.step()
    assert np.linalg.norm(world.block_xy[RED] - start_block) < 0.05


def test_fingers_follow_the_grip_command(demo_world):
    world = demo_world
    assert world.finger_opening == 1.0
    world.apply_action(np.array([0.0, 0.0, 1.0]))
    world.step()
    world.step()
    assert world.finger_opening < 0.05
    world.apply_action(np.array([0.0, 0.0, 0.0]))  # half open
    world.step()
    world.step()
    assert abs(world.finger_opening - 0.5) < 0.1


def test_gaps_from_recorded_poses_match_the_live_world():
    """Episodes kept as poses (the exploit suite) measure a block's gap to the goal as the world does."""
    from inest_sim_node.world import pose_goal_gaps

    env = SweepToTopEnv(config=EnvConfig(max_steps=200))
    rng = np.random.default_rng(1)
    env.reset(seed=3)
    gaps = []
    for _ in range(200):
        env.step(rng.uniform(-1, 1, 3))
        world = env.world
        np.testing.assert_allclose(pose_goal_gaps(world.body_poses(), world.config), world.block_goal_gaps(), atol=1e-9)
        gaps.append(world.block_goal_gaps())
    assert np.ptp(np.array(gaps), axis=0).max() > 0  # the blocks moved, angles and all
