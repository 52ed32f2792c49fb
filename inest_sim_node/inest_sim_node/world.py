"""The pymunk world of "sweep to top in order": arena, goal strip, three blocks, gripper.

Top-down and gravity-free. Ground friction is emulated, as in X-MAGICAL, by velocity-only
pivot and gear joints from each block to the static body. The robot is steered through a
kinematic control body: velocity-only joints drag the robot towards the commanded forward
speed and turn rate, so pushing a block or a wall limits it by force, not by teleporting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pymunk

from .config import LayoutConfig, WorldConfig

BLOCK_COLOURS = ("red", "blue", "yellow")  # also the order in which they must reach the goal
FINGER_SIDES = (-1, 1)  # left, right (seen from behind the robot)
BLOCK_ROUNDING = 0.01  # a block's corner radius, in block sides
BODY_ORDER = (*BLOCK_COLOURS, "left_finger", "right_finger", "robot")  # rows of World.body_poses
_ROBOT_GROUP = 1
_FINGER_MAX_RATE = 3.0  # rad/s: the fingers open or close fully within about one control step


@dataclass(frozen=True)
class Layout:
    """Start poses; blocks listed in task order (red, blue, yellow)."""

    block_xy: np.ndarray  # (3, 2)
    robot_xy: tuple[float, float]
    robot_angle: float


def sample_layout(layout: LayoutConfig, rng: np.random.Generator) -> Layout:
    """Draw start poses from the episode's generator (X-MAGICAL TestLayout style)."""
    if layout.kind == "demo":
        return Layout(np.array([[-0.5, 0.0], [0.0, 0.0], [0.5, 0.0]]), layout.robot_start, 0.0)
    row_y = rng.uniform(*layout.row_y_range)
    xs = rng.choice(np.asarray(layout.slot_xs), size=len(BLOCK_COLOURS), replace=False)
    block_xy = np.stack([xs, np.full(len(xs), row_y)], axis=1)
    block_xy += rng.uniform(-layout.block_jitter, layout.block_jitter, size=block_xy.shape)
    robot_xy = np.asarray(layout.robot_start) + rng.uniform(-layout.robot_jitter, layout.robot_jitter, size=2)
    robot_angle = rng.uniform(-layout.robot_angle_jitter, layout.robot_angle_jitter)
    return Layout(block_xy, (float(robot_xy[0]), float(robot_xy[1])), float(robot_angle))


def pose_goal_gaps(poses: np.ndarray, config: WorldConfig) -> np.ndarray:
    """World.block_goal_gaps of recorded poses (World.body_poses rows): each square block's
    bounding box from its angle and rounded corners, for episodes kept as poses rather than as a live world."""
    angle, y = poses[: len(BLOCK_COLOURS), 0], poses[: len(BLOCK_COLOURS), 2]
    reach = config.block_side / 2 * (np.abs(np.cos(angle)) + np.abs(np.sin(angle)))
    bottom = y - reach - BLOCK_ROUNDING * config.block_side
    return np.maximum(0.0, config.goal_bottom - bottom)


def finger_polygons(config: WorldConfig, side: int) -> list[list[tuple[float, float]]]:
    """Upper arm and inward-bent forearm of one finger, in the finger's frame (pivot at 0)."""
    thickness = 0.25 * config.robot_radius
    upper = 1.1 * config.robot_radius
    fore = 0.7 * config.robot_radius
    half = thickness / 2
    upper_arm = [(-half, 0.0), (half, 0.0), (half, upper), (-half, upper)]
    bend = config.finger_open_angle
    direction = np.array([-side * math.sin(bend), math.cos(bend)])
    normal = np.array([direction[1], -direction[0]]) * half
    start = np.array([0.0, upper - half])
    end = start + fore * direction
    forearm = [start + normal, end + normal, end - normal, start - normal]
    return [upper_arm, [(float(x), float(y)) for x, y in forearm]]


def finger_pivot(config: WorldConfig, side: int) -> tuple[float, float]:
    return (side * 0.45 * config.robot_radius, 0.1 * config.robot_radius)


class World:
    """One episode's physics. Rebuilt on every reset so episodes never share state."""

    def __init__(self, config: WorldConfig, layout: Layout) -> None:
        self.config = config
        self.space = pymunk.Space()
        self.space.iterations = config.solver_iterations
        self.space.collision_slop = 0.01
        self._speed_command = 0.0
        self._turn_command = 0.0
        self._opening_command = 1.0
        self._add_walls()
        self.block_bodies: list[pymunk.Body] = []
        self.block_shapes: list[pymunk.Poly] = []
        for xy in layout.block_xy:
            self._add_block((float(xy[0]), float(xy[1])))
        self._add_robot(layout.robot_xy, layout.robot_angle)

    # --- construction -------------------------------------------------------------
    def _add_walls(self) -> None:
        half, thick = self.config.arena_half_size, 1.0
        outer = half + thick
        corners = [(-outer, outer), (outer, outer), (outer, -outer), (-outer, -outer)]
        body = self.space.static_body
        for start, end in zip(corners, corners[1:] + corners[:1], strict=True):
            wall = pymunk.Segment(body, start, end, thick)
            wall.friction = 0.8
            self.space.add(wall)

    def _add_block(self, xy: tuple[float, float]) -> None:
        body = pymunk.Body()
        body.position = xy
        side = self.config.block_side
        shape = pymunk.Poly.create_box(body, (side, side), BLOCK_ROUNDING * side)
        shape.mass = self.config.block_mass
        shape.friction = 0.5
        slide = pymunk.PivotJoint(self.space.static_body, body, (0, 0), (0, 0))
        slide.max_bias = 0
        slide.max_force = self.config.block_slide_friction
        spin = pymunk.GearJoint(self.space.static_body, body, 0.0, 1.0)
        spin.max_bias = 0
        spin.max_force = self.config.block_spin_friction
        self.space.add(body, shape, slide, spin)
        self.block_bodies.append(body)
        self.block_shapes.append(shape)

    def _add_robot(self, xy: tuple[float, float], angle: float) -> None:
        cfg = self.config
        moment = pymunk.moment_for_circle(cfg.robot_mass, 0, cfg.robot_radius)
        self.robot = pymunk.Body(cfg.robot_mass, moment)
        self.robot.position = xy
        self.robot.angle = angle
        body_shape = pymunk.Circle(self.robot, cfg.robot_radius)
        body_shape.friction = 0.5
        body_shape.filter = pymunk.ShapeFilter(group=_ROBOT_GROUP)
        self.space.add(self.robot, body_shape)

        self.control = pymunk.Body(body_type=pymunk.Body.KINEMATIC)
        self.control.position = xy
        self.control.angle = angle
        drive = pymunk.PivotJoint(self.control, self.robot, (0, 0), (0, 0))
        drive.max_bias = 0
        drive.max_force = cfg.robot_drive_force
        steer = pymunk.GearJoint(self.control, self.robot, 0.0, 1.0)
        steer.max_bias = 0
        steer.max_force = cfg.robot_turn_torque
        self.space.add(self.control, drive, steer)

        self.finger_bodies: list[pymunk.Body] = []
        self._finger_motors: list[pymunk.SimpleMotor] = []
        finger_mass = cfg.robot_mass / 8
        for side in FINGER_SIDES:
            polys = finger_polygons(cfg, side)
            moment = pymunk.moment_for_poly(finger_mass, polys[0] + polys[1])
            finger = pymunk.Body(finger_mass, moment)
            opened = -side * cfg.finger_open_angle  # fingers start open
            finger.angle = angle + opened
            finger.position = self.robot.local_to_world(finger_pivot(cfg, side))
            shapes = [pymunk.Poly(finger, poly) for poly in polys]
            for shape in shapes:
                shape.friction = 5.0  # grippy fingers: grasping works by friction alone
                shape.filter = pymunk.ShapeFilter(group=_ROBOT_GROUP)
            hinge = pymunk.PivotJoint(self.robot, finger, finger.position)
            low, high = sorted((0.0, opened))
            limit = pymunk.RotaryLimitJoint(self.robot, finger, low, high)
            motor = pymunk.SimpleMotor(self.robot, finger, 0.0)
            motor.max_force = cfg.finger_force
            self.space.add(finger, *shapes, hinge, limit, motor)
            self.finger_bodies.append(finger)
            self._finger_motors.append(motor)

    # --- control ------------------------------------------------------------------
    def apply_action(self, action: np.ndarray) -> None:
        """Set forward speed, turn rate and grip from an action already clipped to [-1, 1]."""
        self._speed_command = float(action[0]) * self.config.max_speed
        self._turn_command = float(action[1]) * self.config.max_turn_rate
        self._opening_command = (1.0 - float(action[2])) / 2.0

    def step(self) -> None:
        """Advance one control step (1 / control_hz seconds) in `substeps` physics steps."""
        cfg = self.config
        dt = 1.0 / (cfg.control_hz * cfg.substeps)
        self._update_fingers()
        self.control.angular_velocity = self._turn_command
        speed, robot, control = self._speed_command, self.robot, self.control
        for _ in range(cfg.substeps):
            # Only the heading changes within a control step; the drive follows it.
            angle = robot.angle
            control.velocity = (-math.sin(angle) * speed, math.cos(angle) * speed)
            self.space.step(dt)

    def _update_fingers(self) -> None:
        """Motor rates that would close the gap to the commanded opening within one control step."""
        target = self._opening_command * self.config.finger_open_angle
        angle = self.robot.angle
        for side, finger, motor in zip(FINGER_SIDES, self.finger_bodies, self._finger_motors, strict=True):
            error = (finger.angle - angle) + side * target
            motor.rate = max(-_FINGER_MAX_RATE, min(_FINGER_MAX_RATE, error * self.config.control_hz))

    # --- queries ------------------------------------------------------------------
    @property
    def robot_pose(self) -> tuple[float, float, float]:
        x, y = self.robot.position
        return float(x), float(y), float(self.robot.angle)

    @property
    def finger_opening(self) -> float:
        """0 = closed, 1 = fully open, measured from the finger bodies (a held block keeps them apart)."""
        spread = (self.finger_bodies[0].angle - self.finger_bodies[1].angle) / 2
        return float(np.clip(spread / self.config.finger_open_angle, 0.0, 1.0))

    def body_poses(self) -> np.ndarray:
        """(angle, x, y) of every moving body in BODY_ORDER: all a camera image depends on."""
        bodies = [*self.block_bodies, *self.finger_bodies, self.robot]
        return np.array([(body.angle, *body.position) for body in bodies])

    @property
    def block_xy(self) -> np.ndarray:
        return np.array([tuple(body.position) for body in self.block_bodies])

    def block_goal_gaps(self) -> np.ndarray:
        """How far each block's bounding box still sticks out below the goal strip (0 = inside)."""
        return np.array([max(0.0, self.config.goal_bottom - shape.bb.bottom) for shape in self.block_shapes])

    def in_gripper(self, block: int) -> bool:
        """True when the block's centre sits between the fingers, where a grasp holds it."""
        local = self.robot.world_to_local(self.block_bodies[block].position)
        radius = self.config.robot_radius
        return abs(local.x) < 0.6 * radius and 0.8 * radius < local.y < 2.2 * radius

    # --- direct placement (tests, scripted scenes) -----------------------------------
    def place_block(self, block: int, xy: tuple[float, float], angle: float = 0.0) -> None:
        body = self.block_bodies[block]
        body.position = xy
        body.angle = angle
        body.velocity = (0.0, 0.0)
        body.angular_velocity = 0.0
        self.space.reindex_shapes_for_body(body)
