"""Scripted expert for "sweep to top in order", with per-episode variety for demonstrations.

It reads the privileged world state. For each block in task order it backs straight away
from the block just placed, then either reverses straight to a point below the next block
(when that line is clear of the blocks still to place) or travels a lane below their row
with its fingers turned away from the nearer wall, turns up, pushes the block between
open fingers (closing on it once held), and lets go when the block counts. Per-episode
style parameters and action noise keep the demonstrations from being all alike.

`ScriptedExpert(order=...)` makes it place the blocks in another order, for negative episodes
(e.g. `WRONG_ORDER`, blue first: the environment then never counts more than red). With the
default `TASK_ORDER` it follows the environment's ordered progress and draws exactly the same
random numbers as without the option.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .env import SweepToTopEnv
from .scoring import OrderTracker
from .world import BLOCK_COLOURS, World

TASK_ORDER: tuple[int, ...] = tuple(range(len(BLOCK_COLOURS)))  # red, blue, yellow: the task's order
WRONG_ORDER: tuple[int, ...] = (1, 0, 2)  # blue first, then red, then yellow: a negative for the task


@dataclass(frozen=True)
class ExpertConfig:
    """Ranges the expert draws its style from at every reset; zero-width ranges fix a style."""

    action_noise: float = 0.1  # std of Gaussian noise added to speed and turn
    standoff: tuple[float, float] = (0.53, 0.6)  # robot centre below the row while travelling sideways
    lane_depth: tuple[float, float] = (0.0, 0.08)  # extra depth of that travel lane
    lateral_offset: tuple[float, float] = (-0.04, 0.04)  # aim beside the block centre
    speed: tuple[float, float] = (0.85, 1.0)  # fraction of full speed
    steering_gain: tuple[float, float] = (0.8, 1.0)  # 1 = cancel a heading error in one step
    grasp_probability: float = 0.8  # else push with open fingers all the way
    swoop_probability: float = 0.8  # else always travel the lane below the row
    place_margin: float = 0.03  # keep pushing this far past the goal edge before letting go

    def __post_init__(self) -> None:
        for name in ("standoff", "lane_depth", "lateral_offset", "speed", "steering_gain"):
            low, high = getattr(self, name)
            if not low <= high:
                raise ValueError(f"ExpertConfig.{name} must be a (low, high) range, got {(low, high)}")
        if self.action_noise < 0:
            raise ValueError(f"ExpertConfig.action_noise must be >= 0, got {self.action_noise}")
        for name in ("grasp_probability", "swoop_probability"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"ExpertConfig.{name} must be in [0, 1], got {getattr(self, name)}")


def _wrap(angle: float) -> float:
    return (angle + math.pi) % (2 * math.pi) - math.pi


def check_order(order: tuple[int, ...]) -> tuple[int, ...]:
    """A block order: distinct block indices (0 red, 1 blue, 2 yellow), at least one."""
    order = tuple(int(block) for block in order)
    if not order or len(set(order)) != len(order) or not set(order) <= set(TASK_ORDER):
        raise ValueError(f"order must list distinct block indices from {TASK_ORDER}, got {order}")
    return order


class ScriptedExpert:
    """Maps the current world to an action; call `reset` at the start of every episode.

    `order`: the blocks to place, in the order to place them (block indices, 0 red, 1 blue,
    2 yellow). The default is the task's order, judged by the environment's own ordered progress.
    Any other order is judged by the expert's own copy of the ordering rule applied to that order
    (a block counts once it is in the goal after the blocks listed before it); the expert stops
    once every listed block counts. The order is not part of `ExpertConfig`, so datasets recorded
    before it existed keep their configuration record (and stay resumable).
    """

    def __init__(
        self, config: ExpertConfig | None = None, seed: int | None = None, order: tuple[int, ...] = TASK_ORDER
    ) -> None:
        self.config = config or ExpertConfig()
        self.order = check_order(order)
        self.rng = np.random.default_rng(seed)
        self.reset()

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            self.rng = np.random.default_rng(seed)
        cfg, rng = self.config, self.rng
        self.standoff = rng.uniform(*cfg.standoff)
        self.lane_depth = rng.uniform(*cfg.lane_depth)
        self.lateral = rng.uniform(*cfg.lateral_offset)
        self.speed = rng.uniform(*cfg.speed)
        self.gain = rng.uniform(*cfg.steering_gain)
        self.grasps = bool(rng.random() < cfg.grasp_probability)
        self.swoops = bool(rng.random() < cfg.swoop_probability)
        self.phase = "plan"
        self.lane_y = 0.0
        self.facing = 0.0
        self._block = 0  # blocks of `order` placed so far, as of the previous step
        self._placed = OrderTracker(len(self.order))  # only consulted for an order other than TASK_ORDER

    def placed(self, env: SweepToTopEnv) -> int:
        """How many blocks of `order` count as placed now (the environment's progress for TASK_ORDER)."""
        if self.order == TASK_ORDER:
            return env.progress
        assert env.world is not None
        in_goal = env.world.block_goal_gaps() == 0.0
        return self._placed.update(in_goal[list(self.order)], env.elapsed_steps)

    def act(self, env: SweepToTopEnv) -> np.ndarray:
        world = env.world
        if world is None:
            raise RuntimeError("reset the environment before asking the expert to act")
        self.world_config = world.config
        placed = self.placed(env)
        if placed >= len(self.order):
            return np.array([0.0, 0.0, -1.0])
        if placed != self._block:  # the previous block just counted: let go, then back away
            self._block, self.phase = placed, "release"
        speed, turn, grip = self._control(world, placed)
        noise = self.rng.normal(0.0, self.config.action_noise, size=2) if self.config.action_noise else (0.0, 0.0)
        return np.clip(np.array([speed + noise[0], turn + noise[1], grip]), -1.0, 1.0)

    # --- the plan -------------------------------------------------------------------
    def _control(self, world: World, placed: int) -> tuple[float, float, float]:
        """One step of the plan for the next block of `order`; each phase either acts or hands over."""
        block = self.order[placed]
        x, y, angle = world.robot_pose
        bx, by = world.block_xy[block]
        target_x = bx + self.lateral
        if self.phase == "release":
            self.phase = "back_off"
            return 0.0, 0.0, -1.0
        if self.phase == "back_off":
            # Straight back, no turning, until the fingers are clear of the block just placed.
            if math.dist((x, y), world.block_xy[self.order[placed - 1]]) < 0.5:
                return -self.speed, 0.0, -1.0
            self.phase = "plan"
        if self.phase == "plan":
            # The travel lane lies below the row of blocks, where turning cannot touch them.
            lowest = -world.config.arena_half_size + 1.5 * world.config.robot_radius
            self.lane_y = max(lowest, min(y, by - self.standoff - self.lane_depth))
            self.facing = self._lateral_facing(x, target_x)
            self.phase = "swoop" if self._can_swoop(world, placed, (target_x, self.lane_y)) else "descend"
        if self.phase == "swoop":
            # One straight reverse to below the block; the fingers trail away from it.
            if math.dist((x, y), (target_x, self.lane_y)) > 0.06:
                return *self._drive_to(world, (target_x, self.lane_y), reverse_ok=True), -1.0
            self.phase = "face_up"
        if self.phase == "descend":
            sideways = abs(target_x - x) > 0.05
            if y > self.lane_y + 0.03:
                speed, turn = self._drive_to(world, (x, self.lane_y), reverse_ok=True)
                if sideways and y < by - 0.55:  # clear of the row: start turning on the way down
                    turn = self._turn(_wrap(self.facing - angle))
                return speed, turn, -1.0
            self.phase = "lateral" if sideways else "face_up"
        if self.phase == "lateral":
            # Fingers towards the arena centre, so they never sweep a wall; reverse if needed.
            error = _wrap(self.facing - angle)
            offset = target_x - x
            if abs(offset) > 0.04:
                heading_x = -math.sin(angle)
                speed = min(self.speed, abs(offset) * world.config.control_hz / world.config.max_speed)
                speed *= max(0.0, 1.0 - abs(error) / 0.5)
                return math.copysign(speed, offset * heading_x), self._turn(error), -1.0
            self.phase = "face_up"
        if self.phase == "face_up":
            error = _wrap(-angle)
            if abs(error) > 0.08:
                return 0.0, self._turn(error), -1.0
            self.phase = "push"
        # push: steer through the block towards the top wall, closing on it once it is held
        local = world.robot.world_to_local((bx, by))
        if local.y < 0.0 or abs(local.x) > 0.25:  # lost it: go round again
            self.phase = "plan"
            return 0.0, 0.0, -1.0
        grip = 1.0 if self.grasps and world.in_gripper(block) else -1.0
        if world.block_goal_gaps()[block] == 0.0 and by > self._placed_height(world):
            return 0.0, 0.0, grip
        speed, turn = self._drive_to(world, (bx, by + 0.5), reverse_ok=False)
        return speed, turn, grip

    def _can_swoop(self, world: World, placed: int, target: tuple[float, float]) -> bool:
        """A reverse drive straight to `target`: steep enough and clear of blocks still to place."""
        start = np.array(world.robot_pose[:2])
        segment = np.asarray(target) - start
        if not self.swoops or segment[1] > -0.2 or abs(segment[0]) > 1.5 * -segment[1]:
            return False
        clearance = world.config.robot_radius + 0.75 * world.config.block_side
        for centre in world.block_xy[list(self.order[placed:])]:
            along = np.clip((centre - start) @ segment / (segment @ segment), 0.0, 1.0)
            if np.linalg.norm(start + along * segment - centre) < clearance:
                return False
        return True

    def _placed_height(self, world: World) -> float:
        cfg = world.config
        return cfg.goal_bottom + cfg.block_side / 2 + self.config.place_margin

    def _drive_to(self, world: World, target: tuple[float, float], reverse_ok: bool) -> tuple[float, float]:
        """Pursue a point: turn towards it (or turn the back to it) and drive when roughly facing it."""
        x, y, angle = world.robot_pose
        dx, dy = target[0] - x, target[1] - y
        error = _wrap(math.atan2(-dx, dy) - angle)
        backwards = reverse_ok and abs(error) > math.pi / 2
        if backwards:
            error = _wrap(error - math.pi)
        distance = math.hypot(dx, dy)
        cfg = world.config
        speed = min(self.speed, distance * cfg.control_hz / cfg.max_speed)
        speed *= max(0.0, 1.0 - abs(error) / 0.7)
        return (-speed if backwards else speed), self._turn(error)

    def _turn(self, error: float) -> float:
        """Turn command; gain 1 would cancel the heading error in exactly one control step."""
        cfg = self.world_config
        return float(np.clip(self.gain * error * cfg.control_hz / cfg.max_turn_rate, -1.0, 1.0))

    @staticmethod
    def _lateral_facing(x: float, target_x: float) -> float:
        """Heading for sideways travel between x and target_x: fingers away from the nearer wall."""
        outermost = x if abs(x) > abs(target_x) else target_x
        return -math.pi / 2 if outermost < 0 else math.pi / 2


def run_expert_episode(env: SweepToTopEnv, expert: ScriptedExpert, seed: int) -> tuple[float, int]:
    """Play one episode; returns the end score and the step at which it first reached 1."""
    env.reset(seed=seed)
    expert.reset(seed=seed)
    solved_at = -1
    truncated = False
    info: dict = {"score": 0.0}
    while not truncated:
        _, _, _, truncated, info = env.step(expert.act(env))
        if info["is_success"] and solved_at < 0:
            solved_at = env.elapsed_steps
    return float(info["score"]), solved_at
