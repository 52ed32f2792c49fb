"""Gymnasium environment for "sweep to top in order" (registered as `inest/SweepToTop-v0`)."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from .config import EnvConfig, WorldConfig
from .render import SceneRenderer
from .scoring import OrderTracker, dense_reward
from .world import BLOCK_COLOURS, World, sample_layout

ENV_ID = "inest/SweepToTop-v0"

# The policy's state vector, entry by entry. Blocks always appear in task order.
STATE_FIELDS: tuple[str, ...] = (
    "robot_x",  # robot centre, world units, arena spans [-1.1, 1.1]
    "robot_y",
    "robot_cos",  # cos of the heading; heading 0 faces up (+y)
    "robot_sin",  # sin of the heading (counter-clockwise positive)
    "finger_opening",  # 0 closed .. 1 fully open, measured (a held block keeps it above 0)
    *(f"{c}_{axis}" for c in BLOCK_COLOURS for axis in ("x", "y")),  # block centres
    *(f"dist_robot_{c}" for c in BLOCK_COLOURS),  # robot centre to block centre
    *(f"gap_{c}_goal" for c in BLOCK_COLOURS),  # how far the block sticks out below the goal (0 inside)
    *(f"in_goal_{c}" for c in BLOCK_COLOURS),  # 1.0 while the block lies wholly inside the goal
    "ordered_progress",  # k / 3, k = correctly ordered blocks in the goal (the episode score)
)


def validate_action(action: Any) -> np.ndarray:
    """Reject malformed actions loudly (NaN would silently poison the physics), clip the rest."""
    array = np.asarray(action, dtype=np.float64)
    if array.shape != (3,):
        raise ValueError(f"action must have shape (3,) [speed, turn, grip], got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise ValueError(f"action contains NaN or inf: {array.tolist()}")
    return np.clip(array, -1.0, 1.0)


def action_space() -> spaces.Box:
    """The robot's command: forward speed, turn rate and gripper, each in [-1, 1]."""
    return spaces.Box(-1.0, 1.0, shape=(3,), dtype=np.float32)


def gap_scale(world: WorldConfig) -> float:
    """The largest possible gap below the goal: it normalises the oracle reward."""
    return world.goal_bottom + world.arena_half_size


def state_space(world: WorldConfig) -> spaces.Box:
    half = world.arena_half_size
    n = len(BLOCK_COLOURS)
    low = np.concatenate([[-half, -half, -1, -1, 0], np.full(2 * n, -half), np.zeros(3 * n + 1)])
    high = np.concatenate(
        [
            [half, half, 1, 1, 1],
            np.full(2 * n, half),
            np.full(n, 2 * np.sqrt(2) * half),
            np.full(n, gap_scale(world)),
            np.ones(n + 1),
        ]
    )
    return spaces.Box(low.astype(np.float32), high.astype(np.float32), dtype=np.float32)


def observation_space(config: EnvConfig) -> spaces.Space:
    """What SweepToTopEnv observes under `config`, without building one (a graph's agent needs
    only the spaces; the simulation runs in the simulator nodes)."""
    pixels = spaces.Box(0, 255, shape=(config.image_size, config.image_size, 3), dtype=np.uint8)
    if config.observation == "state":
        return state_space(config.world)
    if config.observation == "pixels":
        return pixels
    return spaces.Dict({"state": state_space(config.world), "pixels": pixels})


class SweepToTopEnv(gym.Env):
    """Push red, then blue, then yellow into the green strip at the top.

    Reward: the dense, order-aware oracle reward (`scoring.dense_reward`, with
    `reward="approach"` also paying for reaching and holding the current block); learned
    rewards replace it in wrappers. Episodes never terminate early; they are truncated after `max_steps`.
    `info["score"]` is the ordered score k / 3 at every step; `info["body_poses"]` the moving
    bodies' poses, from which any camera's image renders again (SceneRenderer.render_poses).
    """

    metadata: ClassVar[dict[str, Any]] = {"render_modes": ["rgb_array"], "render_fps": 8}

    def __init__(self, render_mode: str | None = None, config: EnvConfig | None = None, **kwargs: Any) -> None:
        if config is not None and kwargs:
            raise ValueError(f"pass either config or keyword arguments, not both (got {sorted(kwargs)})")
        self.config = config if config is not None else EnvConfig.from_kwargs(**kwargs)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"unknown render_mode {render_mode!r}; only 'rgb_array' is supported")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": self.config.world.control_hz}
        self.action_space = action_space()
        self._gap_scale = gap_scale(self.config.world)
        self._state_space = state_space(self.config.world)
        self.observation_space = observation_space(self.config)
        self._renderer = SceneRenderer(self.config.world)
        self.world: World | None = None
        self._tracker = OrderTracker()
        self._steps = 0
        self._gaps = np.zeros(len(BLOCK_COLOURS))

    # --- gymnasium API --------------------------------------------------------------
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        self.world = World(self.config.world, sample_layout(self.config.layout, self.np_random))
        self._tracker = OrderTracker()
        self._steps = 0
        self._refresh()
        return self._observation(), self._info()

    def step(self, action: Any):
        if self.world is None:
            raise RuntimeError("call reset() before step()")
        self.world.apply_action(validate_action(action))
        self.world.step()
        self._steps += 1
        self._refresh()
        reward = dense_reward(self.progress, self._gaps, self._gap_scale, self._approach())
        truncated = self._steps >= self.config.max_steps
        return self._observation(), reward, False, truncated, self._info()

    def render(self) -> np.ndarray | None:
        if self.render_mode != "rgb_array":
            return None
        return self.render_camera("allo", self.config.render_size)

    # --- extras ---------------------------------------------------------------------
    def render_camera(self, view: str, size: int | None = None) -> np.ndarray:
        """RGB image (uint8, HxWx3) from either camera, at `size` or the observation size."""
        if self.world is None:
            raise RuntimeError("call reset() before rendering")
        return self._renderer.render(self.world, view, size or self.config.image_size)

    @property
    def progress(self) -> int:
        """Correctly ordered blocks in the goal now (0..3)."""
        return self._tracker.progress

    @property
    def elapsed_steps(self) -> int:
        return self._steps

    def state_vector(self) -> np.ndarray:
        """The policy's observation vector; `STATE_FIELDS` names each entry."""
        world = self.world
        if world is None:
            raise RuntimeError("call reset() before reading the state")
        x, y, angle = world.robot_pose
        blocks = world.block_xy
        robot_dist = np.linalg.norm(blocks - np.array([x, y]), axis=1)
        in_goal = (self._gaps == 0.0).astype(float)
        head = [x, y, np.cos(angle), np.sin(angle), world.finger_opening]
        progress = self._tracker.progress / len(BLOCK_COLOURS)
        state = np.concatenate([head, blocks.ravel(), robot_dist, self._gaps, in_goal, [progress]])
        # Contacts may push a body a hair past a wall; keep the vector inside its declared space.
        return np.clip(state, self._state_space.low, self._state_space.high).astype(np.float32)

    @property
    def holds_current_block(self) -> bool:
        """Whether the block the task needs next sits in the gripper (the 6-subtask scheme's grasp)."""
        assert self.world is not None
        return self.progress < len(BLOCK_COLOURS) and self.world.in_gripper(self.progress)

    def _approach(self) -> tuple[float, bool] | None:
        """The approach oracle's (robot-to-current-block distance, block held), if it is the reward."""
        if self.config.reward != "approach" or self.progress >= len(BLOCK_COLOURS):
            return None
        x, y, _ = self.world.robot_pose
        block = self.progress
        return float(np.hypot(*(self.world.block_xy[block] - (x, y)))), self.world.in_gripper(block)

    def _refresh(self) -> None:
        assert self.world is not None
        self._gaps = self.world.block_goal_gaps()
        self._tracker.update(self._gaps == 0.0, self._steps)

    def _observation(self):
        if self.config.observation == "state":
            return self.state_vector()
        pixels = self.render_camera(self.config.view)
        if self.config.observation == "pixels":
            return pixels
        return {"state": self.state_vector(), "pixels": pixels}

    def _info(self) -> dict[str, Any]:
        progress = self._tracker.progress
        return {
            "score": progress / len(BLOCK_COLOURS),
            "progress": progress,
            "is_success": progress == len(BLOCK_COLOURS),
            "in_goal": self._gaps == 0.0,
            "held": self.holds_current_block,
            "body_poses": self.world.body_poses(),  # every camera renders again from these (render_poses)
        }
