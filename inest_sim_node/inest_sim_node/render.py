"""Top-down RGB rendering with OpenCV, straight at the requested resolution.

Each camera is an affine map from world to pixel coordinates. The allocentric camera
shows the whole arena; the egocentric one follows the robot, rotated with it, robot at
the bottom centre facing up (X-MAGICAL's `set_cam_follow` with target (0.5, 0.15)).
Polygons are drawn anti-aliased with sub-pixel precision, so small images stay faithful.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

from .config import VIEWS, WorldConfig
from .world import BLOCK_COLOURS, FINGER_SIDES, World, finger_polygons

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


def _rotation(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s], [s, c]])


class SceneRenderer:
    """Draws a `World` from either camera; keeps per-size caches of what never moves."""

    def __init__(self, config: WorldConfig) -> None:
        self.config = config
        half_block = config.block_side / 2
        self._block = np.array([[-1, -1], [1, -1], [1, 1], [-1, 1]], dtype=float) * half_block
        self._fingers = [[np.asarray(p) for p in finger_polygons(config, side)] for side in FINGER_SIDES]
        arena = config.arena_half_size
        self._floor = np.array([[-arena, -arena], [arena, -arena], [arena, arena], [-arena, arena]])
        bottom = config.goal_bottom
        self._goal = np.array([[-arena, bottom], [arena, bottom], [arena, arena], [-arena, arena]])
        self._extent = 2 * arena * ZOOM_OUT  # world units spanned by an image side
        self._allo_backdrops: dict[int, np.ndarray] = {}

    def render(self, world: World, view: str, size: int) -> np.ndarray:
        if view not in VIEWS:
            raise ValueError(f"unknown view {view!r}; expected one of {VIEWS}")
        if size <= 0:
            raise ValueError(f"image size must be positive, got {size}")
        linear, offset = self._camera(world, view, size)
        if view == "allo":
            image = self._allo_backdrop(size, linear, offset).copy()
        else:
            image = np.empty((size, size, 3), dtype=np.uint8)
            image[:] = PALETTE["background"]
            self._draw_static(image, linear, offset)
        thin = max(1, round(size / 128))
        for colour, body in zip(BLOCK_COLOURS, world.block_bodies, strict=True):
            pts = self._to_pixels(self._block, linear, offset, body.angle, body.position)
            cv2.fillPoly(image, [pts], PALETTE[colour], cv2.LINE_AA, _SHIFT)
            cv2.polylines(image, [pts], True, _darker(PALETTE[colour]), thin, cv2.LINE_AA, _SHIFT)
        finger_pts = [
            self._to_pixels(poly, linear, offset, finger.angle, finger.position)
            for polys, finger in zip(self._fingers, world.finger_bodies, strict=True)
            for poly in polys
        ]
        cv2.fillPoly(image, finger_pts, PALETTE["finger"], cv2.LINE_AA, _SHIFT)
        centre = self._to_pixels(np.zeros((1, 2)), linear, offset, 0.0, world.robot.position)[0]
        radius = round(self.config.robot_radius * size / self._extent * _ONE)
        cv2.circle(image, tuple(int(v) for v in centre), radius, PALETTE["robot"], -1, cv2.LINE_AA, _SHIFT)
        cv2.circle(image, tuple(int(v) for v in centre), radius, PALETTE["robot_edge"], thin, cv2.LINE_AA, _SHIFT)
        return image

    def _camera(self, world: World, view: str, size: int) -> tuple[np.ndarray, np.ndarray]:
        """World-to-pixel map p -> linear @ p + offset (pixel centres at integer coordinates)."""
        scale = size / self._extent
        flip = np.array([[scale, 0.0], [0.0, -scale]])
        if view == "allo":
            return flip, np.full(2, size / 2 - 0.5)
        x, y, angle = world.robot_pose
        linear = flip @ _rotation(-angle)
        anchor = np.array([EGO_ROBOT_AT[0] * size, EGO_ROBOT_AT[1] * size]) - 0.5
        return linear, anchor - linear @ np.array([x, y])

    def _allo_backdrop(self, size: int, linear: np.ndarray, offset: np.ndarray) -> np.ndarray:
        backdrop = self._allo_backdrops.get(size)
        if backdrop is None:
            backdrop = np.empty((size, size, 3), dtype=np.uint8)
            backdrop[:] = PALETTE["background"]
            self._draw_static(backdrop, linear, offset)
            self._allo_backdrops[size] = backdrop
        return backdrop

    def _draw_static(self, image: np.ndarray, linear: np.ndarray, offset: np.ndarray) -> None:
        floor = self._to_pixels(self._floor, linear, offset)
        goal = self._to_pixels(self._goal, linear, offset)
        cv2.fillPoly(image, [floor], PALETTE["floor"], cv2.LINE_AA, _SHIFT)
        cv2.fillPoly(image, [goal], PALETTE["goal"], cv2.LINE_AA, _SHIFT)
        thin = max(1, round(image.shape[0] / 128))
        cv2.line(image, tuple(goal[0]), tuple(goal[1]), PALETTE["goal_edge"], thin, cv2.LINE_AA, _SHIFT)

    @staticmethod
    def _to_pixels(
        local: np.ndarray,
        linear: np.ndarray,
        offset: np.ndarray,
        angle: float = 0.0,
        position: tuple[float, float] = (0.0, 0.0),
    ) -> np.ndarray:
        """Body-local points to fixed-point pixel coordinates for OpenCV."""
        body_to_pixel = linear @ _rotation(angle)
        pixel_offset = linear @ np.asarray(position, dtype=float) + offset
        pts = local @ body_to_pixel.T + pixel_offset
        return np.rint(pts * _ONE).astype(np.int32)
