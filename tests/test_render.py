"""OpenCV rendering: camera geometry and input checks."""

from __future__ import annotations

import numpy as np
import pytest
from inest_sim_node.render import EGO_ROBOT_AT, PALETTE, SceneRenderer

ROBOT = np.array(PALETTE["robot"])


def _robot_centroid(image: np.ndarray) -> np.ndarray:
    mask = np.all(np.abs(image.astype(int) - ROBOT) <= 3, axis=-1)
    rows, cols = np.nonzero(mask)
    return np.array([cols.mean(), rows.mean()])


@pytest.mark.parametrize("size", [96, 128])
def test_ego_view_keeps_the_robot_at_a_fixed_image_position(demo_world, size):
    renderer = SceneRenderer(demo_world.config)
    expected = np.array([EGO_ROBOT_AT[0] * size, EGO_ROBOT_AT[1] * size]) - 0.5
    centroids, allo_centroids = [], []
    for x, y, angle in [(0.0, -0.6, 0.0), (-0.6, 0.3, 1.2), (0.7, -0.2, -2.5), (0.2, 0.5, 3.0)]:
        demo_world.robot.position = (x, y)
        demo_world.robot.angle = angle
        centroids.append(_robot_centroid(renderer.render(demo_world, "ego", size)))
        allo_centroids.append(_robot_centroid(renderer.render(demo_world, "allo", size)))
    for centroid in centroids:  # the body is partly hidden under fingers; allow a pixel
        assert np.linalg.norm(centroid - expected) < 1.5
    spread = np.ptp(np.array(allo_centroids), axis=0)
    assert spread.min() > 0.3 * size  # in the allocentric view the robot does move


def test_ego_view_rotates_with_the_robot(demo_world):
    renderer = SceneRenderer(demo_world.config)
    demo_world.robot.position = (0.0, 0.3)  # the goal strip is 0.46 above the robot
    demo_world.robot.angle = 0.0
    facing_up = renderer.render(demo_world, "ego", 96)
    demo_world.robot.angle = np.pi / 2  # facing left: the goal strip is now on the right
    facing_left = renderer.render(demo_world, "ego", 96)
    goal = np.array(PALETTE["goal"])

    def goal_pixels(image):
        rows, cols = np.nonzero(np.all(np.abs(image.astype(int) - goal) <= 3, axis=-1))
        assert len(rows) > 100
        return rows.mean(), cols.mean()

    robot_row, centre_col = EGO_ROBOT_AT[1] * 96, EGO_ROBOT_AT[0] * 96
    row, col = goal_pixels(facing_up)
    assert row < robot_row - 15 and abs(col - centre_col) < 3  # straight ahead, above
    _, col = goal_pixels(facing_left)
    assert col > centre_col + 15  # now on the right-hand side


def test_allocentric_view_shows_all_three_block_colours(demo_world):
    image = SceneRenderer(demo_world.config).render(demo_world, "allo", 96)
    for colour in ("red", "blue", "yellow"):
        assert np.all(image == np.array(PALETTE[colour]), axis=-1).sum() > 20


def test_bad_view_and_size_are_rejected(demo_world):
    renderer = SceneRenderer(demo_world.config)
    with pytest.raises(ValueError, match="unknown view 'side'"):
        renderer.render(demo_world, "side", 96)
    with pytest.raises(ValueError, match="must be positive"):
        renderer.render(demo_world, "ego", 0)
