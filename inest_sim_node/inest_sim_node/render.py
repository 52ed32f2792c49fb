"""Top-down RGB rendering with OpenCV, straight at the requested resolution.

Each camera is an affine map from world to pixel coordinates. The allocentric camera
shows the whole arena; the egocentric one follows the robot, rotated with it, robot at
the bottom centre facing up (X-MAGICAL's `set_cam_follow` with target (0.5, 0.15)).
Polygons are drawn anti-aliased with sub-pixel precision, so small images stay faithful.
"""

from __future__ import annotations

import cv2
import numpy as np

from .config import VIEWS, WorldConfig
from .world import BLOCK_COLOURS, BODY_ORDER, FINGER_SIDES, World, finger_polygons

ZOOM_OUT = 1.02  # X-MAGICAL shows a sliver of wall around the arena
EGO_ROBOT_AT = (0.5, 0.85)  # fraction of width, fraction of height from the top
_SHIFT = 4  # sub-pixel bits for OpenCV drawing
_ONE = 1 << _SHIFT

PALETTE: dict[str, tuple[int, int, int]] = {
    "background": (205, 206, 214),
    "floor": (255, 255, 255),
    "goal": (190, 230, 160),
    "goal_edge": (96, 160, 60),
    "red": (225, 60, 80),
    "blue": (60, 110, 210),
    "yellow": (240, 200, 40),
    "robot": (150, 150, 162),
    "robot_edge": (90, 90, 100),
    "finger": (112, 112, 124),
}


def _darker(colour: tuple[int, int, int]) -> tuple[int, int, int]:
    r, g, b = colour
    return int(r * 0.7), int(g * 0.7), int(b * 0.7)


def _rotation(angle: float | np.ndarray) -> np.ndarray:
    """Rotation matrices for one angle (2, 2) or an array of them (..., 2, 2)."""
    c, s = np.cos(angle), np.sin(angle)
    rotation = np.empty((*np.shape(angle), 2, 2))  # filled in place: nested np.stack was a third of a frame
    rotation[..., 0, 0], rotation[..., 0, 1], rotation[..., 1, 0], rotation[..., 1, 1] = c, -s, s, c
    return rotation


class SceneRenderer:
    """Draws a `World` from either camera; keeps per-size caches of what never moves."""

    def __init__(self, config: WorldConfig) -> None:
        self.config = config
        half_block = config.block_side / 2
        block = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float) * half_block
        arena = config.arena_half_size
        floor = np.array([[-arena, -arena], [arena, -arena], [arena, arena], [-arena, arena]])
        bottom = config.goal_bottom
        goal = np.array([[-arena, bottom], [arena, bottom], [arena, arena], [-arena, arena]])
        # Every outline in one array, so one vectorised transform places them all: each point
        # carries the index of the frame it is drawn in (0: world, then blocks, fingers, robot).
        outlines: list[tuple[int, np.ndarray]] = [(0, floor), (0, goal)]
        outlines += [(1 + index, block) for index in range(len(BLOCK_COLOURS))]
        finger_frame = 1 + len(BLOCK_COLOURS)
        for index, side in enumerate(FINGER_SIDES):
            outlines += [(finger_frame + index, np.asarray(p)) for p in finger_polygons(config, side)]
        outlines.append((finger_frame + len(FINGER_SIDES), np.zeros((1, 2))))  # the robot's centre
        self._local = np.concatenate([points for _, points in outlines])
        self._frame_of_point = np.concatenate([np.full(len(points), frame) for frame, points in outlines])
        ends = np.cumsum([len(points) for _, points in outlines])
        self._outline_slices = [slice(start, end) for start, end in zip([0, *ends[:-1]], ends, strict=True)]
        self._extent = 2 * arena * ZOOM_OUT  # world units spanned by an image side
        self._blanks: dict[int, np.ndarray] = {}
        self._allo_backdrops: dict[int, np.ndarray] = {}

    def render(self, world: World, view: str, size: int) -> np.ndarray:
        return self.render_poses(world.body_poses(), view, size)

    def render_poses(self, poses: np.ndarray, view: str, size: int) -> np.ndarray:
        """The image of a world whose moving bodies stand at `poses` (World.body_poses): a
        recorded episode's poses render again from any camera at any size."""
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}; expected one of {VIEWS}")
        if size <= 0:
            raise ValueError(f"image size must be positive, got {size}")
        poses = np.asarray(poses, dtype=float)
        if poses.shape != (len(BODY_ORDER), 3):
            raise ValueError(f"poses must have shape ({len(BODY_ORDER)}, 3) (angle, x, y per body), got {poses.shape}")
        linear, offset = self._camera(poses[-1], view, size)
        pixels = self._outline_pixels(poses, linear, offset)
        outlines = [pixels[part] for part in self._outline_slices]
        floor, goal, *bodies, centre = outlines
        blocks, fingers = bodies[: len(BLOCK_COLOURS)], bodies[len(BLOCK_COLOURS) :]
        if view == "allo":
            image = self._allo_backdrop(size, floor, goal).copy()
        else:
            image = self._blank(size).copy()
            self._draw_static(image, floor, goal)
        thin = max(1, round(size / 128))
        for colour, pts in zip(BLOCK_COLOURS, blocks, strict=True):
            cv2.fillPoly(image, [pts], PALETTE[colour], cv2.LINE_AA, _SHIFT)
            cv2.polylines(image, [pts], True, _darker(PALETTE[colour]), thin, cv2.LINE_AA, _SHIFT)
        cv2.fillPoly(image, fingers, PALETTE["finger"], cv2.LINE_AA, _SHIFT)
        radius = round(self.config.robot_radius * size / self._extent * _ONE)
        centre = (int(centre[0, 0]), int(centre[0, 1]))
        cv2.circle(image, centre, radius, PALETTE["robot"], -1, cv2.LINE_AA, _SHIFT)
        cv2.circle(image, centre, radius, PALETTE["robot_edge"], thin, cv2.LINE_AA, _SHIFT)
        return image

    def _outline_pixels(self, body_poses: np.ndarray, linear: np.ndarray, offset: np.ndarray) -> np.ndarray:
        """Every outline's points in fixed-point pixel coordinates for OpenCV, in one pass."""
        poses = np.concatenate([np.zeros((1, 3)), body_poses])  # frame 0: the world itself
        body_to_pixel = linear @ _rotation(poses[:, 0])
        pixel_offsets = poses[:, 1:] @ linear.T + offset
        frames = self._frame_of_point
        pts = np.einsum("pij,pj->pi", body_to_pixel[frames], self._local) + pixel_offsets[frames]
        return np.rint(pts * _ONE).astype(np.int32)

    def _camera(self, robot_pose: np.ndarray, view: str, size: int) -> tuple[np.ndarray, np.ndarray]:
        """World-to-pixel map p -> linear @ p + offset (pixel centres at integer coordinates);
        `robot_pose` (angle, x, y) places the egocentric camera."""
        scale = size / self._extent
        flip = np.array([[scale, 0.0], [0.0, -scale]])
        if view == "allo":
            return flip, np.full(2, size / 2 - 0.5)
        angle, x, y = robot_pose
        linear = flip @ _rotation(-angle)
        anchor = np.array([EGO_ROBOT_AT[0] * size, EGO_ROBOT_AT[1] * size]) - 0.5
        return linear, anchor - linear @ np.array([x, y])

    def _blank(self, size: int) -> np.ndarray:
        """The background colour at `size`; copying it is faster than filling a new image."""
        blank = self._blanks.get(size)
        if blank is None:
            blank = np.empty((size, size, 3), dtype=np.uint8)
            blank[:] = PALETTE["background"]
            self._blanks[size] = blank
        return blank

    def _allo_backdrop(self, size: int, floor: np.ndarray, goal: np.ndarray) -> np.ndarray:
        backdrop = self._allo_backdrops.get(size)
        if backdrop is None:
            backdrop = self._blank(size).copy()
            self._draw_static(backdrop, floor, goal)
            self._allo_backdrops[size] = backdrop
        return backdrop

    @staticmethod
    def _draw_static(image: np.ndarray, floor: np.ndarray, goal: np.ndarray) -> None:
        cv2.fillPoly(image, [floor], PALETTE["floor"], cv2.LINE_AA, _SHIFT)
        cv2.fillPoly(image, [goal], PALETTE["goal"], cv2.LINE_AA, _SHIFT)
        thin = max(1, round(image.shape[0] / 128))
        cv2.line(image, tuple(goal[0]), tuple(goal[1]), PALETTE["goal_edge"], thin, cv2.LINE_AA, _SHIFT)
